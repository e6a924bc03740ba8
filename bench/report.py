#!/usr/bin/env python3
"""Turn penumbra_bench's JSON into docs/benchmarks.md (tables) and docs/images/bench_*.png.

  bench/report.py --json out/bench/bench.json [--machine out/bench/machine.json]
                  [--doc docs/benchmarks.md] [--images docs/images]
                  [--accuracy-images out/bench/images] [--accuracy-only]
                  [--first-call out/bench/first_call.json]
  bench/report.py --smoke --bench build/penumbra_bench [--out-dir DIR]

The first form writes the report of a finished run. --smoke runs penumbra_bench on two tiny
cases (a few seconds), writes the report of that run into DIR (default: a temporary folder)
and checks it; CI runs it through ctest (bench_report_smoke).

Plain Python 3; the plots need matplotlib (Debian: python3-matplotlib) and are skipped with a
message when it is missing.
"""
import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # bench/: its sibling modules
import docfile  # noqa: E402

REF = {"img": 256, "map": 256, "faces": 1312, "sigma_s": 2.0, "lights": 1, "model": "paper"}
TEXT_KEYS = ("model", "scene", "maps")  # name segments key:value whose value is a word

# The accuracy group (bench/accuracy.hpp): scenes in their order, and the targets for
# the accurate model (bench/test_accuracy.cpp asserts the same).
ACC_SCENES = ["sphere", "knot_h0", "knot_h0.3", "knot_h1", "grazing"]
ACC_SCENE_WORDS = {
    "sphere": "the bundled unit sphere resting on the ground",
    "knot_h0": "a torus knot (3840 faces) lying on the ground",
    "knot_h0.3": "the knot 0.3 above the ground",
    "knot_h1": "the knot 1 above the ground",
    "grazing": "a sphere of radius 0.5 under a light at 18° elevation",
}
ACC_TARGETS = {"area": 0.05, "lit": 0.02, "rmse": 0.05, "leak": 0.0, "time": 1.5}

# Targets: this 2-core machine, PoCL, the turnaround scene, 256² image, 256² map, forward.
FRAME_TARGETS = [
    ("no shadows, forward", dict(shadows="none", sampling="truncated"), 4.0),
    ("hard shadows, truncated, forward", dict(shadows="hard", sampling="truncated"), 10.0),
    ("soft shadows, truncated, forward", dict(shadows="soft", sampling="truncated"), 30.0),
    ("hard shadows, exact, forward", dict(shadows="hard", sampling="exact"), 100.0),
]
PAPER = {"none": (1.0, 1.0), "hard": (33.0, 33.0), "soft": (104.0, 104.0)}

# Why a target is missed, by the start of its label (or one of several): what the time is spent
# on (the profile table below has the figures), written for the kernels as they are; the
# measurements behind them are in docs/benchmarks-log.md.
# Why the exact backward costs more than its forward (two of the reasons below).
EXACT_BACKWARD = ("the exact backward computes three matrix products (Gy·S and Gyd·S, summed "
                  "against Gx and Gxd, and (a⊙Gy)ᵀ·Gx for dL/dS) where the forward computes one "
                  "(Gy·S), and twice the weight matrices (Gx, Gy and the derivative weights Gxd, "
                  "Gyd) in batches half as large.")
MISS_REASONS = [
    ("no shadows", "the three raster passes are most of the frame. For every pixel and every "
     "face whose cut-off box reaches it, `raster_count` computes the barycentrics, the distance "
     "to the three edges and a softplus (on vectors of the tuning's pixels per work-item), and "
     "`raster_fragments` computes them again for the faces `raster_count` marked, to write the "
     "kept fragments, because which fragments are kept depends on the largest weight, known "
     "only after all faces. The kept fragments' records (shading terms, weight, depth) are a "
     "large part of `raster_fragments`."),
    ("hard shadows, truncated", "the light's own raster pass (a 256² soft depth map, the same "
     "three passes) comes on top of the camera pass, then one Gaussian window of about 11×11 "
     "texels per fragment. The same kernels have met the limit in other runs: the target lies "
     "within the run-to-run spread of this shared machine."),
    ("hard shadows, exact", "every fragment's Gaussian weights span the map: `exact_weights` "
     "writes N·(W_s + H_s) of them, and `matmul_nn_rowdot` forms Gy·S, each row summed against "
     "Gx as it is formed, over the weights that are not exactly 0 (within about 18.7 texels of "
     "μ at σ_s = 2 in float); their device times per frame are in the profile below. The two "
     "raster passes come on top. CLBlast (sampling `gemm`) multiplies every weight and stores "
     "the product."),
    ("backward ≤ 3× forward (hard, exact", EXACT_BACKWARD + " The largest part is `matmul_tn` "
     "(dL/dS), kept fast by float kernels flushing subnormal numbers (math.md §11.2)."),
    ("backward ≤ 3× forward (hard, gemm", EXACT_BACKWARD + " CLBlast (`gemm`) multiplies "
     "every weight, in the forward's one product and the backward's three alike. dL/dS has a "
     "small output (the map) and a long inner dimension (a batch's fragments), which CLBlast "
     "runs slowly in one GEMM; penumbra asks for it in chunks of 1024 fragments."),
    ("backward ≤ 3× forward (hard, truncated", "the texel gathers (each shadow-map texel sums the "
     "fragments whose window holds it, found through texel buckets) and the per-face raster "
     "backward, which walks each face's pixel box (its cut-off test on 16 pixels at a time, the "
     "rest per pixel), are loops per work-item that PoCL runs one work-item at a time."),
    ("backward ≤ 3× forward (soft", "the compare's two sigmoids and their derivatives are "
     "evaluated again for every fragment at every texel of its window twice: per texel in the "
     "gather (`soft_gather`, on blocks of 8×8 texels) and per fragment (`soft_sample_bwd`), "
     "against one lookup (`soft_sample`) in the forward. Each sigmoid's divisions and "
     "exponential are most of both kernels; replacing the divisions by reciprocals would "
     "change the gradients' last bits and speeds the forward as much as the backward, so the "
     "quotient barely moves."),
    ("512²", "the raster passes alone take more than the target on this machine. A tile's list "
     "holds about 77 faces (8×8 tiles, this Xeon's tuned entry); `raster_count` evaluates the "
     "coverage, depth and softplus of every face that reaches a block of 16 pixels, and "
     "`raster_fragments` evaluates again those that may keep a fragment (4.6 kept per pixel) "
     "and writes their records. The evaluations and the records are about three quarters of "
     "the frame and the softplus about a fifth: with a coverage function that cost nothing "
     "the frame would still take about 45 ms, and to take 30 ms the evaluations would have to "
     "run about 2.8 times faster. The calling thread's own work (checks and packing of the "
     "scene, upload, conversion of the outputs) adds about 8 ms a frame."),
    ("256², 100 852 faces", "the same raster passes in the camera's and the light's view, "
     "forward and (per face, over its pixel box) backward, plus the lookups and gathers; "
     "`raster_bwd`, `raster_count` and `raster_fragments` are the largest kernels of a step, "
     "and the calling thread's own work (packing the scene, summing the per-face light "
     "gradients) adds about 23 ms. The dense sphere keeps 6.8 fragments a pixel in the "
     "camera's view: neighbouring faces of the surface lie within ε_w of the heaviest."),
]


# ---- reading -------------------------------------------------------------------------------

def parse_name(name):
    """'fwd/hard/exact/img:256/...' → dict of its parts (see bench/bench_*.cpp)."""
    parts = [p for p in name.split("/") if p not in ("manual_time", "real_time")
             and not p.startswith(("iterations:", "repeats:", "min_time:"))]
    rec = {"large": False}
    if parts and parts[0] == "large":
        rec["large"] = True
        parts = parts[1:]
    params = {}
    words = []
    for p in parts:
        if ":" in p:
            k, v = p.split(":", 1)
            params[k] = v if k in TEXT_KEYS else float(v) if k == "sigma_s" else int(v)
        else:
            words.append(p)
    if not words:
        return None
    if words[0] == "ceiling":
        rec.update(kind="ceiling", what=words[1] if len(words) > 1 else "")
    elif words[:2] == ["accuracy", "ratio"]:
        rec.update(kind="accuracy_ratio", shadows=words[2], sampling=words[3])
    elif words[0] == "step":  # a render and its backward in turn (bench_render.cpp, run_step)
        rec.update(kind="step", shadows=words[1], sampling=words[2], model="paper")
    elif words[0] in ("turnaround", "accuracy"):
        rec.update(kind=words[0], pass_=words[1], shadows=words[2], sampling=words[3])
    elif words[0] in ("fwd", "bwd"):  # the paper's model unless the name says /model:
        rec.update(kind="render", pass_=words[0], shadows=words[1], sampling=words[2],
                   model="paper")
    else:
        return None
    rec.update(params)
    return rec


def load(path):
    with open(path) as f:
        data = json.load(f)
    records = []
    for b in data.get("benchmarks", []):
        if b.get("run_type", "iteration") != "iteration":
            continue
        rec = parse_name(b["name"])
        if rec is None:
            continue
        rec["name"] = b["name"]
        rec["error"] = b.get("error_message") if b.get("error_occurred") else None
        rec["iterations"] = b.get("iterations", 0)
        for k, v in b.items():
            if isinstance(v, (int, float)) and k not in rec:
                rec[k] = v
        records.append(rec)
    return data.get("context", {}), records


class Results:
    def __init__(self, records):
        self.records = [r for r in records if not r["error"]]
        self.errors = [r for r in records if r["error"]]

    def find(self, kind="render", **want):
        """The one record of `kind` matching `want`; parameters not given take REF's values."""
        keys = dict(REF) if kind == "render" else {}
        keys.update(want)
        for r in self.records:
            if r.get("kind") != kind:
                continue
            if all(r.get(k if k != "pass" else "pass_") == v for k, v in keys.items()):
                return r
        return None

    def render(self, pass_="fwd", **want):
        return self.find("render", pass_=pass_, **want)

    def all(self, kind):
        return [r for r in self.records if r.get("kind") == kind]


# ---- formatting ----------------------------------------------------------------------------

def fmt(x, digits=3):
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    if x == 0:
        return "0"
    a = abs(x)
    if a >= 10 ** digits:
        return f"{x:,.0f}"
    d = max(0, digits - 1 - int(math.floor(math.log10(a))))
    return f"{x:.{d}f}"


def si(x):
    if x is None:
        return "–"
    for unit, scale in (("T", 1e12), ("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if abs(x) >= scale:
            return f"{x / scale:.3g} {unit}"
    return f"{x:.3g}"


def ms(r):
    return r.get("ms_median") if r else None


def step(res, **want):
    """The step case (a render and its backward in turn) at the reference point but `want`."""
    return res.find("step", **{**REF, **want})


def bwd_over_fwd(res, shadows, sampling):
    """(backward ms, backward / forward) at the reference point: from the step case, whose two
    calls meet the same machine, else from the separate fwd and bwd cases."""
    s = step(res, shadows=shadows, sampling=sampling)
    if s and s.get("ms_fwd"):
        return s["ms_bwd"], s["bwd_ratio"]
    f, b = (ms(res.render(d, shadows=shadows, sampling=sampling)) for d in ("fwd", "bwd"))
    return b, (b / f if f and b else None)


def fwd_plus_bwd(res, **want):
    """Median ms of a hard truncated render plus its backward: the step case's median step,
    else the sum of the separate cases' medians."""
    s = step(res, shadows="hard", sampling="truncated", **want)
    if s and s.get("ms_median") is not None:
        return s["ms_median"]
    f, b = (ms(res.render(d, shadows="hard", sampling="truncated", **want)) for d in ("fwd", "bwd"))
    return f + b if f is not None and b is not None else None


def table(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


# Within this fraction of its limit a case's verdict can flip from one run to the next on a
# shared machine: the same case's median moves by more than that between runs under load.
NOISE = 0.05


def verdict(measured, limit):
    """Met/missed and by how much, for an upper limit."""
    if measured is None:
        return "not measured", "–"
    near = f" (within {NOISE * 100:.0f} %: another run may"
    close = near + " not meet it)" if measured > limit * (1 - NOISE) else ""
    if measured <= limit:
        by = f"{limit / measured:.2f}× under the limit" if measured > 0 else ""
        return "met", by + close
    close = near + " meet it)" if measured < limit * (1 + NOISE) else ""
    return "**missed**", f"{measured / limit:.2f}× over the limit" + close


# ---- plots ---------------------------------------------------------------------------------

def get_plt():
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        return plt
    except ImportError:
        print("report: matplotlib not found (Debian: python3-matplotlib); plots skipped",
              file=sys.stderr)
        return None


SERIES = [("fwd", "none", "truncated", "forward, no shadows", "C0", "-"),
          ("fwd", "hard", "truncated", "forward, hard truncated", "C1", "-"),
          ("fwd", "hard", "exact", "forward, hard exact", "C3", "-"),
          ("fwd", "hard", "gemm", "forward, hard gemm (CLBlast)", "C4", "-"),
          ("fwd", "soft", "truncated", "forward, soft truncated", "C2", "-"),
          ("fwd", "soft", "exact", "forward, soft exact", "C5", "-"),
          ("bwd", "none", "truncated", "backward, no shadows", "C0", "--"),
          ("bwd", "hard", "truncated", "backward, hard truncated", "C1", "--"),
          ("bwd", "hard", "exact", "backward, hard exact", "C3", "--"),
          ("bwd", "soft", "truncated", "backward, soft truncated", "C2", "--")]


def sweep(res, key, value=ms, **fixed):
    """{(pass, shadows, sampling): [(x, value), ...]} over render cases varying `key` (cases
    without the value left out); the value is the median ms unless `value` says otherwise."""
    out = {}
    for r in res.all("render"):
        if any(r.get(k) != v for k, v in {**REF, **fixed}.items() if k != key):
            continue
        if value(r) is not None:
            out.setdefault((r["pass_"], r["shadows"], r["sampling"]), []).append((r[key], value(r)))
    return {k: sorted(v) for k, v in out.items()}


def device_mib(r):
    return r.get("device_MiB")


def plot_sweep(plt, res, key, xlabel, path, logx=True, value=ms,
               ylabel="median time per frame (ms)", **fixed):
    data = sweep(res, key, value, **fixed)
    if not data:
        return False
    if not any(len(data.get((p, sh, sa), [])) >= 2 for p, sh, sa, *_ in SERIES):
        return False
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for pass_, sh, sa, label, color, style in SERIES:
        pts = data.get((pass_, sh, sa))
        if not pts or len(pts) < 2:
            continue
        ax.plot([p[0] for p in pts], [p[1] for p in pts], style, marker="o", color=color,
                label=label, ms=4)
    ax.set_xscale("log" if logx else "linear")
    ax.set_yscale("log")
    xs = sorted({x for pts in data.values() for x, _ in pts})
    ax.set_xticks(xs)
    ax.set_xticklabels([fmt(x, 2) if isinstance(x, float) else str(x) for x in xs],
                       rotation=30 if len(xs) > 5 else 0)
    ax.minorticks_off()
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    docfile.save_figure(fig, path, dpi=110)
    plt.close(fig)
    return True


def acc_ref(r):
    """The reference settings of the accuracy group: the model's default map size and σ_s."""
    return r.get("default_map") == 1 and r.get("default_sigma_s") == 1


def plot_tradeoff(plt, res, path):
    """Shadow-region RMSE against forward time, one panel per scene: both models, every
    mode and sampling (reference map and σ_s; exact at its own map size)."""
    acc = [r for r in res.all("accuracy") if r["shadows"] != "none" and
           (acc_ref(r) or r["sampling"] == "exact")]
    scenes = [sc for sc in ACC_SCENES if any(r["scene"] == sc for r in acc)]
    if not scenes:
        return False
    fig, axes = plt.subplots(1, len(scenes), figsize=(3.2 * len(scenes), 3.6), sharey=True,
                             squeeze=False)
    for ax, sc in zip(axes[0], scenes):
        for r in (r for r in acc if r["scene"] == sc):
            color = {"accurate": "C2", "paper": "C3"}[r["model"]]
            marker = {"truncated": "o", "exact": "s", "gemm": "^"}[r["sampling"]]
            fill = color if r["shadows"] == "hard" else "none"
            ax.scatter(ms(r), r["rmse_shadow"], edgecolors=color, facecolors=fill, marker=marker)
        ax.axhline(ACC_TARGETS["rmse"], color="grey", lw=0.8, ls="--")
        ax.set_xscale("log")
        ax.set_title(sc, fontsize=9)
        ax.set_xlabel("forward ms (median)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("shadow-region RMSE\n(hard vs point light, soft vs sphere light)")
    from matplotlib.lines import Line2D
    handles = [Line2D([], [], color=c, marker="o", ls="", label=l)
               for c, l in (("C2", "accurate"), ("C3", "paper"))]
    handles += [Line2D([], [], color="k", marker=m, ls="", mfc=f, label=l)
                for m, f, l in (("o", "k", "hard, truncated"), ("o", "none", "soft, truncated"),
                                ("s", "k", "exact"), ("^", "k", "gemm"))]
    axes[0][-1].legend(handles=handles, fontsize=6)
    fig.tight_layout()
    docfile.save_figure(fig, path, dpi=100)
    plt.close(fig)
    return True


def copy_comparisons(folder, image_dir):
    """truth | penumbra | difference strips of the accurate model (compare_*_accurate_*.png
    written by the accuracy group under $PENUMBRA_BENCH_IMAGES) → image_dir/accuracy_*.png."""
    copied = []
    for sc in ACC_SCENES:
        for sh in ("hard", "soft"):
            src = os.path.join(folder or "", f"compare_{sc}_accurate_{sh}.png")
            if folder and os.path.exists(src):
                docfile.copy_file(src, os.path.join(image_dir, f"accuracy_{sc}_{sh}.png"))
                copied.append((sc, sh))
    return copied


# ---- per-kernel profiles ------------------------------------------------------------------

# exact-dense: the hard exact case at σ_s = DENSE_SIGMA_S, where the products skip nothing;
# accurate: the truncated case of the accurate model (the renderer's default).
PROFILE_MODES = [("none", "truncated"), ("hard", "truncated"), ("hard", "exact"),
                 ("hard", "exact-dense"), ("hard", "gemm"), ("soft", "truncated"),
                 ("hard", "accurate"), ("soft", "accurate")]
# A row of the PENUMBRA_PROFILE=1 table: kernel, device ms, launches.
KERNEL_LINE = re.compile(r"^\s+([A-Za-z_]\w*)\s+(\d+(?:\.\d+)?)\s+(\d+)\s*$")


def stage_of(kernel):
    """Pipeline stage (kernels/<stage>.cl) of a kernel, by name; CLBlast's own kernels apart."""
    if kernel in ("transform_fwd", "transform_bwd", "face_setup"):
        return "transform"
    if kernel == "clblast_gemm":
        return "CLBlast"
    for prefix, stage in (("bin_", "bin"), ("raster_", "raster"), ("shadow_", "shadow"),
                          ("exact_", "shadow"), ("soft_", "shadow"), ("matmul_", "matmul"), ("row_dot", "matmul"),
                          ("penumbra_", "penumbra"), ("pcf_", "pcf")):
        if kernel.startswith(prefix):
            return stage
    # penumbra's kernels are snake_case; CLBlast's (Xgemm, TransposeMatrix, ...) are not.
    return "CLBlast" if kernel[:1].isupper() else "other"


def load_profiles(folder):
    """{(shadows, sampling): {"kernels": [(name, launches, ns)] per frame, "frames": int,
    "status": int}}. A profile sums a case's frames; raster_resolve runs once per view, and a
    frame has one view, or two with a light's shadow map."""
    out = {}
    if not folder:
        return out
    for sh, sa in PROFILE_MODES:
        path = os.path.join(folder, f"profile_fwd_{sh}_{sa}.txt")
        if not os.path.exists(path):
            continue
        kernels, status = [], None
        for line in open(path, errors="replace"):
            m = KERNEL_LINE.match(line)
            if m:
                kernels.append((m.group(1), int(m.group(3)), float(m.group(2)) * 1e6))
            elif line.startswith("exit status"):
                status = int(line.split()[-1])
        resolves = sum(n for name, n, _ in kernels if name == "raster_resolve")
        frames = resolves // (1 if sh == "none" else 2)
        if not frames:
            kernels = []
        out[(sh, sa)] = {"kernels": [(name, n / frames, round(ns / frames))
                                     for name, n, ns in kernels],
                         "frames": frames, "status": status}
    return out


def profiled_case(res, mode):
    """The forward case a profile mode ran (PROFILE_MODES)."""
    sh, sa = mode
    if sa == "accurate":
        return res.render("fwd", shadows=sh, sampling="truncated", model="accurate")
    if sa == "exact-dense":
        return res.render("fwd", shadows=sh, sampling="exact", sigma_s=DENSE_SIGMA_S)
    return res.render("fwd", shadows=sh, sampling=sa)


def product_flops(r):
    """Flops of the exact sum's forward products per frame: 2·N·W_s·H_s per light."""
    return 2.0 * r["fragments"] * r["map"] ** 2 * r.get("lights", 1)


def weight_exps(r):
    """The most exps exact_weights evaluates per frame: N·(W_s + H_s) per light."""
    return r["fragments"] * 2 * r["map"] * r.get("lights", 1)


def kernel_rates(r, kernels, peak, exp_rate):
    """The throughput of each profiled kernel whose work a ceiling measures, against it, from
    case r's counters and the kernel's device time per frame: the truncated samplers weigh
    samples_per_s·time texels a frame (one exp each, as the targets count them), exact_weights
    evaluates at most N·(W_s + H_s) exps per light, a product (penumbra's kernels, CLBlast's
    GEMM) 2·N·W_s·H_s flops per light; penumbra's skip the weights that are exactly 0, so their
    rate is dense-equivalent unless every weight is nonzero (dense_products). The raster, bin
    and transform kernels mix their arithmetic with branches and memory: no one ceiling."""
    if not r or not r.get("fragments"):
        return "–"
    out = []
    for name, _, ns in sorted(kernels, key=lambda k: -k[2]):
        if not ns:
            continue
        if name in ("shadow_sample", "soft_sample") and r.get("samples_per_s") and exp_rate:
            rate = r["samples_per_s"] * ms(r) * 1e-3 / (ns * 1e-9)
            out.append(f"`{name}` {si(rate)} samples/s = {fmt(rate / exp_rate * 100, 2)} % of "
                       f"exp rate")
        elif name == "exact_weights" and exp_rate:
            rate = weight_exps(r) / (ns * 1e-9)
            out.append(f"`{name}` ≤ {si(rate)} exp/s = {fmt(rate / exp_rate * 100, 2)} % of "
                       f"exp rate")
        elif (name == "clblast_gemm" or name.startswith("matmul_")) and peak:
            rate = product_flops(r) / (ns * 1e-9) / 1e9
            out.append(f"`{name}` {fmt(rate)} GFLOP/s = {fmt(rate / peak * 100, 2)} % of FMA peak"
                       if dense_products(r) else f"`{name}` {fmt(rate)} GFLOP/s dense-equivalent")
    return "; ".join(out) if out else "–"


def profile_section(res, profiles, peak=None, exp_rate=None):
    if not profiles:
        return None
    frames = sorted({p["frames"] for p in profiles.values() if p["kernels"]})
    L = ["Device time per kernel and forward frame of the suite's cases at the reference point",
         "(bundled scene, 256², 256² map, the paper's shadow model), from",
         "`PENUMBRA_PROFILE=1 penumbra_bench --benchmark_filter=^fwd/S/M/img:256/map:256/"
         "faces:1312/sigma_s:2/lights:1/manual_time`:",
         "each launch waited for, its device time summed per kernel over the case's frames",
         f"({'–'.join(str(f) for f in (frames[0], frames[-1])) if frames else 'none'} per mode,"
         " the warm-up included) and divided by them; CLBlast's GEMM is",
         "one row, the time of the last kernel of each call, the event CLBlast returns.",
         "The raster kernels serve both the light pass and the camera pass; the exact case runs",
         "penumbra's direct product kernels, the gemm case CLBlast's GEMM; exact-dense is the",
         "exact case at σ_s = 400 (`sigma_s:400` in the filter), where no weight is 0 and the",
         "products skip nothing. *Against the ceiling*: kernel_rates in bench/report.py, each",
         "kernel's work per frame (samples, exps, flops) over its device time per frame, against",
         "the machine's ceiling above."]
    if any(sa == "accurate" and p["kernels"] for (_, sa), p in profiles.items()):
        L += ["The accurate rows are the accurate model's truncated cases (`/model:accurate`",
              "after `lights:1` in the filter), the renderer's default."]
    L.append("")
    rows = []
    for (sh, sa), p in profiles.items():
        if not p["kernels"]:
            rows.append((f"{sh} / {sa}", f"unavailable (the profiled run exited with status "
                                         f"{p['status']})", "", "", ""))
            continue
        total = sum(ns for _, _, ns in p["kernels"])
        stages = {}
        for name, launches, ns in p["kernels"]:
            stages[stage_of(name)] = stages.get(stage_of(name), 0) + ns
        stage_txt = ", ".join(f"{k} {fmt(v / 1e6)} ms ({v * 100 / total:.0f} %)"
                              for k, v in sorted(stages.items(), key=lambda kv: -kv[1]))
        top = ", ".join(f"`{n}` {fmt(ns / 1e6)} ms ×{l:g}" for n, l, ns in
                        sorted(p["kernels"], key=lambda k: -k[2])[:4])
        rates = kernel_rates(profiled_case(res, (sh, sa)) if res else None, p["kernels"], peak,
                             exp_rate)
        rows.append((f"{sh} / {sa}", f"{fmt(total / 1e6)} ms", stage_txt, top, rates))
    L.append(table(("mode", "kernel time", "by stage", "largest kernels (time × launches per frame)",
                    "against the ceiling"), rows))
    dominant = []
    for (sh, sa), p in profiles.items():
        if p["kernels"]:
            total = sum(ns for _, _, ns in p["kernels"])
            stages = {}
            for name, _, ns in p["kernels"]:
                stages[stage_of(name)] = stages.get(stage_of(name), 0) + ns
            top = max(stages.items(), key=lambda kv: kv[1])
            dominant.append(f"{sh} / {sa}: {top[0]} ({top[1] * 100 / total:.0f} %)")
    if dominant:
        L += ["", "Dominant stage by device time: " + "; ".join(dominant) + "."]
    return "\n".join(L)


# The σ_s of the dense exact cases: no Gaussian weight of a 256² map is 0 there (float).
DENSE_SIGMA_S = 400.0


def dense_products(r):
    """Whether a hard exact or gemm case's GFLOP/s counts the flops its products execute:
    CLBlast's GEMM multiplies every weight, penumbra's kernels skip those that are exactly 0
    (exp's argument −d²/(2σ_s) below −87 in float), which none is where σ_s ≥ (W_s − 1)²/174."""
    return r.get("sampling") == "gemm" or r.get("sigma_s", 0) >= (r["map"] - 1) ** 2 / 174


def matmul_rate(res, profiles, dense=False):
    """GFLOP/s of the exact path's product kernels alone, from the profile (dense-equivalent
    but at σ_s = DENSE_SIGMA_S), their ms, exact_weights' ms and the frame's kernel ms."""
    mode = ("hard", "exact-dense" if dense else "exact")
    p, r = profiles.get(mode), profiled_case(res, mode)
    if not p or not p["kernels"] or not r or not r.get("fragments"):
        return None
    ns = sum(t for n, _, t in p["kernels"] if stage_of(n) == "matmul")
    weights = sum(t for n, _, t in p["kernels"] if n == "exact_weights")
    return (product_flops(r) / (ns * 1e-9) / 1e9 if ns else None, ns / 1e6, weights / 1e6,
            sum(t for _, _, t in p["kernels"]) / 1e6)


# ---- the report ----------------------------------------------------------------------------

def case_label(r):
    return f"{r['shadows']} / {r['sampling']}"


def write_report(context, records, machine, doc_path, image_dir, accuracy_images, smoke=False,
                 profiles=None, first_call=None):
    res = Results(records)
    profiles = profiles or {}
    plt = get_plt()
    os.makedirs(image_dir, exist_ok=True)
    rel_images = os.path.relpath(image_dir, os.path.dirname(os.path.abspath(doc_path)))
    L = []
    w = L.append

    w("# Benchmarks")
    w("")
    w("What penumbra costs on a CPU through PoCL — forward and backward, no / hard / soft shadows,")
    w("truncated / exact / gemm sampling — and how close each shadow method comes to a ray-traced")
    w("ground truth. Everything on this page was generated by `bench/report.py` from one run of")
    w("the suite" + (" (a smoke run: two tiny cases only)" if smoke else "") + "; rerun it with")
    w("")
    w("```sh")
    w("scripts/bench.sh            # install, build, run the default suite, regenerate this page")
    w("scripts/bench.sh --scaling  # the same plus the face and image sweeps' large cases (to 1M faces, 2048²)")
    w("scripts/bench.sh --large    # the same plus every large case (exact at 1024², 1024² maps, ...)")
    w("```")
    w("")

    # Machine.
    w("## Machine and run")
    w("")
    rows = []
    m = machine or {}
    rows.append(("CPU (`lscpu \\| grep 'Model name'`)", m.get("cpu_model") or context.get("cpu_model", "–")))
    rows.append(("cores (`nproc`)", m.get("nproc", context.get("num_cpus", "–"))))
    rows.append(("OpenCL device", context.get("device", "–")))
    rows.append(("PoCL", m.get("pocl_version", "–")))
    rows.append(("device version", context.get("device_version", "–")))
    if m.get("command"):
        rows.append(("command", f"`{m['command']}`"))
    rows.append(("date", context.get("date", "–")))
    if m.get("wall_seconds") is not None:
        rows.append(("suite wall time", f"{m['wall_seconds']:.0f} s"))
    rows.append(("load average (1, 5, 15 min) before the run",
                 m.get("loadavg_before") or context.get("loadavg_at_start", "–")))
    if m.get("loadavg_after"):
        rows.append(("load average after the run", m["loadavg_after"]))
    loads = [r["loadavg_1min"] for r in res.records if r.get("loadavg_1min") is not None]
    if loads:
        loads.sort()
        rows.append(("1-min load average at the end of each case",
                     f"median {fmt(loads[len(loads) // 2])}, range {fmt(loads[0])}–{fmt(loads[-1])} "
                     f"({len(loads)} cases)"))
    rows.append(("memory figure", context.get("peak_memory", "–")))
    w(table(("", ""), rows))
    w("")
    w("Times are wall-clock medians over the iterations of each case (Google Benchmark manual")
    w("time around the synchronous `Renderer::render` or `Renderer::backward` call, after one")
    w("untimed warm-up call that builds the kernels). The machine has two cores and may be")
    w("shared: a 1-minute load average above 2 means other processes competed for them, and")
    w("times measured then are longer than the renderer alone would take; *best ms* (the")
    w("fastest iteration) shows how far. Even at a low load average and the same measured FMA")
    w("ceiling, whole runs of the suite on this 2-core virtual machine have differed by up to")
    w("about 60 % in the same case, so a target within that margin of its limit can come out")
    w("either way from run to run. The measurements behind the explanations below are dated in")
    w("[benchmarks-log.md](benchmarks-log.md).")
    w("The Debian `libbenchmark` package prints *Library was built as DEBUG*; that concerns the")
    w("harness, not the measured code (penumbra is built Release).")
    w("")

    # Ceiling.
    fma = res.find("ceiling", what="fma")
    ex = res.find("ceiling", what="exp")
    nex = res.find("ceiling", what="native_exp")
    def best(r, key):  # the rate of the fastest iteration
        return r[key] * r["ms_median"] / r["ms_min"] if r and r.get("ms_min") else None
    peak_median = fma["gflops"] if fma else None
    peak = best(fma, "gflops")
    exp_rate = best(ex, "gexp_per_s") * 1e9 if ex else None
    w("## The machine's ceiling")
    w("")
    w("Small compute-bound OpenCL kernels through the same PoCL device (`bench/bench_ceiling.cpp`:")
    w("64 work-items, each 12 independent float16 chains):")
    w("")
    rows = []
    if fma:
        rows.append(("FMA, float32", f"{fmt(peak_median)} GFLOP/s", f"{fmt(peak)} GFLOP/s"))
    if ex:
        rows.append(("`exp`, float32", f"{fmt(ex['gexp_per_s'])} G exp/s",
                     f"{fmt(best(ex, 'gexp_per_s'))} G exp/s"))
    if nex:
        rows.append(("`native_exp`, float32", f"{fmt(nex['gexp_per_s'])} G exp/s",
                     f"{fmt(best(nex, 'gexp_per_s'))} G exp/s"))
    w(table(("kernel", "median", "best (the ceiling)"), rows) if rows else "(not measured)")
    w("")
    w("The ceiling is the fastest iteration (*best*): the medians include whatever else the")
    w("machine ran. Below, *% of peak* divides a GFLOP/s figure by the best FMA figure, and")
    w("*% of exp* divides texel samples per second by the best `exp` rate, as if each sample cost")
    w("one exp (truncated and soft sampling, whose per-texel work is a Gaussian or sigmoids; the")
    w("hard exact and gemm paths are products and are compared with the FMA peak instead).")
    w("")

    # Targets.
    w("## Targets")
    w("")
    w("The turnaround scene (1312 faces), 256² image, 256² map, the paper's shadow model at its")
    w("σ_s = 2, one light, this machine (the accuracy section compares the two models' times).")
    w("")
    def against(r):
        if not r:
            return "–"
        if r.get("gflops") and peak and dense_products(r):
            return f"{fmt(r['gflops'])} GFLOP/s = {fmt(r['gflops'] / peak * 100, 2)} % of FMA peak"
        if r.get("gflops") and peak:
            dense = res.render(r["pass_"], shadows="hard", sampling="exact", sigma_s=DENSE_SIGMA_S)
            out = f"{fmt(r['gflops'])} GFLOP/s dense-equivalent"
            if dense and dense.get("gflops"):
                out += (f"; dense at σ_s = {DENSE_SIGMA_S:g}: {fmt(dense['gflops'])} GFLOP/s = "
                        f"{fmt(dense['gflops'] / peak * 100, 2)} % of FMA peak")
            return out
        if r.get("samples_per_s") and exp_rate and r.get("sampling") != "exact":
            return (f"{si(r['samples_per_s'])} samples/s = "
                    f"{fmt(r['samples_per_s'] / exp_rate * 100, 2)} % of exp rate")
        if r.get("pixel_face_pairs_per_s"):
            return f"{si(r['pixel_face_pairs_per_s'])} pixel·face pairs/s"
        return "–"

    rows = []
    for label, want, limit in FRAME_TARGETS:
        r = res.render("fwd", **want)
        v, by = verdict(ms(r), limit)
        rows.append((f"{label} ≤ {limit:g} ms", f"{fmt(ms(r))} ms", v, by, against(r)))
    for sh, sa in (("none", "truncated"), ("hard", "truncated"), ("soft", "truncated"),
                   ("hard", "exact"), ("hard", "gemm")):
        bwd_ms, ratio = bwd_over_fwd(res, sh, sa)
        v, by = verdict(ratio, 3.0)
        rows.append((f"backward ≤ 3× forward ({sh}, {sa})",
                     f"{fmt(bwd_ms)} ms = {fmt(ratio)}× forward" if ratio else "–", v, by,
                     against(res.render("bwd", shadows=sh, sampling=sa))))
    ta = {sh: res.find("turnaround", shadows=sh) for sh in ("none", "hard", "soft")}
    soft_s = ta["soft"]["seconds"] if ta["soft"] else None
    v, by = verdict(soft_s, 3.0)
    rows.append(("90-frame soft turnaround ≤ 3 s", f"{fmt(soft_s)} s", v, by, "–"))
    for sh, limit in (("hard", 3.0), ("soft", 8.0)):
        ratio = (ta[sh]["seconds"] / ta["none"]["seconds"]) if ta[sh] and ta["none"] else None
        v, by = verdict(ratio, limit)
        rows.append((f"turnaround {sh}/none ≤ {limit:g}", fmt(ratio), v, by, "–"))
    big = res.render("fwd", shadows="none", sampling="truncated", img=512, faces=100852)
    v, by = verdict(ms(big), 30.0)
    rows.append(("512², 100 852 faces, no shadows, forward ≤ 30 ms", f"{fmt(ms(big))} ms", v, by,
                 against(big)))
    both = fwd_plus_bwd(res, faces=100852)
    v, by = verdict(both, 200.0)
    rows.append(("256², 100 852 faces, hard shadows, forward + backward ≤ 200 ms",
                 f"{fmt(both)} ms" if both is not None else "–", v, by, "–"))
    w(table(("target", "measured (median)", "", "by how much",
             "throughput (against the ceiling where one applies)"), rows))
    w("")
    if res.all("step"):
        w("The backward/forward quotients and the 100k-face forward + backward come from the")
        w("`step/...` cases: a render and then its backward, in turn, as each step of an")
        w("optimisation takes them, so that both calls meet the same machine (the separate `fwd`")
        w("and `bwd` cases run minutes apart); the sum is the median step.")
        w("")
    missed = [row[0] for row in rows if row[2] == "**missed**"]
    reasons = []
    for start, why in MISS_REASONS:
        hits = [m for m in missed if m.startswith(start)]
        if hits:
            reasons.append(f"- *{'; '.join(hits)}*: {why}")
    if reasons:
        w("Why the missed targets are missed:")
        w("")
        w("\n".join(reasons))
        w("")

    # Where the time goes.
    w("## Where the time goes")
    w("")
    w(stage_notes(res, peak, exp_rate, profiles))
    w("")
    prof = profile_section(res, profiles, peak, exp_rate)
    if prof:
        w(prof)
        w("")

    # Matrix.
    w("## Shadows × sampling (reference point)")
    w("")
    w("256² image, 256² map (soft exact: 64² in the default suite, 256² under `large/`), 1312")
    w("faces, σ_s = 2, one light. N is the number of fragments the camera's view kept")
    w("(`Renderer::fragment_counts`): the fragments whose shadow terms the lookup samples.")
    w("")
    rows = []
    for pass_ in ("fwd", "bwd"):
        for sh, sa, mp in (("none", "truncated", 256), ("hard", "truncated", 256),
                           ("hard", "exact", 256), ("hard", "gemm", 256),
                           ("soft", "truncated", 256), ("soft", "exact", 64),
                           ("soft", "exact", 256)):
            r = res.render(pass_, shadows=sh, sampling=sa, map=mp)
            if not r:
                continue
            g = r.get("gflops")
            sps = r.get("samples_per_s")
            # Products are compared with the FMA peak; exact sums skip the texels of weight 0.
            exp_sps = sps if not g and sa != "exact" else None
            rows.append(("forward" if pass_ == "fwd" else "backward", f"{sh} / {sa}", f"{mp}²",
                         fmt(ms(r)), fmt(r.get("ms_min")), fmt(r.get("frames_per_s")),
                         si(r.get("pixel_face_pairs_per_s")), si(sps),
                         f"{fmt(exp_sps / exp_rate * 100, 2)} %" if exp_sps and exp_rate else "–",
                         (fmt(g) if dense_products(r) else f"{fmt(g)} (dense-eq.)") if g else "–",
                         f"{fmt(g / peak * 100, 2)} %" if g and peak and dense_products(r)
                         else "–",
                         f"{fmt(r.get('peak_rss_MiB'))} ({fmt(r.get('rss_at_start_MiB'))})"
                         if r.get("rss_at_start_MiB") else fmt(r.get("peak_rss_MiB"))))
    w(table(("pass", "shadows / sampling", "map", "median ms", "best ms", "frames/s",
             "pixel·face pairs/s", "samples/s", "% of exp", "GFLOP/s", "% of peak",
             "peak RSS MiB (at start)"), rows))
    w("")
    w("*pixel·face pairs/s* counts the brute-force pairs, (W·H + lights·W_s·H_s when shadows are")
    w("on)·faces, per second: a size-normalised speed (tiling visits far fewer pairs). *samples/s*")
    w("counts texels weighed per second: N·(2R)² per light truncated, R = sqrt(2σ_s·ln(1/ε_λ)),")
    w("N·W_s·H_s exact and gemm (exact: every texel counted, though the kernels skip those whose")
    w("weight is exactly 0; no % of exp). *GFLOP/s* (hard exact and gemm): products·2·N·W_s·H_s per light")
    w("per frame (one product forward, three backward) over the whole-frame time; for exact on")
    w("penumbra's kernels a dense-equivalent figure (*dense-eq.*, no % of peak): they skip the")
    w("weights that are exactly 0 and execute far fewer flops (the σ_s sweep's dense cases, σ_s =")
    w(f"{DENSE_SIGMA_S:g}, run them on every weight). *Peak RSS*")
    w("is the process's resident-memory high-water mark during the case (device buffers of PoCL's")
    w("CPU device are host memory); in brackets, the resident size when the case began, which")
    w("still holds what earlier cases left allocated, so only the difference is the case's own.")
    w("")

    # Sweeps.
    plots = {}
    if plt:
        plots["res"] = plot_sweep(plt, res, "img", "image size W = H (pixels)",
                                  os.path.join(image_dir, "bench_time_vs_resolution.png"))
        plots["map"] = plot_sweep(plt, res, "map", "shadow-map size W_s = H_s (texels)",
                                  os.path.join(image_dir, "bench_time_vs_map.png"))
        plots["faces"] = plot_sweep(plt, res, "faces", "faces",
                                    os.path.join(image_dir, "bench_time_vs_faces.png"))
        plots["memory"] = plot_sweep(plt, res, "faces", "faces",
                                     os.path.join(image_dir, "bench_memory_vs_faces.png"),
                                     value=device_mib, ylabel="device memory of one call (MiB)")
        plots["sigma_s"] = plot_sweep(plt, res, "sigma_s", "σ_s (texel²)",
                                      os.path.join(image_dir, "bench_time_vs_sigma_s.png"))
        plots["tradeoff"] = plot_tradeoff(plt, res, os.path.join(image_dir, "bench_error_vs_time.png"))

    for key, title, xname, plot in (
            ("img", "Image size", "image", "res"), ("map", "Shadow-map size", "map", "map"),
            ("faces", "Face count", "faces", "faces"), ("sigma_s", "σ_s", "σ_s", "sigma_s"),
            ("lights", "Lights", "lights", None)):
        data = sweep(res, key)
        if not data:
            continue
        xs = sorted({x for pts in data.values() for x, _ in pts})
        if len(xs) < 2:
            continue
        w(f"## {title}")
        w("")
        w(sweep_intro(key))
        w("")
        rows = []
        for pass_, sh, sa, label, *_ in SERIES + [("fwd", "soft", "exact", "forward, soft exact", "", ""),
                                                   ("bwd", "soft", "exact", "backward, soft exact", "", ""),
                                                   ("bwd", "hard", "gemm", "backward, hard gemm", "", "")]:
            pts = dict(data.get((pass_, sh, sa), []))
            if len(pts) < 1 or any(r[0] == label for r in rows):
                continue
            rows.append([label] + [fmt(pts.get(x)) for x in xs])
        w(table([f"median ms \\ {xname}"] + [fmt(x) if key == "sigma_s" else str(x) for x in xs], rows))
        w("")
        if plot and plots.get(plot):
            w(f"![time vs {xname}]({rel_images}/bench_time_vs_{ {'res': 'resolution'}.get(plot, plot) }.png)")
            w("")
        if key in ("img", "faces"):
            L.extend(work_lines(res, key, xname))
        if key == "faces":
            L.extend(memory_lines(res, plots.get("memory"), rel_images))

    # Turnaround.
    w("## The paper's turnaround")
    w("")
    w("90 frames of `data/scenes/turnaround.json` at 256² (256² map, truncated sampling), camera 0")
    w("orbiting 360° about +y through its target, forward only, one warm-up frame first. The")
    w("paper's figures (1 s, 33 s and 104 s for the 90 frames) were measured on a GPU.")
    w("")
    rows = []
    for sh in ("none", "hard", "soft"):
        r = ta[sh]
        if not r:
            continue
        ratio = r["seconds"] / ta["none"]["seconds"] if ta["none"] else None
        rows.append((sh, fmt(r["seconds"]), fmt(r["ms_median"]), fmt(ratio),
                     fmt(PAPER[sh][0]), fmt(PAPER[sh][1])))
    w(table(("shadows", "90 frames (s)", "median ms/frame", "ratio to none", "paper (s)",
             "paper ratio"), rows) if rows else "(not run)")
    w("")

    # Accuracy.
    L.extend(accuracy_section(res, plots.get("tradeoff"), rel_images, accuracy_images, image_dir))

    if first_call:  # bench/first_call.py's section, from its own runs
        L.extend(first_call)

    # Large and failed.
    large = [r for r in res.records if r["large"]]
    w("## Large cases")
    w("")
    if large:
        w("The large cases of this run (`scripts/bench.sh --large` runs all of them, `--scaling`")
        w("those of the face and image sweeps, which the tables above include):")
        w("")
        rows = [(r["name"].replace("/manual_time", ""), fmt(ms(r)), fmt(device_mib(r)))
                for r in large]
        w(table(("case", "median ms", "device MiB"), rows))
    else:
        w("The cases named `large/...` (1024² and 2048² images, 1024² maps, 200k and 1M faces, soft")
        w("exact at 256², exact and gemm at 512² and more) were not part of this run;")
        w("`scripts/bench.sh --large` runs them too, which takes much longer than the default suite.")
    w("")
    if res.errors:
        w("## Cases that failed")
        w("")
        w(table(("case", "error"), [(r["name"], r["error"]) for r in res.errors]))
        w("")

    L.extend(files_section())
    docfile.write_text(doc_path, "\n".join(L))
    print(f"report: wrote {doc_path}" + (f" and plots in {image_dir}" if plt else ""))


def ns_per_fragment(r):
    """A case's median time per fragment the camera's view kept (counter `fragments`), in ns."""
    return ms(r) * 1e6 / r["fragments"] if ms(r) and r.get("fragments") else None


def work_lines(res, key, xname):
    """Time per kept fragment along the image or face sweep: whether a frame's cost grows with
    its work and not faster."""
    per = sweep(res, key, ns_per_fragment)
    kept = dict(sweep(res, key, lambda r: r.get("fragments")).get(("fwd", "none", "truncated"), []))
    xs = sorted(kept)
    if len(xs) < 2:
        return []
    rows, spans = [["kept fragments N"] + [fmt(kept[x]) for x in xs]], []
    for pass_, sh, sa, label, *_ in SERIES:
        pts = dict(per.get((pass_, sh, sa), []))
        if len(pts) < 2:
            continue
        rows.append([label] + [fmt(pts.get(x)) for x in xs])
        lo, hi = min(pts.values()), max(pts.values())
        spans.append(f"{label} {fmt(lo)} to {fmt(hi)} ns (×{fmt(hi / lo)})")
    return ["The work of a frame is the fragments the camera's view keeps (N, counter `fragments`: "
            "`Renderer::fragment_counts`): the (pixel, face) pairs whose aggregation weight is at "
            "least ε_w times the pixel's largest. Median time per kept fragment (ns), the "
            "light's pass and the fixed costs of a frame included:",
            "",
            table([f"ns per fragment \\ {xname}"] + [str(x) for x in xs], rows),
            "",
            f"From N = {fmt(kept[xs[0]])} to {fmt(kept[xs[-1]])}: " + "; ".join(spans) + ". "
            "`raster_count` evaluates every pixel that a face's cut-off box reaches, whether it "
            "keeps a fragment there or not, and binning costs per face: the smaller the faces, "
            "the more of that work per kept fragment.",
            ""]


def memory_lines(res, plotted, rel_images):
    """The face sweep's device memory: one call's peak (device_MiB) per face count, and what
    each face adds between the smallest and the largest mesh."""
    data = sweep(res, "faces", device_mib)
    xs = sorted({x for pts in data.values() for x, _ in pts})
    if len(xs) < 2:
        return []
    rows, slopes = [], []
    for pass_, sh, sa, label, *_ in SERIES:
        pts = data.get((pass_, sh, sa), [])
        if len(pts) < 2:
            continue
        rows.append([label] + [fmt(dict(pts).get(x)) for x in xs])
        (x0, m0), (x1, m1) = pts[0], pts[-1]
        slopes.append(f"{label} {fmt((m1 - m0) * 2 ** 20 / (x1 - x0))}")
    L = ["Device memory of one call: the most the renderer's buffers held at once during the",
         "warm-up `render` (and, for backward cases, the `backward` after it), from",
         "`penumbra::device_memory_use` (counter `device_MiB`). Most of what grows with the face",
         "count is the kept fragments: the faces whose soft coverage reaches a pixel all keep one",
         "there, more of them the smaller the faces.",
         "",
         table(["device MiB \\ faces"] + [str(x) for x in xs], rows),
         "",
         f"Bytes per added face, from {xs[0]} to {xs[-1]} faces: " + "; ".join(slopes) + ".",
         ""]
    if plotted:
        L += [f"![device memory vs faces]({rel_images}/bench_memory_vs_faces.png)", ""]
    return L


def sweep_intro(key):
    return {
        "img": "Image size W = H, everything else at the reference point (256² map, 1312 faces).",
        "map": "Shadow-map size W_s = H_s at a 256² image. Gemm hard shadows cost O(N·W_s·H_s) "
               "(CLBlast multiplies every weight); exact ones O(N·(W_s + H_s)) for the weights "
               "plus products over those not exactly 0 (about 37 texels a side at σ_s = 2); "
               "truncated ones O(N·R²); all plus the light pass, O(W_s·H_s).",
        "faces": "Face count: the bundled 1280-face sphere, then icospheres of geodesic frequency "
                 "16, 32, 50, 71 (100 and 224 in the large cases) — 20·n² faces — on the 32-face "
                 "ground plane, 256² image and map.",
        "sigma_s": "σ_s (texel²) at the reference point: the truncated window has radius "
                   "R = sqrt(2σ_s·ln(1/ε_λ)), so its area grows linearly with σ_s; the exact "
                   "sums leave out the weights beyond sqrt(174·σ_s) texels (exactly 0 in "
                   f"float), which grows the same way. At σ_s = {DENSE_SIGMA_S:g} (hard exact "
                   "only) no weight of the 256² map is 0: the products run dense.",
        "lights": "Lights: one shadow map (and penumbra map) per light; lights 2 and 3 are light 0 "
                  "turned about +y by 120° and 240°.",
    }[key]


def linfit(pts):
    n = len(pts)
    if n < 2:
        return None
    mx = sum(x for x, _ in pts) / n
    my = sum(y for _, y in pts) / n
    sxx = sum((x - mx) ** 2 for x, _ in pts)
    if sxx == 0:
        return None
    b = sum((x - mx) * (y - my) for x, y in pts) / sxx
    return my - b * mx, b


def stage_notes(res, peak, exp_rate, profiles):
    """Stage attribution from differences between cases (no per-kernel timers)."""
    f = {k: ms(res.render("fwd", shadows=k[0], sampling=k[1])) for k in
         (("none", "truncated"), ("hard", "truncated"), ("hard", "exact"), ("hard", "gemm"),
          ("soft", "truncated"))}
    b = {k: ms(res.render("bwd", shadows=k[0], sampling=k[1])) for k in f}
    out = []
    none, hard, soft = f[("none", "truncated")], f[("hard", "truncated")], f[("soft", "truncated")]
    if none and hard:
        out.append(f"- **Forward, no shadows** ({fmt(none)} ms) is the camera pass alone: transform, "
                   f"binning, the three raster passes and the copy of the outputs to the host.")
        s = (f"- **Hard shadows, truncated** ({fmt(hard)} ms) add {fmt(hard - none)} ms: the light's "
             f"raster pass (a 256² soft depth map) plus the truncated lookup of every fragment.")
        pts = [(r[0], r[1]) for r in sweep(res, "sigma_s").get(("fwd", "hard", "truncated"), [])]
        fit = linfit(pts)
        sane = False
        if fit and len(pts) >= 3:
            a, slope = fit
            my = sum(y for _, y in pts) / len(pts)
            ss_tot = sum((y - my) ** 2 for _, y in pts)
            ss_res = sum((y - a - slope * x) ** 2 for x, y in pts)
            r2 = 1 - ss_res / ss_tot if ss_tot > 0 else 0
            # Only a clean line says something: rising, through the points, above "none".
            sane = slope > 0 and r2 >= 0.9 and none <= a <= hard
        if sane:
            s += (f" A straight line through time vs σ_s ({len(pts)} points, R² = {r2:.2f}, σ_s "
                  f"{fmt(min(p[0] for p in pts), 2)}–{fmt(max(p[0] for p in pts), 2)}) has "
                  f"slope {fmt(slope)} ms per texel² and meets σ_s = 0 at {fmt(a)} ms, so at σ_s = 2 "
                  f"the lookup's window-dependent part is about {fmt(2 * slope)} ms and the light pass "
                  f"with the fixed costs about {fmt(a - none)} ms.")
        mp = dict(sweep(res, "map").get(("fwd", "hard", "truncated"), []))
        if 64 in mp and 256 in mp:
            s += (f" Shrinking the map to 64² takes the frame from {fmt(mp[256])} to "
                  f"{fmt(mp[64])} ms.")
        out.append(s)
    if soft and hard:
        out.append(f"- **Soft shadows, truncated** ({fmt(soft)} ms) add {fmt(soft - hard)} ms to "
                   f"hard ones: the penumbra map P of the light (every texel against the occluders "
                   f"binned near it) and the compare-then-filter lookup (two sigmoids per texel "
                   f"instead of one filtered depth).")
    ex, gm = f[("hard", "exact")], f[("hard", "gemm")]
    if ex and none:
        r = res.render("fwd", shadows="hard", sampling="exact")
        flops = r["gflops"] * ex * 1e-3 if r.get("gflops") else None
        s = (f"- **Hard exact** ({fmt(ex)} ms) spends {fmt(ex - none)} ms beyond the camera "
             f"pass on the light pass and the exact sum (N ≈ {fmt(r.get('fragments'))}")
        if flops:
            s += f", {fmt(flops)} GFLOP per frame if every weight were multiplied"
        s += ")."
        mm = matmul_rate(res, profiles)
        if mm and mm[0]:
            rate, mm_ms, w_ms, total_ms = mm
            s += (f" Per profiled frame the product kernels took {fmt(mm_ms)} ms "
                  f"({fmt(rate)} GFLOP/s dense-equivalent: they skip the weights that are "
                  f"exactly 0, beyond about 18.7 texels of μ) and the Gaussian weight matrices "
                  f"Gx, Gy (`exact_weights`) {fmt(w_ms)} ms, of {fmt(total_ms)} ms of kernel "
                  f"time.")
            dense = res.render("fwd", shadows="hard", sampling="exact", sigma_s=DENSE_SIGMA_S)
            if dense and dense.get("gflops") and peak:
                s += (f" Where no weight is 0 (σ_s = {DENSE_SIGMA_S:g}) the products run dense: "
                      f"{fmt(ms(dense))} ms a frame, {fmt(dense['gflops'])} GFLOP/s over the "
                      f"whole frame = {fmt(dense['gflops'] / peak * 100, 2)} % of the FMA "
                      f"ceiling")
                dm = matmul_rate(res, profiles, dense=True)
                if dm and dm[0]:
                    s += (f"; the product kernels alone took {fmt(dm[1])} ms of it, "
                          f"{fmt(dm[0])} GFLOP/s = {fmt(dm[0] / peak * 100, 2)} % of the "
                          f"ceiling")
                s += "."
            if exp_rate and r.get("fragments"):
                exps = weight_exps(r)
                s += (f" Those weights are N·(W_s + H_s) = {si(exps)} exps at most, "
                      f"{fmt(exps / exp_rate * 1e3)} ms at the measured exp rate (the exps "
                      f"below the smallest normal number are skipped).")
        elif flops:
            s += (f" Counting the whole difference as product time gives ≥ "
                  f"{fmt(flops / ((ex - none) * 1e-3))} GFLOP/s dense-equivalent.")
        if gm:
            s += f" CLBlast's GEMM (gemm, {fmt(gm)} ms) takes {fmt(gm / ex)}× the direct kernels' time."
        out.append(s)
    parts = []
    for k, label in ((("none", "truncated"), "none"), (("hard", "truncated"), "hard truncated"),
                     (("soft", "truncated"), "soft truncated"), (("hard", "exact"), "hard exact"),
                     (("hard", "gemm"), "hard gemm")):
        ratio = bwd_over_fwd(res, *k)[1]
        if ratio:
            parts.append(f"{label} {fmt(ratio)}×")
    if parts:
        out.append("- **Backward / forward**: " + ", ".join(parts) + ". The backward call "
                   "re-runs no forward stage; it walks the stages in reverse (resolve, shadow "
                   "lookup, texel gathers, raster per face, transform per vertex) and copies the "
                   "gradients to the host.")
    acc = []
    for sh in ("hard", "soft"):
        f, b = (res.render(p, shadows=sh, sampling="truncated", model="accurate")
                for p in ("fwd", "bwd"))
        if ms(f) and ms(b):
            acc.append(f"{sh} forward {fmt(ms(f))} ms, backward {fmt(ms(b))} ms "
                       f"({fmt(ms(b) / ms(f))}×)")
    if acc:
        out.append("- **The accurate model** (the renderer's default; truncated, the same "
                   "settings as above, so a 256² map where its default is 384²): "
                   + "; ".join(acc) + ".")
    big = [(sh, step(res, shadows=sh, sampling="truncated", faces=100852, model=model))
           for model in ("paper", "accurate") for sh in ("hard", "soft")]
    big = [f"{s['model']} {sh} {fmt(s['ms_median'])} ms (forward {fmt(s['ms_fwd'])}, backward "
           f"{fmt(s['ms_bwd'])})" for sh, s in big if s and s.get("ms_fwd")]
    if big:
        out.append("- **100 852 faces, a render and its backward** (`step` cases, 256² image and "
                   "map, truncated): " + "; ".join(big) + ".")
    fc = sweep(res, "faces").get(("fwd", "none", "truncated"), [])
    if len(fc) >= 2:
        (f0, t0), (f1, t1) = fc[0], fc[-1]
        out.append(f"- **Faces**: from {f0} to {f1} faces (×{fmt(f1 / f0)}) the no-shadow forward "
                   f"goes from {fmt(t0)} to {fmt(t1)} ms (×{fmt(t1 / t0)}).")
    rs = sweep(res, "img").get(("fwd", "none", "truncated"), [])
    if len(rs) >= 2:
        (x0, t0), (x1, t1) = rs[0], rs[-1]
        out.append(f"- **Pixels**: from {x0}² to {x1}² (×{fmt((x1 / x0) ** 2)} pixels) the "
                   f"no-shadow forward goes from {fmt(t0)} to {fmt(t1)} ms (×{fmt(t1 / t0)}).")
    return "\n".join(out) if out else "(not enough cases measured)"


def acc_case(res, scene, model, shadows, sampling, exact_map=None):
    for r in res.all("accuracy"):
        if (r["scene"], r["model"], r["shadows"], r["sampling"]) != (scene, model, shadows, sampling):
            continue
        if exact_map is None and acc_ref(r):
            return r
        if r.get("default_sigma_s") == 1 and r["map"] == exact_map:
            return r
    return None


def acc_ratio(res, scene, shadows, default_maps=False):
    """The accurate/paper forward time case of a scene and mode (frames of the two in turn),
    both at a 256² map, or each at its own default map."""
    for r in res.all("accuracy_ratio"):
        if ((r["scene"], r["shadows"]) == (scene, shadows) and r.get("time_ratio")
                and (r.get("maps") == "default") == default_maps):
            return r
    return None


def accuracy_rows(res):
    """The table of every scene, model, mode and sampling (reference σ_s; every map measured)."""
    rows = []
    order = {"none": 0, "hard": 1, "soft": 2}
    samp = {"truncated": 0, "exact": 1, "gemm": 2}
    acc = sorted(res.all("accuracy"), key=lambda r: (
        ACC_SCENES.index(r["scene"]) if r["scene"] in ACC_SCENES else 99, r["model"] != "accurate",
        order[r["shadows"]], samp[r["sampling"]], r["map"], r["sigma_s"]))
    for r in acc:
        rows.append((r["scene"], r["model"] if r["shadows"] != "none" else "–",
                     f"{r['shadows']} / {r['sampling']}", f"{r['map']}²", fmt(r["sigma_s"], 2),
                     fmt(ms(r)), fmt(r.get("area_ratio")), fmt(r.get("lit_error")),
                     fmt(r.get("rmse_shadow")), fmt(r.get("leak"))))
    return rows


def accuracy_target_rows(res):
    """The issue's targets for the accurate model, truncated, per scene and mode."""
    rows, misses = [], []
    for sc in ACC_SCENES:
        for sh in ("hard", "soft"):
            a = acc_case(res, sc, "accurate", sh, "truncated")
            p = acc_case(res, sc, "paper", sh, "truncated")
            ratio = acc_ratio(res, sc, sh)
            if not a:
                continue
            checks = [("area", a.get("area_ratio"), lambda x: abs(x - 1) <= ACC_TARGETS["area"]),
                      ("lit", a.get("lit_error"), lambda x: x <= ACC_TARGETS["lit"]),
                      ("rmse", a.get("rmse_shadow"), lambda x: x <= ACC_TARGETS["rmse"]),
                      ("leak", a.get("leak"), lambda x: x <= ACC_TARGETS["leak"]),
                      ("time", ratio["time_ratio"] if ratio else None,
                       lambda x: x <= ACC_TARGETS["time"])]
            cells = []
            for name, x, ok in checks:
                if x is None:
                    cells.append("–")
                    continue
                good = ok(x)
                digits = 4 if name == "area" else 3  # enough to show which side of 5 %
                cells.append(fmt(x, digits) + ("" if good else " **missed**"))
                if not good:
                    misses.append(f"{sc} {sh}: {name} {fmt(x, digits)}")
            rows.append([sc, sh] + cells)
    return rows, misses


def accuracy_section(res, tradeoff_plot, rel_images, accuracy_images, image_dir):
    L = []
    w = L.append
    w("## Accuracy beside cost")
    w("")
    acc = res.all("accuracy")
    if not acc:
        w("(not run: the accuracy group needs Embree 3 at build time — Debian `libembree-dev`.)")
        w("")
        return L
    w("Each shadow model, mode and sampling against a ground truth ray-traced with Embree on the")
    w("CPU (`bench/truth.cpp`): the same geometry, camera and Lambert + ambient shading, one")
    w("primary ray per pixel centre, visibility from shadow rays — one to the point light (the")
    w("truth of hard shadows and of none) or 256 stratified points on the disc of a sphere light")
    w("of diameter D_L = 0.5 (the truth of soft shadows). Camera 0 of the turnaround scene at")
    w("256², default settings, on these scenes (`bench/accuracy.cpp`):")
    w("")
    for sc in ACC_SCENES:
        if any(r["scene"] == sc for r in acc):
            w(f"- `{sc}`: {ACC_SCENE_WORDS[sc]};")
    w("")
    w("and these measures, over ground pixels (the rays of the pixel and of every pixel within")
    w("2 px hit the ground: silhouettes, where the soft rasterizer blends a nearer surface in,")
    w("are left out — its coverage stays above the cut-off ε_D out to √(σ ln(1/ε_D − 1)), 1.2 px")
    w("at the default σ; the margin is that, rounded up). penumbra's")
    w("visibility is its per-pixel shadow term, s = (C − C_ambient)/(C_unshadowed − C_ambient)")
    w("from three renders of the same scene:")
    w("")
    w("- *area*: ground pixels with s < 0.5 over those with truth visibility < 0.5 (1 is right);")
    w("- *lit error*: mean relative colour error Σ|C − T|/ΣT over ground pixels the truth lights")
    w("  fully;")
    w("- *shadow RMSE*: RGB RMSE over ground pixels within 8 px of the sphere light's shadow")
    w("  (penumbra included; the same pixels for every method of a scene);")
    w("- *leak*: of the ground pixels within 3 px of where the caster touches the ground that the")
    w("  truth shadows, the fraction penumbra lights (– where nothing touches the ground).")
    w("")
    rows, misses = accuracy_target_rows(res)
    if rows:
        w("### The accurate model's targets")
        w("")
        w("Truncated sampling, the model's default map (accurate 384², paper 256²). Targets:")
        w(f"area within {100 * ACC_TARGETS['area']:g} % of the truth, lit error ≤ "
          f"{100 * ACC_TARGETS['lit']:g} %, shadow RMSE ≤ {ACC_TARGETS['rmse']}, no leak")
        w("(`bench/test_accuracy.cpp`, run by ctest as `bench_accuracy_targets`, asserts these),")
        w(f"forward time ≤ {ACC_TARGETS['time']}× the paper model's at equal settings: the medians")
        w("of the `accuracy/ratio` cases, both models at a 256² map, which render a frame of each")
        w("in turn so that the load of this shared machine weighs on both alike (the forward times")
        w("of the tables below, each model at its own default map, come from separate cases,")
        w("minutes apart).")
        w("")
        w(table(("scene", "shadows", "area ratio", "lit error", "shadow RMSE", "leak",
                 "time / paper"), rows))
        w("")
        w(f"Missed ({len(misses)}): " + ("; ".join(misses) if misses else "none") + ".")
        w("")
        sums, defaults = [], []
        for sh in ("hard", "soft"):
            for default_maps, out in ((False, sums), (True, defaults)):
                pairs = [acc_ratio(res, sc, sh, default_maps) for sc in ACC_SCENES]
                if not (pairs and all(pairs)):
                    continue
                ratio = sum(r["ms_accurate"] for r in pairs) / sum(r["ms_paper"] for r in pairs)
                missed = not default_maps and ratio > ACC_TARGETS["time"]
                out.append(f"{sh} {fmt(ratio)}" + (" (**missed**)" if missed else ""))
        if sums:
            w("Forward time of the accurate model over the paper model's, medians summed over the")
            w("scenes: " + ", ".join(sums) + ".")
            w("")
        if defaults:
            w("The same with each model at its own default map (accurate 384², paper 256²; the")
            w("`accuracy/ratio/.../maps:default` cases, a frame of each in turn): "
              + ", ".join(defaults) + ".")
            w("")
    w("### Every model, mode and sampling")
    w("")
    w("Exact sampling weighs every texel of the map whose weight is not 0 for every fragment (the")
    w("kernels leave out the rest): the default suite runs it at a 128² map, the `large/` cases at")
    w("256². σ_s is each model's")
    w("default (accurate 0.35 texel², paper 2) unless the sphere scene varies it, with the map")
    w("size, under truncated sampling.")
    w("")
    w(table(("scene", "model", "shadows / sampling", "map", "σ_s", "forward ms", "area ratio",
             "lit error", "shadow RMSE", "leak"), accuracy_rows(res)))
    w("")
    if tradeoff_plot:
        w("Shadow-region error against forward time (green: accurate, red: paper; filled: hard,")
        w("hollow: soft; dashed: the 0.05 target):")
        w("")
        w(f"![error vs time]({rel_images}/bench_error_vs_time.png)")
        w("")
    copied = copy_comparisons(accuracy_images, image_dir)
    if copied:
        w("Truth | accurate model | difference (red: penumbra darker, blue: brighter, ×4) of every")
        w("scene: [shadows.md](shadows.md#against-a-ray-tracer).")
        w("")
    return L


def write_accuracy_only(context, records, machine, doc_path, image_dir, accuracy_images):
    """The accuracy section alone, from a run of that group, with the run's own machine lines."""
    res = Results(records)
    plt = get_plt()
    os.makedirs(image_dir, exist_ok=True)
    rel_images = os.path.relpath(image_dir, os.path.dirname(os.path.abspath(doc_path)))
    tradeoff = plt and plot_tradeoff(plt, res, os.path.join(image_dir, "bench_error_vs_time.png"))
    lines = accuracy_section(res, tradeoff, rel_images, accuracy_images, image_dir)
    m = machine or {}
    loads = sorted(r["loadavg_1min"] for r in res.records if r.get("loadavg_1min") is not None)
    run = [f"This section comes from its own run of the accuracy group, {context.get('date', '–')}:",
           f"`{m.get('command', '–')}` on {context.get('device', '–')} ({m.get('nproc', '–')} cores),",
           f"load average {m.get('loadavg_before', context.get('loadavg_at_start', '–'))} before,",
           f"{m.get('loadavg_after', '–')} after"]
    if loads:
        run[-1] += f", 1-min load at the end of each case {fmt(loads[0])}–{fmt(loads[-1])}"
    run[-1] += (" (the machine is shared: above 2, other processes competed for its two cores and"
                " times are longer than penumbra alone would take).")
    docfile.replace_section(doc_path, lines[:2] + run + [""] + lines[2:])
    docfile.replace_section(doc_path, files_section())


def files_section():
    return [
        "## Files",
        "",
        "- `bench/bench_render.cpp` forward and backward cases; `bench/bench_turnaround.cpp` the",
        "  90-frame orbit; `bench/bench_accuracy.cpp` the accuracy cases, with the Embree ground",
        "  truth in `bench/truth.cpp` and the scenes and measures in `bench/accuracy.cpp`;",
        "  `bench/bench_ceiling.cpp` the FMA and exp ceilings; `bench/common.cpp` scenes (the",
        "  icosphere generator), timing and counters; `bench/main.cpp` the default filter.",
        "- `bench/report.py` this page and the plots; `scripts/bench.sh` the whole pipeline",
        "  (`--accuracy`: the accuracy group alone, which rewrites only its section and this one).",
        "- `bench/first_call.py` the first render in new processes, kernel caches cold and warm,",
        "  and PoCL's floor (`bench/bench_build_floor.cpp`, `penumbra_bench --build-floor`) (its",
        "  section; `--doc docs/benchmarks.md` rewrites that section alone).",
        "- Case names: `[large/]<fwd|bwd>/<shadows>/<sampling>/img:W/map:M/faces:F/sigma_s:S/lights:L`",
        "  (the paper's model; `/model:accurate` after them for the accurate model's), accuracy",
        "  cases `accuracy/fwd/...` with `/model:<accurate|paper>/scene:<name>` after them, steps",
        "  (a render and its backward in turn) `step/<shadows>/<sampling>/img:W/...`,",
        "  so `--benchmark_filter` selects by any of them, e.g. `build/penumbra_bench",
        "  --benchmark_filter='^fwd/hard/.*/img:256/'` or `'^accuracy/.*/scene:knot_h0/'`.",
        "- ctest runs `bench_smoke` (two tiny cases), `bench_report_smoke` (`report.py --smoke`)",
        "  and `bench_accuracy_targets` (`bench/test_accuracy.cpp`, the accurate model's targets",
        "  against the ray-traced truth; built where Embree is found).",
        "",
    ]


# ---- smoke ---------------------------------------------------------------------------------

SMOKE_FILTER = "^(fwd|bwd)/hard/truncated/img:256/map:256/faces:1312/sigma_s:2/lights:1/manual_time"


def smoke(bench, out_dir):
    os.makedirs(out_dir, exist_ok=True)
    js = os.path.join(out_dir, "smoke.json")
    cmd = [bench, f"--benchmark_filter={SMOKE_FILTER}", "--benchmark_min_time=0.01",
           f"--benchmark_out={js}", "--benchmark_out_format=json"]
    print("report: running", " ".join(cmd))
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    context, records = load(js)
    if len(records) != 2 or any(r["error"] for r in records):
        sys.exit(f"report: smoke run expected two good cases, got {[(r['name'], r['error']) for r in records]}")
    doc = os.path.join(out_dir, "benchmarks.md")
    write_report(context, records, None, doc, os.path.join(out_dir, "images"), None, smoke=True)
    text = open(doc).read()
    for needle in ("## Targets", "hard / truncated", "## The machine's ceiling"):
        if needle not in text:
            sys.exit(f"report: smoke report lacks {needle!r}")
    print("report: smoke OK")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", help="penumbra_bench JSON output")
    ap.add_argument("--machine", help="machine.json written by scripts/bench.sh")
    ap.add_argument("--doc", default="docs/benchmarks.md")
    ap.add_argument("--images", default="docs/images")
    ap.add_argument("--accuracy-images", help="folder of PNGs from PENUMBRA_BENCH_IMAGES")
    ap.add_argument("--profiles", help="folder of profile_fwd_*.txt from scripts/bench.sh")
    ap.add_argument("--accuracy-only", action="store_true",
                    help="rewrite only the accuracy section of --doc from a run of the accuracy "
                         "group (--benchmark_filter=^accuracy/), keeping the rest of the page")
    ap.add_argument("--first-call", help="JSON of bench/first_call.py: adds its section")
    ap.add_argument("--smoke", action="store_true", help="tiny run + report check (CI)")
    ap.add_argument("--bench", help="penumbra_bench executable (with --smoke)")
    ap.add_argument("--out-dir", help="where --smoke writes (default: a temporary folder)")
    a = ap.parse_args()
    if a.smoke:
        if not a.bench:
            sys.exit("report: --smoke needs --bench PATH")
        if a.out_dir:
            smoke(a.bench, a.out_dir)
        else:
            d = tempfile.mkdtemp(prefix="penumbra_bench_smoke_")
            try:
                smoke(a.bench, d)
            finally:
                shutil.rmtree(d, ignore_errors=True)
        return
    if not a.json:
        sys.exit("report: --json FILE is required (or --smoke)")
    context, records = load(a.json)
    machine = None
    if a.machine and os.path.exists(a.machine):
        with open(a.machine) as f:
            machine = json.load(f)
    if a.accuracy_only:
        write_accuracy_only(context, records, machine, a.doc, a.images, a.accuracy_images)
        return
    first_call = None
    if a.first_call and os.path.exists(a.first_call):
        import first_call as fc  # bench/first_call.py, next to this script
        with open(a.first_call) as f:
            first_call = fc.section(json.load(f))
    write_report(context, records, machine, a.doc, a.images, a.accuracy_images,
                 profiles=load_profiles(a.profiles), first_call=first_call)


if __name__ == "__main__":
    main()
