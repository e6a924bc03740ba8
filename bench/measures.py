"""What the report computes from the records: formatted figures, the cases it compares, the
targets and their verdicts, sweeps, rates against the machine's ceiling."""
import math

from results import REF

# The accuracy group (bench/accuracy.hpp): scenes in their order, and the targets for the
# accurate model (bench/test_accuracy.cpp asserts the same).
ACC_SCENES = ["sphere", "knot_h0", "knot_h0.3", "knot_h1", "grazing", "among", "among_frustum",
              "sphere_100k", "sphere_100k_512"]
ACC_SCENE_WORDS = {
    "sphere": "the bundled unit sphere resting on the ground",
    "knot_h0": "a torus knot (3840 faces) lying on the ground",
    "knot_h0.3": "the knot 0.3 above the ground",
    "knot_h1": "the knot 1 above the ground",
    "grazing": "a sphere of radius 0.5 under a light at 18° elevation",
    "among": "a light among four spheres on four sides (its shadow map a cube)",
    "among_frustum": "the same light held to one 120° frustum: what the cube gives, and costs",
    "sphere_100k": "the bundled scene with a sphere of 100,820 faces (beside Mitsuba, "
                   "bench/mitsuba_side_by_side.py)",
    "sphere_100k_512": "that scene at 512²",
}
# Scenes beside the others but outside the targets: what a default avoids, and the scenes of
# the comparison with Mitsuba.
ACC_CONTRASTS = ["among_frustum", "sphere_100k", "sphere_100k_512"]
# The scenes whose truth | penumbra | difference strips docs/shadows.md shows: the 100k-face
# spheres are there for their times beside Mitsuba, and their strips would be the sphere's.
ACC_PICTURED = [s for s in ACC_SCENES if not s.startswith("sphere_100k")]
ACC_TARGETS = {"area": 0.05, "lit": 0.02, "rmse": 0.05, "leak": 0.0, "time": 1.5}

# Targets: this 2-core machine, PoCL, the turnaround scene, 256² image, 256² map, forward.
FRAME_TARGETS = [
    ("no shadows, forward", dict(shadows="none", sampling="truncated"), 4.0),
    ("hard shadows, truncated, forward", dict(shadows="hard", sampling="truncated"), 10.0),
    ("soft shadows, truncated, forward", dict(shadows="soft", sampling="truncated"), 30.0),
    ("hard shadows, exact, forward", dict(shadows="hard", sampling="exact"), 100.0),
]
PAPER = {"none": (1.0, 1.0), "hard": (33.0, 33.0), "soft": (104.0, 104.0)}

# The σ_s of the dense exact cases: no Gaussian weight of a 256² map is 0 there (float).
DENSE_SIGMA_S = 400.0

# Within this fraction of its limit a case's verdict can flip from one run to the next on a
# shared machine: the same case's median moves by more than that between runs under load.
NOISE = 0.05

# The render series of the sweeps' tables and plots: pass, shadows, sampling, label, colour,
# line style.
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


def device_mib(r):
    return r.get("device_MiB")


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


def ns_per_fragment(r):
    """A case's median time per fragment the camera's view kept (counter `fragments`), in ns."""
    return ms(r) * 1e6 / r["fragments"] if ms(r) and r.get("fragments") else None


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


def best(r, key):
    """The rate of a ceiling case's fastest iteration."""
    return r[key] * r["ms_median"] / r["ms_min"] if r and r.get("ms_min") else None


def ceilings(res):
    """(FMA median GFLOP/s, FMA best GFLOP/s, exp best per second) of the ceiling cases."""
    fma, ex = res.find("ceiling", what="fma"), res.find("ceiling", what="exp")
    return (fma["gflops"] if fma else None, best(fma, "gflops"),
            best(ex, "gexp_per_s") * 1e9 if ex else None)


def stage_of(kernel):
    """Pipeline stage (kernels/<stage>.cl) of a kernel, by name; CLBlast's own kernels apart."""
    if kernel in ("transform_fwd", "transform_bwd", "face_setup", "albedo_bwd", "sum_rows"):
        return "transform"
    if kernel == "clblast_gemm":
        return "CLBlast"
    for prefix, stage in (("bin_", "bin"), ("raster_", "raster"), ("shadow_", "shadow"),
                          ("exact_", "shadow"), ("soft_map_", "soft map"), ("soft_", "shadow"),
                          ("matmul_", "matmul"), ("row_dot", "matmul"), ("pcf_", "pcf")):
        if kernel.startswith(prefix):
            return stage
    # penumbra's kernels are snake_case; CLBlast's (Xgemm, TransposeMatrix, ...) are not.
    return "CLBlast" if kernel[:1].isupper() else "other"


def stage_times(kernels):
    """{stage: ns per frame} of a profile's kernels."""
    stages = {}
    for name, _, ns in kernels:
        stages[stage_of(name)] = stages.get(stage_of(name), 0) + ns
    return stages


def profiled_case(res, mode):
    """The forward case a profile mode ran (results.PROFILE_MODES)."""
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


def dense_products(r):
    """Whether a hard exact or gemm case's GFLOP/s counts the flops its products execute:
    CLBlast's GEMM multiplies every weight, penumbra's kernels skip those that are exactly 0
    (exp's argument −d²/(2σ_s) below −87 in float), which none is where σ_s ≥ (W_s − 1)²/174."""
    return r.get("sampling") == "gemm" or r.get("sigma_s", 0) >= (r["map"] - 1) ** 2 / 174


def kernel_rate(r, name, ns, peak, exp_rate):
    """One kernel's throughput against its ceiling (kernel_rates), or None."""
    if name in ("shadow_sample", "soft_sample") and r.get("samples_per_s") and exp_rate:
        rate = r["samples_per_s"] * ms(r) * 1e-3 / (ns * 1e-9)
        return f"`{name}` {si(rate)} samples/s = {fmt(rate / exp_rate * 100, 2)} % of exp rate"
    if name == "exact_weights" and exp_rate:
        rate = weight_exps(r) / (ns * 1e-9)
        return f"`{name}` ≤ {si(rate)} exp/s = {fmt(rate / exp_rate * 100, 2)} % of exp rate"
    if (name == "clblast_gemm" or name.startswith("matmul_")) and peak:
        rate = product_flops(r) / (ns * 1e-9) / 1e9
        return (f"`{name}` {fmt(rate)} GFLOP/s = {fmt(rate / peak * 100, 2)} % of FMA peak"
                if dense_products(r) else f"`{name}` {fmt(rate)} GFLOP/s dense-equivalent")
    return None


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
    out = [kernel_rate(r, name, ns, peak, exp_rate)
           for name, _, ns in sorted(kernels, key=lambda k: -k[2]) if ns]
    out = [o for o in out if o]
    return "; ".join(out) if out else "–"


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


def acc_ref(r):
    """The reference settings of the accuracy group: the model's default map size and σ_s."""
    return r.get("default_map") == 1 and r.get("default_sigma_s") == 1


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
