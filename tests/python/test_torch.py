"""penumbra.torch: the autograd Function against finite differences and against the module."""
import numpy as np
import pytest
import torch

import penumbra
import penumbra.torch as pt
from conftest import small_scene


@pytest.mark.parametrize("model", ["accurate", "paper"])
@pytest.mark.parametrize("shadows", ["none", "hard", "soft"])
def test_gradcheck_double(context, shadows, model):
    scene = small_scene(shadows)
    scene.params.shadow_model = getattr(penumbra.ShadowModel, model)
    render = pt.SceneRenderer(scene, context)
    p = render.parameters(torch.float64)
    inputs = [p[k].clone().requires_grad_() for k in ("vertices", "albedo", "lights", "ambient")]
    colour, silhouette, depth = render(*inputs)
    assert colour.shape == (1, 10, 10, 3) and depth.shape == silhouette.shape == (1, 10, 10)
    # Every input reaches the outputs (through the shadows too, when they are on).
    grads = torch.autograd.grad(colour.sum() + depth.sum(), inputs)
    assert all(g.abs().max() > 0 for g in grads)
    assert torch.autograd.gradcheck(render, inputs, eps=1e-6, atol=1e-6, rtol=1e-4)


def test_float_inputs_render_in_float(context):
    scene = small_scene("hard", 16)
    render = pt.SceneRenderer(scene, context)
    p = render.parameters(torch.float32)
    colour, _, _ = render(p["vertices"], p["albedo"], p["lights"], p["ambient"])
    assert colour.dtype == torch.float32
    (expected,) = penumbra.Renderer(context).render(render.scene)
    assert np.array_equal(colour[0].numpy(), expected["color"].astype(np.float32))


def test_its_scene_is_a_copy(context):
    render = pt.SceneRenderer(small_scene("hard", 16), context)
    p = render.parameters(torch.float32)
    before = render(p["vertices"], p["albedo"], p["lights"], p["ambient"])[0]
    scene = render.scene
    scene.meshes = scene.meshes[:1]
    scene.cameras[0].width = 8
    assert len(render.scene.meshes) == 2 and render.scene.cameras[0].width == 16
    assert torch.equal(render(p["vertices"], p["albedo"], p["lights"], p["ambient"])[0], before)


def test_backward_after_other_renders(context):
    """backward re-renders its own scene when other renders came in between."""
    render = pt.SceneRenderer(small_scene("hard"), context)
    p = render.parameters()
    v = p["vertices"].clone().requires_grad_()
    first = render(v, p["albedo"], p["lights"], p["ambient"])[0].sum()
    (expected,) = torch.autograd.grad(first, v)
    v2 = v.detach() + 0.05
    first = render(v, p["albedo"], p["lights"], p["ambient"])[0].sum()
    render(v2, p["albedo"], p["lights"], p["ambient"])  # a render of another scene
    (again,) = torch.autograd.grad(first, v)
    assert torch.equal(again, expected)


def test_errors(context):
    render = pt.SceneRenderer(small_scene(), context)
    p = render.parameters()
    with pytest.raises(penumbra.Error, match=r"vertices has shape \(3, 3\); expected \(10, 3\)"):
        render(p["vertices"][:3], p["albedo"], p["lights"], p["ambient"])
    with pytest.raises(penumbra.Error, match="vertices must be float32 or float64, not int32"):
        render(p["vertices"].int(), p["albedo"], p["lights"], p["ambient"])
    with pytest.raises(penumbra.Error, match="albedo must be float32 or float64, not float16"):
        render(p["vertices"], p["albedo"].half(), p["lights"], p["ambient"])


def test_threads_sharing_a_scene_renderer_get_their_own_gradients(context):
    import threading
    render = pt.SceneRenderer(small_scene("hard"), context)
    p = render.parameters()

    def gradient(shift):
        v = (p["vertices"] + shift).requires_grad_()
        (g,) = torch.autograd.grad(render(v, p["albedo"], p["lights"], p["ambient"])[0].sum(), v)
        return g

    expected = {shift: gradient(shift) for shift in (0.0, 0.05)}
    failures = []

    def work(shift):
        for _ in range(5):
            if not torch.equal(gradient(shift), expected[shift]):
                failures.append(shift)

    threads = [threading.Thread(target=work, args=(s,)) for s in expected]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert failures == []


@pytest.mark.skipif(not hasattr(torch.library, "custom_op"),
                    reason="the operator needs torch.library.custom_op (torch 2.4 or later)")
def test_compiled_graph_holds_the_render_whole(context):
    """A SceneRenderer's call is the operator penumbra::scene_render: torch.compile traces it
    with no graph break (fullgraph), and it renders and differentiates as Render does."""
    render = pt.SceneRenderer(small_scene("soft"), context)
    p = render.parameters(torch.float64)
    inputs = [p[k].clone().requires_grad_() for k in ("vertices", "albedo", "lights", "ambient")]

    def loss(vertices, albedo, lights, ambient):
        colour, silhouette, _ = render(vertices, albedo, lights, ambient)
        return colour.square().mean() + silhouette.mean()

    compiled = torch.compile(loss, fullgraph=True, backend="aot_eager")
    value = compiled(*inputs)
    grads = torch.autograd.grad(value, inputs)
    slots = render._slots.get(penumbra.Precision.double, 1)
    colour, silhouette, _ = pt.Render.apply(render.scene, slots, inputs[0][None], *inputs[1:])
    expected = colour[0].square().mean() + silhouette[0].mean()
    assert torch.equal(value, expected)
    for got, want in zip(grads, torch.autograd.grad(expected, inputs)):
        assert torch.equal(got, want)
    torch.library.opcheck(torch.ops.penumbra.scene_render.default,
                          (render._key, inputs[0][None].detach(), *(t.detach() for t in inputs[1:])))
