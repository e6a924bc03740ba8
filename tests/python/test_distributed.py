"""torch.distributed (gloo): two processes, each rendering half of the cameras, all-reduce their
gradients and get the gradients of one process rendering every camera."""
import numpy as np
import pytest
import torch
import torch.distributed as dist
import torch.multiprocessing as mp

import penumbra
import penumbra.torch as pt
from penumbra.distributed import all_reduce_gradients, split_views
from conftest import small_scene

NAMES = ("vertices", "albedo", "lights", "ambient")


def four_views():
    scene = small_scene("hard", 12)
    cameras = []
    for eye in [(0.3, 2.5, 3.0), (3.0, 2.0, 0.5), (-2.5, 2.5, -1.5), (0.5, 3.5, -2.5)]:
        c = scene.cameras[0]
        c.eye = eye
        cameras.append(c)
    scene.cameras = cameras
    return scene


def loss_and_grads(scene):
    """L = Σ over the scene's views of fixed random weights · (colour, silhouette, depth)."""
    render = pt.SceneRenderer(scene)
    x = {k: v.requires_grad_() for k, v in render.parameters(torch.float64).items()}
    colour, silhouette, depth = render(*(x[k] for k in NAMES))
    loss = 0
    for view, camera in enumerate(scene.cameras):
        g = torch.Generator().manual_seed(int(1000 * camera.eye[0]))  # the view's own weights
        w = [torch.randn(t.shape[1:], generator=g, dtype=torch.float64)
             for t in (colour, silhouette, depth)]
        loss = loss + (w[0] * colour[view]).sum() + (w[1] * silhouette[view]).sum() \
            + (w[2] * depth[view]).sum()
    loss.backward()
    return x


def worker(rank, world_size, store, out):
    dist.init_process_group("gloo", init_method=f"file://{store}", rank=rank,
                            world_size=world_size)
    x = loss_and_grads(split_views(four_views()))
    all_reduce_gradients([x[k] for k in NAMES])
    torch.save({k: x[k].grad for k in NAMES}, f"{out}.{rank}")
    dist.destroy_process_group()


def test_two_processes_give_the_single_process_gradients(tmp_path):
    mp.spawn(worker, args=(2, tmp_path / "store", tmp_path / "grads"), nprocs=2)
    single = loss_and_grads(four_views())
    for rank in range(2):
        grads = torch.load(tmp_path / f"grads.{rank}", weights_only=True)
        for k in NAMES:
            assert grads[k].abs().max() > 0
            # The same sums, added in another order: equal to rounding.
            assert torch.allclose(grads[k], single[k].grad, rtol=1e-9, atol=1e-12), k


def test_split_views():
    scene = four_views()
    eyes = [c.eye for c in scene.cameras]
    assert [c.eye for c in split_views(scene, 0, 2).cameras] == eyes[0::2]
    assert [c.eye for c in split_views(scene, 1, 3).cameras] == [eyes[1]]
    with pytest.raises(penumbra.Error, match="cannot split 4 camera"):
        split_views(scene, 0, 5)
    if not dist.is_initialized():
        with pytest.raises(penumbra.Error, match="not initialised"):
            split_views(scene)
