"""The Python module against the penumbra tool: same pictures, same gradients, same errors."""
import subprocess

import numpy as np
import pytest

import penumbra

SIZE = ["--width", "64", "--height", "64"]


def run_cli(cli, *args):
    return subprocess.run([str(cli), *args], capture_output=True, text=True)


def bundled(shadows, size=64, model="accurate"):
    scene = penumbra.bundled_scene()
    scene.params.shadows = getattr(penumbra.Shadows, shadows)
    scene.params.shadow_model = getattr(penumbra.ShadowModel, model)
    cameras = scene.cameras
    for c in cameras:
        c.width = c.height = size
    scene.cameras = cameras
    penumbra.refit_light_frusta(scene)  # as the tool does after its options
    return scene


@pytest.mark.parametrize("shadows,precision,model", [
    ("none", "float", "accurate"), ("hard", "float", "accurate"), ("soft", "float", "accurate"),
    ("hard", "double", "accurate"), ("hard", "float", "paper"), ("soft", "float", "paper")])
def test_render_equals_cli_bit_for_bit(cli, context, tmp_path, shadows, precision, model):
    raw = tmp_path / "raw"
    r = run_cli(cli, "render", "-o", str(tmp_path / "x.png"), "--raw", str(raw),
                "--shadows", shadows, "--precision", precision, "--shadow-model", model, *SIZE)
    assert r.returncode == 0, r.stderr
    renderer = penumbra.Renderer(context, getattr(penumbra.Precision, precision))
    assert renderer.fragment_counts() == []
    (view,) = renderer.render(bundled(shadows, model=model))
    (kept,) = renderer.fragment_counts()
    assert isinstance(kept, int) and kept > 0
    for name in ("color", "silhouette", "depth"):
        expected = np.load(raw / f"{name}.npy")  # float32, as the tool writes it
        assert view[name].dtype == np.float64 and view[name].shape == expected.shape
        assert np.array_equal(view[name].astype(np.float32), expected), name
        if precision == "float":  # a float render is exact in float64
            assert np.array_equal(view[name], expected.astype(np.float64)), name
    for kind, maps in (("shadow_map", renderer.shadow_maps()),
                       ("penumbra_map", renderer.penumbra_maps())):
        files = sorted(raw.glob(f"{kind}_*.npy"))
        assert len(maps) == len(files)
        for m, f in zip(maps, files):
            assert np.array_equal(m.astype(np.float32), np.load(f)), f.name
    assert len(renderer.shadow_maps()) == (shadows != "none")


@pytest.mark.parametrize("backend,cli_args", [
    ("kernels", ["--sampling", "exact", "--exact-backend", "kernels"]),
    ("clblast", ["--sampling", "gemm"])])
def test_exact_backend_equals_cli_bit_for_bit(cli, context, tmp_path, backend, cli_args):
    raw = tmp_path / "raw"
    r = run_cli(cli, "render", "-o", str(tmp_path / "x.png"), "--raw", str(raw), "--shadows",
                "hard", "--shadow-model", "paper", "--map-size", "64", *cli_args, *SIZE)
    assert r.returncode == 0, r.stderr
    assert f"exact on {backend}" in r.stdout, r.stdout
    scene = penumbra.bundled_scene()
    scene.params.shadow_map_size = 64
    scene.params.shadows = penumbra.Shadows.hard
    scene.params.shadow_model = penumbra.ShadowModel.paper
    scene.params.sampling = penumbra.Sampling.exact
    scene.params.exact_backend = getattr(penumbra.ExactBackend, backend)
    cameras = scene.cameras
    for c in cameras:
        c.width = c.height = 64
    scene.cameras = cameras
    penumbra.refit_light_frusta(scene)
    (view,) = penumbra.Renderer(context, penumbra.Precision.float).render(scene)
    assert np.array_equal(view["color"].astype(np.float32), np.load(raw / "color.npy"))


def test_clblast_backend_needs_the_paper_hard_exact_sum(context):
    scene = bundled("soft", model="paper")
    scene.params.sampling = penumbra.Sampling.exact
    scene.params.exact_backend = penumbra.ExactBackend.clblast
    with pytest.raises(penumbra.Error, match="soft shadows"):
        penumbra.Renderer(context, penumbra.Precision.float).render(scene)


def test_backward_equals_cli_bit_for_bit(cli, context, tmp_path):
    rng = np.random.default_rng(3)
    grads = {"color": rng.normal(size=(64, 64, 3)), "silhouette": rng.normal(size=(64, 64)),
             "depth": rng.normal(size=(64, 64))}
    (tmp_path / "g").mkdir()
    for name, g in grads.items():
        np.save(tmp_path / "g" / f"{name}.npy", g)
    r = run_cli(cli, "backward", "--grad-in", str(tmp_path / "g"), "-o", str(tmp_path / "out"),
                "--shadows", "hard", *SIZE)
    assert r.returncode == 0, r.stderr
    renderer = penumbra.Renderer(context)
    scene = bundled("hard")
    renderer.render(scene)
    g = renderer.backward(scene, [grads])
    for mesh, dv, da in zip(scene.meshes, g["vertices"], g["albedo"]):
        assert np.array_equal(dv, np.load(tmp_path / "out" / f"vertices_{mesh.name}.npy"))
        assert np.array_equal(da, np.load(tmp_path / "out" / f"albedo_{mesh.name}.npy"))
    lights = np.concatenate([g["light_position"], g["light_color"], g["light_size"][:, None]],
                            axis=1)
    assert np.array_equal(lights, np.load(tmp_path / "out" / "lights.npy"))
    assert np.array_equal(g["ambient"][None], np.load(tmp_path / "out" / "ambient.npy"))
    assert np.abs(lights).max() > 0


def cli_error(cli, *args):
    r = run_cli(cli, *args)
    assert r.returncode == 1
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith("penumbra: error: ")
    return line[len("penumbra: error: "):]


def test_errors_have_the_cli_messages(cli, context, tmp_path):
    missing = str(tmp_path / "missing.json")
    with pytest.raises(penumbra.Error) as e:
        penumbra.load_scene(missing)
    assert str(e.value) == cli_error(cli, "render", missing, "-o", str(tmp_path / "x.png"))

    bad = tmp_path / "bad.json"
    bad.write_text('{"meshes": [], "cameras": [{"eye": [0, 0, 1], "width": 0}]}')
    with pytest.raises(penumbra.Error) as e:
        penumbra.load_scene(str(bad))
    assert str(e.value) == cli_error(cli, "render", str(bad), "-o", str(tmp_path / "x.png"))

    with pytest.raises(penumbra.Error) as e:
        penumbra.Context("no-such-device")
    assert str(e.value) == cli_error(cli, "render", "--device", "no-such-device",
                                     "-o", str(tmp_path / "x.png"))
    assert isinstance(e.value, RuntimeError)


def test_parameters_round_trip_and_shape_errors():
    scene = penumbra.bundled_scene()
    p = scene.parameters()
    assert p["vertices"].shape == (sum(len(m.vertices) for m in scene.meshes), 3)
    assert p["lights"].shape == (1, 7) and np.allclose(p["lights"][0], (3, 6, 2.5, 1, 1, 1, 0.5))
    moved = p["vertices"] + 0.5
    scene.set_parameters(moved, p["albedo"], p["lights"], p["ambient"])
    assert np.array_equal(scene.parameters()["vertices"], moved)
    assert np.array_equal(scene.meshes[1].vertices, moved[len(scene.meshes[0].vertices):])
    n = len(moved)
    with pytest.raises(penumbra.Error, match=rf"vertices has shape \(3, 3\); expected \({n}, 3\)"):
        scene.set_parameters(moved[:3], p["albedo"], p["lights"], p["ambient"])
    with pytest.raises(penumbra.Error, match=r"lights has shape \(1, 3\); expected \(1, 7\)"):
        scene.set_parameters(moved, p["albedo"], p["lights"][:, :3], p["ambient"])
    with pytest.raises(penumbra.Error, match="albedo must be float32 or float64, not float16"):
        scene.set_parameters(moved, p["albedo"].astype(np.float16), p["lights"], p["ambient"])
    with pytest.raises(penumbra.Error, match=r"ambient has shape"):  # checked before any is set
        scene.set_parameters(moved - 1, p["albedo"] / 2, p["lights"], p["ambient"][:2])
    assert np.array_equal(scene.parameters()["vertices"], moved)
    assert np.array_equal(scene.parameters()["albedo"], p["albedo"])
    scene.set_parameters(moved.astype(np.float32), p["albedo"], p["lights"], p["ambient"])
    assert np.array_equal(scene.parameters()["vertices"], moved.astype(np.float32))
    # Any strides, read as the values they show: a transposed copy's view, one row broadcast.
    columns = np.asfortranarray(moved)
    grey = np.broadcast_to(np.float32([0.1, 0.2, 0.3]), p["albedo"].shape)
    scene.set_parameters(columns, grey, p["lights"], p["ambient"])
    assert np.array_equal(scene.parameters()["vertices"], moved)
    assert np.array_equal(scene.parameters()["albedo"], np.broadcast_to(grey, grey.shape))


def test_model_defaults_read_and_take_none():
    # docs/api.md: the optional parameters are None where the shadow model's default applies.
    p = penumbra.RenderParams()
    for name in ("sigma_s", "gamma_s", "beta", "shadow_map_size"):
        assert getattr(p, name) is None, name
        setattr(p, name, 64)
        assert getattr(p, name) == 64, name
        setattr(p, name, None)
        assert getattr(p, name) is None, name


def test_outputs_are_moved_not_copied(context):
    renderer = penumbra.Renderer(context)
    (view,) = renderer.render(bundled("none", 16))
    color = view["color"]
    # The array does not own its memory: it is the C++ image's buffer, kept alive by a capsule.
    assert not color.flags.owndata and color.flags.c_contiguous and color.flags.writeable
    assert color.shape == (16, 16, 3) and 0 < color.mean() <= 1


def test_backward_input_errors(context):
    renderer = penumbra.Renderer(context)
    scene = bundled("none", 16)
    renderer.render(scene)
    cases = [([{"color": np.zeros((3, 3, 3))}],
              "gradient of color for camera 0 is 3x3x3, expected 16x16x3"),
             ([{"colour": np.zeros((16, 16, 3))}], "unknown output 'colour'"),
             ([{"depth": "deep"}], "depth of camera 0 must be an array, not str"),
             ([{"depth": np.zeros((16, 16), dtype=np.int64)}],
              "depth of camera 0 must be float32 or float64, not int64"),
             ([{"depth": np.zeros(16)}], r"must be an array of shape \(H, W\) or \(H, W, C\)"),
             (["x"], "the gradients of camera 0 must be a dict or None"),
             ([None, None], "got gradients for 2 camera")]
    for grads, message in cases:
        with pytest.raises(penumbra.Error, match=message):
            renderer.backward(scene, grads)
    # Missing keys and None are zero gradients.
    g = renderer.backward(scene, [{"color": None}])
    assert not g["vertices"][0].any() and not g["ambient"].any()


def test_backward_parameters_equals_the_dict_backward_in_the_gradients_dtype(context):
    renderer = penumbra.Renderer(context)
    scene = bundled("hard", 16)
    renderer.render(scene)
    rng = np.random.default_rng(3)
    colour = (rng.integers(-8, 8, (1, 16, 16, 3)) / 8).astype(np.float32)
    depth = (rng.integers(0, 8, (1, 16, 16)) / 16).astype(np.float32)
    by_dict = renderer.backward(scene, [{"color": colour[0], "depth": depth[0]}])
    for c, d, dtype in [(colour, depth, np.float32),
                        (colour.astype(np.float64), depth, np.float64),
                        (np.asfortranarray(colour), depth, np.float32),
                        (None, None, np.float64)]:
        g = renderer.backward_parameters(scene, c, None, d)
        assert all(a.dtype == dtype for a in g.values())
        expected = by_dict if c is not None else renderer.backward(scene, [{}])
        assert np.array_equal(g["vertices"], np.concatenate(expected["vertices"]).astype(dtype))
        positions = np.stack(expected["light_position"]).astype(dtype)
        assert np.array_equal(g["lights"][:, :3], positions)
    with pytest.raises(penumbra.Error,
                       match=r"the gradient of depth has shape \(1, 8, 16\); expected \(1, 16, 16\)"):
        renderer.backward_parameters(scene, None, None, depth[:, :8])
    depth[0, 3, 2] = np.inf
    with pytest.raises(penumbra.Error, match=r"depth for camera 0 is infinite at pixel \(2, 3\)"):
        renderer.backward_parameters(scene, None, None, depth)


def test_version_is_the_projects():
    import re
    from conftest import ROOT
    cmake = (ROOT / "CMakeLists.txt").read_text()
    assert penumbra.__version__ == re.search(r"project\(penumbra VERSION ([0-9.]+)", cmake)[1]


def test_devices_say_how_transfers_move(monkeypatch):
    monkeypatch.delenv("PENUMBRA_TRANSFERS", raising=False)
    devices = penumbra.list_devices()
    assert devices
    for d in devices:
        assert isinstance(d.shares_host_memory, bool)
        assert penumbra.Context(str(d.index)).copy_transfers == (not d.shares_host_memory)
    monkeypatch.setenv("PENUMBRA_TRANSFERS", "copy")
    assert penumbra.Context(str(devices[0].index)).copy_transfers


def test_warming_a_cache_that_is_off_is_an_error(monkeypatch):
    """(The build's own warm-up is tested with the tool: tests/test_cache.cpp.)"""
    monkeypatch.setenv("PENUMBRA_CACHE_DIR", "off")
    with pytest.raises(penumbra.Error, match="kernel cache is off"):
        penumbra.warm_kernel_cache(penumbra.Context())


def test_lists_are_copies_that_outlive_their_scene():
    """docs/api.md's pattern, 100 times: each camera read back is the one set, never freed
    memory (list getters used to hand out handles into the scene's list)."""
    scene = penumbra.bundled_scene()
    for i in range(100):
        cams = scene.cameras
        cams[0].eye = (float(i), 2.0, 5.0)
        cams[0].width = 16 + i
        scene.cameras = cams
        assert scene.cameras[0].eye == (float(i), 2.0, 5.0) and scene.cameras[0].width == 16 + i
        assert cams[0].fov_deg == scene.cameras[0].fov_deg > 0  # the old copy is still whole
    lights = scene.lights
    frustum = lights[0].frustum  # a handle that keeps its light alive
    del lights
    scene.lights = []
    assert frustum.fov_deg > 0


def test_arrays_read_out_are_read_only_copies():
    mesh = penumbra.bundled_scene().meshes[0]
    v = mesh.vertices
    with pytest.raises(ValueError, match="read-only"):
        v[:, 1] += 0.3  # would change nothing: refused rather than silently ignored
    mesh.vertices = v + 0.3  # assigning is the way
    assert np.array_equal(mesh.vertices, v + 0.3)
    with pytest.raises(penumbra.Error, match="faces must be integers .* not float64"):
        mesh.faces = mesh.faces.astype(np.float64)


def test_threads_sharing_a_renderer_take_turns(context):
    import threading
    renderer = penumbra.Renderer(context)
    scenes = [bundled(s, 24) for s in ("hard", "soft")]
    expected = [penumbra.Renderer(context).render(s)[0]["color"] for s in scenes]
    failures = []

    def work(k):
        try:
            for _ in range(6):
                (view,) = renderer.render(scenes[k])
                if not np.array_equal(view["color"], expected[k]):
                    failures.append(k)
        except Exception as e:  # noqa: BLE001  any error fails the test below
            failures.append(repr(e))

    threads = [threading.Thread(target=work, args=(k,)) for k in (0, 1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert failures == []


def test_ctrl_c_interrupts_a_long_render_and_leaves_the_renderer_usable():
    import subprocess
    import sys
    script = """
import os, signal, threading, time
import numpy as np, penumbra
scene = penumbra.bundled_scene()
scene.params.shadows = penumbra.Shadows.soft
cams = scene.cameras * 40
for c in cams:  # 40 views of 2.4 s in all on two idle cores: the signal comes well before the end
    c.width = c.height = 512
scene.cameras = cams
small = penumbra.bundled_scene()
renderer = penumbra.Renderer(penumbra.Context())
renderer.render(small)
threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
start = time.monotonic()
try:
    renderer.render(scene)
    print("finished")
except KeyboardInterrupt:
    print("interrupted after", round(time.monotonic() - start, 1))
try:
    renderer.backward(small, [None])
except penumbra.Error as e:
    print("backward:", e)
(again,) = renderer.render(small)
(fresh,) = penumbra.Renderer(penumbra.Context()).render(small)
print("same", np.array_equal(again["color"], fresh["color"]))
"""
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("interrupted after"), r.stdout
    assert float(lines[0].split()[-1]) < 2.5
    assert "call render() first" in lines[1]
    assert lines[2] == "same True"
