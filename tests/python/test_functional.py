"""penumbra.torch.render, the functional API: gradients against finite differences, batches,
lists of meshes, frusta that follow the geometry, collapsed faces, and its errors."""
import numpy as np
import pytest
import torch

import penumbra
import penumbra.torch as pt
from conftest import small_scene


def inputs(shadows="hard", model="accurate", dtype=torch.float64, size=10, fixed_frusta=True):
    """small_scene's meshes, camera, light and parameters as the functional API takes them; the
    light's frustum fitted once (finite differences then see the function backward
    differentiates) or left to each call."""
    scene = small_scene(shadows, size)
    scene.params.shadow_model = getattr(penumbra.ShadowModel, model)
    penumbra.fit_light_frusta(scene)
    (light,) = scene.lights
    vertices = [torch.tensor(m.vertices, dtype=dtype) for m in scene.meshes]
    faces = [torch.tensor(m.faces, dtype=torch.int64) for m in scene.meshes]
    albedo = [torch.tensor(m.albedo, dtype=dtype) for m in scene.meshes]
    lights = pt.Light.point(torch.tensor(light.position, dtype=dtype),
                            color=torch.tensor(light.color, dtype=dtype),
                            size=torch.tensor(light.size, dtype=dtype),
                            frustum=light.frustum if fixed_frusta else None)
    ambient = torch.tensor(scene.ambient, dtype=dtype)
    return vertices, faces, scene.cameras, lights, albedo, ambient, scene.params


@pytest.mark.parametrize("model", ["accurate", "paper"])
@pytest.mark.parametrize("shadows", ["none", "hard", "soft"])
@pytest.mark.parametrize("batched", [False, True])
def test_gradcheck_double(context, shadows, model, batched):
    vertices, faces, cameras, light, albedo, ambient, params = inputs(shadows, model)
    v = torch.cat(vertices)
    f = torch.cat([faces[0], faces[1] + len(vertices[0])])
    a = torch.cat(albedo)
    if batched:  # two shapes: the second one's ball lower and smaller
        v = torch.stack([v, torch.cat([vertices[0] * 0.9, vertices[1]])])
        a = torch.stack([a, a.flip(0)])
    p, c, s = light.vector.clone(), light.color.clone(), light.size.clone()

    def run(v, a, p, c, s, ambient):
        light.vector, light.color, light.size = p, c, s
        return pt.render(v, f, cameras, light, albedo=a, ambient=ambient, params=params,
                         context=context)

    args = [t.clone().requires_grad_() for t in (v, a, p, c, s, ambient)]
    colour, silhouette, depth = run(*args)
    lead = (2,) if batched else ()
    assert colour.shape == lead + (1, 10, 10, 3) and depth.shape == lead + (1, 10, 10)
    grads = torch.autograd.grad(colour.sum() + depth.sum(), args)
    reached = [g.abs().max() > 0 for g in grads]
    assert reached[:4] + [reached[5]] == [True] * 5  # size only moves soft shadows
    assert reached[4] == (shadows == "soft"), reached
    assert torch.autograd.gradcheck(run, args, eps=1e-6, atol=1e-6, rtol=1e-4)


def test_batch_equals_separate_calls_and_lists_equal_one_mesh(context):
    vertices, faces, cameras, light, albedo, ambient, params = inputs(dtype=torch.float32)
    v = torch.cat(vertices)
    f = torch.cat([faces[0], faces[1] + len(vertices[0])])
    shapes = torch.stack([v, v * 1.1, v + 0.05])
    batch = pt.render(shapes, f, cameras, light, params=params, context=context)
    for b in range(3):
        one = pt.render(shapes[b], f, cameras, light, params=params, context=context)
        for got, want in zip(batch, one):
            assert torch.equal(got[b], want)
    listed = pt.render(vertices, faces, cameras, light, params=params, context=context)
    assert all(torch.equal(a, b[0]) for a, b in zip(listed, batch))
    assert batch[0].dtype == torch.float32


def test_lights_and_ambient_given_as_numbers_render_as_tensors_of_them(context):
    """Numbers are made into tensors once and reused: each call must still render its own."""
    vertices, faces, cameras, light, _, _, params = inputs(dtype=torch.float32)
    position, colours = light.vector.tolist(), []
    for shift, ambient in ((0.0, 0.2), (0.5, 0.4), (0.0, 0.2)):
        moved = [position[0] + shift, *position[1:]]
        numbers = pt.Light.point(moved, size=0.1, frustum=light.frustum)
        tensors = pt.Light.point(torch.tensor(moved), size=torch.tensor(0.1), frustum=light.frustum)
        got = pt.render(vertices, faces, cameras, numbers, ambient=ambient, params=params,
                        context=context)
        want = pt.render(vertices, faces, cameras, tensors, ambient=torch.tensor(ambient),
                         params=params, context=context)
        assert all(torch.equal(a, b) for a, b in zip(got, want))
        colours.append(got[0])
    assert not torch.equal(colours[0], colours[1]) and torch.equal(colours[0], colours[2])


def test_a_light_position_listing_tensors_gets_their_gradients(context):
    vertices, faces, cameras, light, _, _, params = inputs()
    x, whole = light.vector[0].clone().requires_grad_(), light.vector.clone().requires_grad_()
    for position in ([x, *light.vector[1:].tolist()], whole):
        point = pt.Light.point(position, size=0.1, frustum=light.frustum)
        pt.render(vertices, faces, cameras, point, params=params, context=context)[0].sum().backward()
    assert x.grad is not None and torch.equal(x.grad, whole.grad[0]) and x.grad != 0


def test_each_call_renders_its_own_faces_and_differentiates_its_own_shape(context):
    """Faces are converted once per face tensor, yet a tensor changed in place renders anew; a
    backward after another call's render (other faces) differentiates its own call."""
    vertices, faces, cameras, light, albedo, ambient, params = inputs(dtype=torch.float32, size=24)
    v = torch.cat(vertices)
    f = torch.cat([faces[0], faces[1] + len(vertices[0])])
    render = lambda v, f: pt.render(v, f, cameras, light, params=params, context=context)  # noqa: E731
    before = render(v, f)[1]
    f[: len(faces[0])] = f[: len(faces[0])].roll(1, 0)[:, [0, 2, 1]]  # the ball's faces mixed
    after = render(v, f)[1]
    assert not torch.equal(before, after)
    assert torch.equal(after, render(v, f.clone())[1])

    a = v.clone().requires_grad_()
    render(a, f)[0].sum().backward()
    alone = a.grad.clone()
    a.grad = None
    colour = render(a, f)[0]
    render(v * 1.2, faces[1])  # the ground alone: the same slot renders other faces between
    colour.sum().backward()
    assert torch.equal(a.grad, alone)

    moved = a * 1  # the vertices changed in place after the render: torch refuses the backward
    colour = render(moved, f)[0]
    with torch.no_grad():
        moved.add_(0.1)
    with pytest.raises(RuntimeError, match="modified by an inplace operation"):
        colour.sum().backward()


def dark(colour):
    return int((colour[0].sum(-1) < 0.5).sum())


def test_shadows_follow_the_mesh_and_a_fixed_frustum_warns(context, capfd):
    vertices, faces, cameras, light, albedo, ambient, params = inputs(size=48, fixed_frusta=False)
    moved = [vertices[0] + torch.tensor([1.0, 0.0, 0.2], dtype=torch.float64), vertices[1]]
    follow, _, _ = pt.render(moved, faces, cameras, light, albedo=albedo, ambient=ambient,
                             params=params, context=context)
    capfd.readouterr()  # what compiling the kernels printed, if anything
    scene = small_scene("hard", 48)  # the moved scene, built afresh: its frustum fitted to it
    meshes = scene.meshes
    meshes[0].vertices = moved[0].numpy()
    scene.meshes = meshes
    (fresh,) = penumbra.Renderer(context, penumbra.Precision.double).render(scene)
    assert np.array_equal(follow[0].numpy(), fresh["color"])
    assert capfd.readouterr().err == ""
    # The frustum fitted to the unmoved ball cuts the moved ball's shadow off: one warning.
    _, _, _, fixed, _, _, _ = inputs(size=48)
    own = penumbra.Context()  # renderers of their own, which have not warned yet
    cut, _, _ = pt.render(moved, faces, cameras, fixed, params=params, context=own)
    pt.render(moved, faces, cameras, fixed, params=params, context=own)
    assert dark(cut) < dark(follow)
    err = capfd.readouterr().err
    assert err.count("penumbra: warning:") == 1 and "leaves out faces" in err, err


def balls_around_a_light():
    """Balls on four sides of a point light, seen from above: one frustum cannot hold them all."""
    ball, faces = pt.load_mesh(penumbra.data_dir() / "meshes" / "icosphere.obj")
    balls = [ball * 0.3 + torch.tensor(c) for c in ([1.5, 0, 0], [-1.5, 0, 0], [0, 0, 1.5],
                                                    [0, 0, -1.5])]
    camera = penumbra.Camera.look_at((0, 6, 0.01), (0, 0, 0), width=16, height=16)
    return balls, [faces] * 4, camera


def test_a_light_held_to_one_frustum_among_the_objects_warns_that_shadows_are_missing(capfd):
    balls, faces, camera = balls_around_a_light()
    light = pt.Light.point(torch.tensor([0.0, 0.1, 0.0]), shadow_map="frustum")
    own = penumbra.Context()  # renderers that have not warned yet
    capfd.readouterr()
    pt.render(balls, faces, camera, light, context=own)
    pt.render(balls, faces, camera, light, context=own)
    err = capfd.readouterr().err
    assert err.count("penumbra: warning:") == 1 and "light 0 is among the objects" in err, err
    # One ball beside the light fits in front of it: no warning, from renderers that could.
    pt.render(balls[:1], faces[:1], camera, light, context=penumbra.Context())
    assert "penumbra: warning" not in capfd.readouterr().err


def test_a_light_among_the_objects_casts_shadows_on_every_side(capfd):
    """By default such a light maps its shadows on a cube: the balls' far sides, which face
    away from it, and the shadowed ground are dark on all four sides, and nothing warns."""
    balls, faces, camera = balls_around_a_light()
    ground = torch.tensor([[-4.0, -0.3, -4.0], [4.0, -0.3, -4.0], [4.0, -0.3, 4.0],
                           [-4.0, -0.3, 4.0]])
    quad = torch.tensor([[0, 2, 1], [0, 3, 2]])
    dark = {}
    for shape in ("auto", "frustum"):
        light = pt.Light.point(torch.tensor([0.0, 0.1, 0.0]), shadow_map=shape)
        params = penumbra.RenderParams()
        params.shadows = penumbra.Shadows.hard
        colour, _, _ = pt.render(balls + [ground], faces + [quad], camera, light, ambient=0.0,
                                 params=params, context=penumbra.Context())
        dark[shape] = int((colour.amax(-1) < 0.02).sum())
    err = capfd.readouterr().err
    assert err.count("penumbra: warning:") == 1, err  # the frustum's, not the cube's
    assert dark["auto"] > dark["frustum"], dark
    with pytest.raises(penumbra.Error, match="shadow_map 'sphere'"):
        pt.Light.point((0, 1, 0), shadow_map="sphere")


def test_a_collapsed_face_contributes_nothing(context):
    vertices, faces, cameras, light, albedo, ambient, params = inputs("soft")
    v = torch.cat(vertices)
    f = torch.cat([faces[0], faces[1] + len(vertices[0])])
    point = torch.tensor([[0.1, 0.7, 0.1]] * 3, dtype=torch.float64)  # three corners at one point
    line = torch.tensor([[0.0, 0.5, 0.0], [0.1, 0.6, 0.1], [0.2, 0.7, 0.2]], dtype=torch.float64)
    n = len(v)
    for extra in (point, line):
        x = torch.cat([v, extra]).requires_grad_()
        out = pt.render(x, torch.cat([f, torch.tensor([[n, n + 1, n + 2]])]), cameras, light,
                        params=params, context=context)
        base = pt.render(v, f, cameras, light, params=params, context=context)
        assert all(torch.equal(a, b) for a, b in zip(out, base))
        (g,) = torch.autograd.grad(out[0].sum(), x)
        assert torch.isfinite(g).all() and not g[n:].any() and g[:n].abs().max() > 0


def test_errors_name_the_dtype_and_the_problem(context):
    vertices, faces, cameras, light, albedo, ambient, params = inputs(dtype=torch.float32)
    v, f = vertices[0], faces[0]
    cases = [
        (lambda: pt.render(v, f.float(), cameras, light), "faces must be integers .* not float32"),
        (lambda: pt.render(v.int(), f, cameras, light), "vertices must be float32 or float64, not int32"),
        (lambda: pt.render(v, f, cameras, light, albedo=torch.ones(3, dtype=torch.float16)),
         "albedo must be float32 or float64, not float16"),
        (lambda: pt.render(v, f + 100, cameras, light), "out of range"),
        (lambda: pt.render(v[None, None], f, cameras, light), r"\(V, 3\) or \(B, V, 3\) tensor"),
        (lambda: pt.render(v, f, cameras, "light"), "lights must be penumbra.torch.Light"),
        (lambda: pt.render(v, f, cameras, pt.Light.point((1, 2)), params=params),
         "a 3-vector position"),
    ]
    for call, message in cases:
        with pytest.raises(penumbra.Error, match=message):
            call()


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_non_finite_upstream_gradients_are_refused(context, bad):
    vertices, faces, cameras, light, albedo, ambient, params = inputs()
    v = vertices[0].clone().requires_grad_()
    colour, _, _ = pt.render(v, faces[0], cameras, light, params=params, context=context)
    upstream = torch.zeros_like(colour)
    upstream[0, 3, 4, 1] = bad
    word = "NaN" if bad != bad else "infinite"
    with pytest.raises(penumbra.Error, match=f"gradient of color for camera 0 is {word} at "
                                             r"pixel \(4, 3\); gradients must be finite"):
        colour.backward(upstream)


def test_keyword_constructors():
    c = pt.Camera.look_at((0, 1, 4), (0, 0, 0), fov=30, width=32, height=24, near=0.5, far=9)
    assert (c.eye, c.target, c.up, c.fov_deg, c.width, c.height, c.near, c.far) == \
        ((0, 1, 4), (0, 0, 0), (0, 1, 0), 30, 32, 24, 0.5, 9)
    assert penumbra.Camera(eye=(1, 2, 3), width=8).eye == (1, 2, 3)
    d = penumbra.Light.directional((0, -1, 0), color=(0.5, 0.5, 0.5), size=0.1)
    assert d.type == penumbra.LightType.directional and d.size == 0.1
    m = penumbra.Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    assert m.albedo.shape == (3, 3) and np.all(m.albedo == 0.8)


def test_load_mesh(tmp_path):
    vertices, faces = pt.load_mesh(penumbra.data_dir() / "meshes" / "icosphere.obj")
    assert vertices.dtype == torch.float32 and vertices.shape[1] == 3
    assert faces.dtype == torch.int64 and faces.shape == (1280, 3) and faces.max() < len(vertices)


def test_load_mesh_reads_other_formats_and_drops_degenerate_faces(tmp_path, capfd):
    (tmp_path / "square.off").write_text("OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n"
                                         "4 0 1 2 3\n3 0 1 4\n")
    vertices, faces = pt.load_mesh(tmp_path / "square.off")
    assert faces.shape == (2, 3)  # the square's two triangles; the flat one dropped
    assert "dropped 1 of 3 faces" in capfd.readouterr().err
    with pytest.raises(penumbra.Error, match="the face at triangle 3 is degenerate"):
        pt.load_mesh(tmp_path / "square.off", refuse_degenerate=True)
    with pytest.raises(penumbra.Error, match=r"is not of a known format \('.dae'\)"):
        pt.load_mesh(tmp_path / "scene.dae")
