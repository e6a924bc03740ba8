"""penumbra beside Mitsuba 3, a CPU ray tracer (PyPI `mitsuba`, its LLVM variant, the `direct`
integrator), on the same scenes and camera: what each costs at equal error.

    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \\
        python3 bench/mitsuba_side_by_side.py [--bench build/penumbra_bench] [--doc docs/benchmarks.md]

Needs `pip install mitsuba` and an LLVM newer than Debian 12's default (Debian: libllvm19); it
is not part of the test run. The scenes are the accuracy suite's `sphere` (the bundled scene)
and `sphere_100k` (the same with a 100,820-face sphere), 256², and `sphere_100k_512`, that at
512², with a point light (hard shadows) or a sphere light of the same diameter (soft).

Errors are colour RMSE over the accuracy suite's shadow region (ground pixels within 8 px of
the soft truth's shadow): penumbra's is its bias against the Embree ray-traced truth (the
suite's rmse_shadow); Mitsuba's is its noise against its own image at --reference-spp, both
brought to the truth by the per-channel o + k·colour that fits the reference to the truth over
the region (Mitsuba has no ambient term, and its light falls off as 1/r² and carries the
Lambertian 1/π, which penumbra's shading leaves out). "Matched" is Mitsuba at
the samples per pixel whose error equals penumbra's (interpolated log-log between the powers of
two measured); its time is interpolated the same way. Times are medians of --runs renders after
a warm-up, one renderer after the other; forward + backward compares penumbra's accurate step
(render + backward, the suite's step/ cases at σ_s 2 and a 256² map) with Mitsuba's
`direct_projective` at 1 spp (unguided) differentiating a mean of the image by the caster's
vertex positions.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

from docfile import replace_section
from sections import SIDE_BY_SIDE as SECTION

SCENES = ["sphere", "sphere_100k", "sphere_100k_512"]
SHADOWS = ["hard", "soft"]


def fail(message):
    sys.exit(f"mitsuba_side_by_side: {message}")


def run_bench(bench, out_dir, runs):
    """penumbra's forward time and rmse_shadow per (scene, shadows), its step time per shadows,
    and, in out_dir, the scenes, truths and regions (PENUMBRA_BENCH_IMAGES)."""
    cases = ("^(accuracy/fwd/(hard|soft)/truncated/.*model:accurate/scene:sphere(_100k(_512)?)?/|"
             "step/(hard|soft)/truncated/img:256/map:256/faces:100852/.*model:accurate/)")
    json_path = os.path.join(out_dir, "penumbra.json")
    cmd = [bench, f"--benchmark_filter={cases}", f"--benchmark_repetitions={runs}",
           "--benchmark_report_aggregates_only=true", f"--benchmark_out={json_path}",
           "--benchmark_out_format=json"]
    env = dict(os.environ, PENUMBRA_BENCH_IMAGES=out_dir)
    if subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL).returncode != 0:
        fail(f"{' '.join(cmd)} failed")
    forward, step = {}, {}
    for b in json.load(open(json_path))["benchmarks"]:
        if b.get("aggregate_name", "median" if runs == 1 else "") != "median":
            continue  # (one run has no aggregates)
        words = dict(w.split(":", 1) for w in b["run_name"].split("/") if ":" in w)
        shadows = b["run_name"].split("/")[2 if b["run_name"].startswith("accuracy") else 1]
        if b["run_name"].startswith("step/"):
            step[shadows] = b["real_time"]
        elif b.get("default_map") == 1 and b.get("default_sigma_s") == 1:
            forward[(words["scene"], shadows)] = {"ms": b["real_time"], "rmse": b["rmse_shadow"],
                                                  "faces": int(words["faces"]),
                                                  "img": int(words["img"])}
    return forward, step


def mitsuba_scene(mi, desc_dir, scene, shadows, integrator=None):
    """The scene file that bench wrote, as a Mitsuba scene: camera 0, light 0 (a point light, or
    a sphere light of its diameter), two-sided diffuse meshes of each mesh's albedo."""
    desc = json.load(open(os.path.join(desc_dir, scene + ".json")))
    cam, light = desc["cameras"][0], desc["lights"][0]
    d = {"type": "scene", "integrator": integrator or {"type": "direct"}}
    d["sensor"] = {
        "type": "perspective", "fov": cam["fov"], "fov_axis": "y",
        "near_clip": cam["near"], "far_clip": cam["far"],
        "to_world": mi.ScalarTransform4f().look_at(origin=cam["eye"], target=cam["target"],
                                                   up=cam["up"]),
        "film": {"type": "hdrfilm", "width": cam["width"], "height": cam["height"],
                 "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        "sampler": {"type": "independent", "sample_count": 1}}
    for i, m in enumerate(desc["meshes"]):
        d["caster" if i == 0 else f"mesh{i}"] = {
            "type": "obj", "filename": os.path.join(desc_dir, m["file"]), "face_normals": True,
            "bsdf": {"type": "twosided", "bsdf": {
                "type": "diffuse", "reflectance": {"type": "rgb", "value": m["albedo"]}}}}
    if shadows == "hard":
        d["light"] = {"type": "point", "position": light["position"],
                      "intensity": {"type": "rgb", "value": light["color"]}}
    else:
        d["light"] = {"type": "sphere", "center": light["position"], "radius": light["size"] / 2,
                      "emitter": {"type": "area", "radiance": {"type": "rgb",
                                                               "value": light["color"]}}}
    if integrator:  # a differentiable render: shapes may move across the image's border
        d["sensor"]["film"]["sample_border"] = True
    return mi.load_dict(d)


def render(mi, scene, spp, seed):
    return np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)


def reference(mi, scene, spp):
    """The mean of spp/64 renders of 64 spp each (one render of them all would not fit)."""
    passes = max(1, spp // 64)
    return sum(render(mi, scene, min(spp, 64), 10_000 + k) for k in range(passes)) / passes


def timed(fn, runs):
    fn()  # warm-up: Mitsuba compiles a kernel per new configuration
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times)) * 1e3


def rmse(image, truth, region):
    return float(np.sqrt(np.mean((image[region] - truth[region]) ** 2)))


def fit_to(truth, ref, region):
    """The per-channel map o + k·image that brings Mitsuba's reference closest to the truth over
    the region (least squares): the truth's ambient term, and its light without the 1/r² and 1/π."""
    fits = [np.polyfit(ref[region][:, c], truth[region][:, c], 1) for c in range(3)]
    k, o = np.array([f[0] for f in fits]), np.array([f[1] for f in fits])
    return lambda image: o + k * image


def mitsuba_curve(mi, scene, truth, region, args):
    """(spp, error, ms) for spp = 1, 2, 4, … --max-spp, the error against the reference, both
    brought to the truth by fit_to; and that map."""
    ref = reference(mi, scene, args.reference_spp)
    fit = fit_to(truth, ref, region)
    curve = []
    spp = 1
    while spp <= args.max_spp:
        errors = [rmse(fit(render(mi, scene, spp, s)), fit(ref), region) for s in range(3)]
        ms = timed(lambda: render(mi, scene, spp, 0), args.runs)
        curve.append((spp, float(np.mean(errors)), ms))
        spp *= 2
    return curve, fit, ref


def matched(curve, target):
    """Mitsuba's spp and time at error `target` (log-log between the bracketing powers of two);
    at 1 spp when even that is below it, None when --max-spp is not enough."""
    if target >= curve[0][1]:
        return curve[0][0], curve[0][2], "≤ "
    for (s0, e0, t0), (s1, e1, t1) in zip(curve, curve[1:]):
        if e1 <= target <= e0:
            f = np.log(target / e0) / np.log(e1 / e0)
            return (float(np.exp(np.log(s0) + f * np.log(s1 / s0))),
                    float(np.exp(np.log(t0) + f * np.log(t1 / t0))), "")
    return None


def mitsuba_step_ms(mi, dr, desc_dir, scene, shadows, runs):
    """Mitsuba's forward + backward at 1 spp: d(mean colour)/d(caster's vertex positions)."""
    integrator = {"type": "direct_projective", "sppc": 1, "sppp": 1, "sppi": 1,
                  "guiding": "none"}
    s = mitsuba_scene(mi, desc_dir, scene, shadows, integrator)
    params = mi.traverse(s)
    key = "caster.vertex_positions"
    dr.enable_grad(params[key])
    params.update()

    def step():
        image = mi.render(s, params, spp=1, seed=0)
        dr.backward(dr.mean(image, axis=None))
        grad = np.array(dr.grad(params[key]))
        dr.clear_grad(params[key])
        return grad

    return timed(step, runs)


def picture(path, images, labels):
    """The images side by side, each labelled below, as a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from docfile import save_figure
    fig, axes = plt.subplots(1, len(images), figsize=(2.6 * len(images), 3.0))
    for ax, image, label in zip(axes, images, labels):
        ax.imshow(np.clip(image, 0, 1), interpolation="nearest")
        ax.set_xlabel(label, fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bench", default="build/penumbra_bench", help="penumbra_bench to run")
    p.add_argument("--cli", default="build/penumbra", help="penumbra's tool, for the first call")
    p.add_argument("--runs", type=int, default=5, help="timed renders per case (median)")
    p.add_argument("--reference-spp", type=int, default=1024, help="Mitsuba's reference")
    p.add_argument("--max-spp", type=int, default=256, help="the most spp Mitsuba is timed at")
    p.add_argument("--doc", help="the page whose section '" + SECTION[3:] + "' to rewrite")
    p.add_argument("--figure", help="where the picture goes (default: beside --doc, "
                   "images/mitsuba_side_by_side.png)")
    args = p.parse_args()
    for path in (args.bench, args.cli):
        if not os.path.exists(path):
            fail(f"no {path}: build it first (cmake --build build)")
    try:
        import drjit as dr
        import mitsuba as mi
        mi.set_variant("llvm_ad_rgb")
        args.mitsuba_version = mi.__version__
    except (ImportError, AttributeError) as e:
        fail(f"Mitsuba's LLVM variant is unavailable ({e}); pip install mitsuba, and point "
             "DRJIT_LIBLLVM_PATH at an LLVM newer than 15 (Debian: libllvm19)")
    with tempfile.TemporaryDirectory() as work:
        print("penumbra_bench ...", file=sys.stderr)
        forward, step = run_bench(args.bench, work, args.runs)
        rows, shown = compare_forward(mi, work, forward, args)
        step_rows = []
        for shadows in SHADOWS:
            print(f"mitsuba: sphere_100k {shadows} forward + backward ...", file=sys.stderr)
            step_rows.append((shadows, step[shadows],
                              mitsuba_step_ms(mi, dr, work, "sphere_100k", shadows, args.runs)))
        print("first calls ...", file=sys.stderr)
        lines = section(rows, step_rows, first_calls(args.cli, work, args.runs), args)
        print("\n".join(lines))
        if args.doc:
            replace_section(args.doc, lines, before="## Large cases")
            figure = args.figure or os.path.join(os.path.dirname(args.doc), "images",
                                                 "mitsuba_side_by_side.png")
            picture(figure, shown, ["ray-traced truth (Embree)", "penumbra (accurate, soft)",
                                    "Mitsuba at matched error", "Mitsuba, reference"])


def compare_forward(mi, work, forward, args):
    """A row per scene and shadow mode: (scene, penumbra's case, shadows, Mitsuba's curve,
    matched); and the images of the bundled scene's soft shadows for the picture."""
    rows, shown = [], []
    for scene in SCENES:
        region = np.load(os.path.join(work, scene + "_region.npy")) > 0.5
        for shadows in SHADOWS:
            print(f"mitsuba: {scene} {shadows} ...", file=sys.stderr)
            pen = forward[(scene, shadows)]
            truth = np.load(os.path.join(work, f"{scene}_truth_{shadows}.npy"))
            s = mitsuba_scene(mi, work, scene, shadows)
            curve, fit, ref = mitsuba_curve(mi, s, truth, region, args)
            rows.append((scene, pen, shadows, curve, matched(curve, pen["rmse"])))
            if scene == "sphere" and shadows == "soft":
                ours = np.load(os.path.join(work, f"{scene}_accurate_{shadows}.npy"))
                spp = rows[-1][4][0] if rows[-1][4] else args.max_spp
                shown = [truth, ours, fit(render(mi, s, max(1, round(spp)), 1)), fit(ref)]
    return rows, shown


# Mitsuba's first render in a new process (argv: this folder, the scenes' folder): ms on stdout.
MITSUBA_FIRST = """
import sys, time
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
sys.path.insert(0, sys.argv[1])
from mitsuba_side_by_side import mitsuba_scene
scene = mitsuba_scene(mi, sys.argv[2], "sphere", "hard")
start = time.perf_counter()
mi.render(scene, spp=1).numpy()
print((time.perf_counter() - start) * 1e3)
"""


def first_calls(cli, work, runs):
    """The first render of the bundled scene (hard shadows, 256²) in a new process with empty
    kernel caches, medians in ms: penumbra's as its tool prints it (PENUMBRA_CACHE_DIR and
    POCL_CACHE_DIR empty), Mitsuba's at 1 spp (Dr.Jit's cache, under an empty HOME, empty)."""
    ours, theirs = [], []
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as empty:
            env = dict(os.environ, HOME=empty, PENUMBRA_CACHE_DIR=os.path.join(empty, "penumbra"),
                       POCL_CACHE_DIR=os.path.join(empty, "pocl"))
            out = subprocess.run([cli, "render", os.path.join(work, "sphere.json"), "--shadows",
                                  "hard", "-o", os.path.join(empty, "first.png")],
                                 env=env, capture_output=True, text=True)
            found = re.search(r", ([0-9.]+) ms \(", out.stdout)
            if out.returncode != 0 or not found:
                fail(f"{cli} render failed: {out.stderr.strip() or out.stdout.strip()}")
            ours.append(float(found.group(1)))
            out = subprocess.run([sys.executable, "-c", MITSUBA_FIRST,
                                  os.path.dirname(os.path.abspath(__file__)), work],
                                 env=env, capture_output=True, text=True)
            if out.returncode != 0:
                fail(f"Mitsuba's first render failed: {out.stderr.strip()}")
            theirs.append(float(out.stdout.split()[-1]))
    return float(np.median(ours)), float(np.median(theirs))


def load_words():
    with open("/proc/loadavg") as f:
        return f.read().split()[0]


def verdict(rows):
    """Where penumbra is ahead at equal error and where Mitsuba is, in a sentence."""
    def named(keep):
        return ", ".join(f"{scene} {shadows} ({m[1] / pen['ms']:.2f})"
                         for scene, pen, shadows, _, m in rows if m and keep(m[1] / pen["ms"]))
    ahead, behind = named(lambda r: r >= 1), named(lambda r: r < 1)
    return ("A quotient above 1 means penumbra reaches its error first. "
            + (f"penumbra is ahead on {ahead}" if ahead else "penumbra is ahead on none")
            + (f"; Mitsuba on {behind}." if behind else ".")
            + " A point light costs a ray tracer one shadow ray per sample, and a few samples "
            "per pixel already bring its noise to penumbra's bias; a light of some size costs "
            "it many samples, while penumbra's soft shadows cost little more than its hard ones.")


def section(rows, step_rows, first, args):
    lines = [SECTION, "",
             f"penumbra and Mitsuba {args.mitsuba_version} (LLVM variant, `direct` integrator) "
             "on the same scenes and camera, on two CPU cores (PoCL for penumbra; load "
             f"{load_words()} at the end, {time.strftime('%Y-%m-%d', time.gmtime())}); by "
             "`bench/mitsuba_side_by_side.py` (its header says how errors are measured). "
             "Mitsuba's error is its noise; penumbra's is its bias against the ray-traced truth; "
             "\"matched\" is Mitsuba at the samples per pixel that give penumbra's error.", "",
             "| scene | faces | image | shadows | penumbra | its error | Mitsuba, matched error | "
             "Mitsuba's time ÷ penumbra's |", "|---|---|---|---|---|---|---|---|"]
    for scene, pen, shadows, curve, m in rows:
        if m is None:
            match, ratio = f"> {args.max_spp} spp (error {curve[-1][1]:.4f})", "–"
        else:
            spp, ms, below = m
            match = f"{below}{spp:.3g} spp, {ms:.1f} ms"
            ratio = f"{ms / pen['ms']:.2f}"
        lines.append(f"| {scene} | {pen['faces']:,} | {pen['img']}² | {shadows} | {pen['ms']:.1f} ms | "
                     f"{pen['rmse']:.4f} | {match} | {ratio} |")
    lines += ["", verdict(rows), "",
              "Forward and backward, 100,852 faces: penumbra's step (render and backward, the "
              "accurate model at σ_s 2 and a 256² map, the suite's `step/` cases) beside "
              "Mitsuba's `direct_projective` at 1 spp, the gradient of the image's mean by the "
              "sphere's vertices.", "",
              "| shadows | penumbra | Mitsuba | Mitsuba's time ÷ penumbra's |", "|---|---|---|---|"]
    for shadows, ours, theirs in step_rows:
        lines.append(f"| {shadows} | {ours:.1f} ms | {theirs:.1f} ms | {theirs / ours:.2f} |")
    lines += ["", "The first render in a new process with empty kernel caches (the bundled scene, "
              "hard shadows, 256²; Mitsuba at 1 spp, its Dr.Jit cache empty), medians of "
              f"{args.runs}: penumbra {first[0]:,.0f} ms, Mitsuba {first[1]:,.0f} ms "
              f"(Mitsuba's time ÷ penumbra's: {first[1] / first[0]:.2f}). After setup penumbra's "
              "kernel cache is full, and its first render is the *kernel cache* row of "
              "\"First call in a new process\" above."]
    lines += ["", "![truth, penumbra, Mitsuba at matched error, Mitsuba's reference]"
              "(images/mitsuba_side_by_side.png)", ""]
    return lines


if __name__ == "__main__":
    main()
