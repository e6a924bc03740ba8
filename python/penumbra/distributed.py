"""Rendering split across processes with torch.distributed.

Every process renders its share of the cameras (or of the lights' separate scenes, or runs its
own optimisation restart) and computes its part of a loss that is a sum over those shares;
after loss.backward(), all_reduce_gradients() sums the parameters' gradients over the processes,
so that every process holds the gradient of the whole loss and takes the same optimiser step.

    dist.init_process_group("gloo")               # torchrun sets rank, size and rendezvous
    scene = split_views(scene)                    # this process's cameras
    render = penumbra.torch.SceneRenderer(scene, device=str(local_rank))
    loss = <sum over this process's views>; loss.backward()
    all_reduce_gradients([vertices, ...]); optimizer.step()

The tensors are on the CPU, so the backend is gloo, on one machine or many (TCP). Each process
renders on its own OpenCL device: pass device= (an index or part of a device name) to the
SceneRenderer or set PENUMBRA_DEVICE per process. docs/api.md, "Several processes", has the
torchrun commands.
"""
import torch
import torch.distributed as dist

import penumbra

__all__ = ["split_views", "all_reduce_gradients"]


def _rank_and_size(rank, world_size):
    if rank is None or world_size is None:
        if not dist.is_initialized():
            raise penumbra.Error("torch.distributed is not initialised: call "
                                 "torch.distributed.init_process_group first, or pass rank and "
                                 "world_size")
        rank = dist.get_rank() if rank is None else rank
        world_size = dist.get_world_size() if world_size is None else world_size
    return rank, world_size


def split_views(scene, rank=None, world_size=None):
    """A copy of the scene with this process's cameras: camera k goes to process k % size.

    Lights, meshes and parameters are the same on every process (so are the fitted light
    frusta, which depend on the meshes only).
    """
    rank, world_size = _rank_and_size(rank, world_size)
    cameras = scene.cameras
    if len(cameras) < world_size:
        raise penumbra.Error(f"cannot split {len(cameras)} camera(s) over {world_size} "
                             f"processes: every process needs at least one")
    part = penumbra.Scene(scene)
    part.cameras = cameras[rank::world_size]
    return part


def all_reduce_gradients(parameters):
    """Sums the .grad of every tensor over the processes (a missing .grad counts as zero)."""
    for p in parameters:
        if p.grad is None:
            p.grad = torch.zeros_like(p)
        dist.all_reduce(p.grad, op=dist.ReduceOp.SUM)
