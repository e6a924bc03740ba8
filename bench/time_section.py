"""The page's "Where the time goes": what each stage adds, from differences between cases, and
the device time per kernel of the profiled cases."""
from measures import (DENSE_SIGMA_S, bwd_over_fwd, fmt, kernel_rates, linfit, matmul_rate, ms,
                      profiled_case, si, stage_times, step, sweep, weight_exps)
from page_template import block, table, text

# The forward cases at the reference point the notes compare.
MODES = (("none", "truncated"), ("hard", "truncated"), ("hard", "exact"), ("hard", "gemm"),
         ("soft", "truncated"))


def sigma_fit(res, none, hard):
    """The σ_s sweep's straight line, as a sentence, where it is a clean one: rising, through
    the points, above the no-shadow frame."""
    pts = [(r[0], r[1]) for r in sweep(res, "sigma_s").get(("fwd", "hard", "truncated"), [])]
    fit = linfit(pts)
    if not (fit and len(pts) >= 3):
        return ""
    a, slope = fit
    my = sum(y for _, y in pts) / len(pts)
    ss_tot = sum((y - my) ** 2 for _, y in pts)
    ss_res = sum((y - a - slope * x) ** 2 for x, y in pts)
    r2 = 1 - ss_res / ss_tot if ss_tot > 0 else 0
    if not (slope > 0 and r2 >= 0.9 and none <= a <= hard):
        return ""
    return text("note-hard-fit", points=len(pts), r2=f"{r2:.2f}",
                lo=fmt(min(p[0] for p in pts), 2), hi=fmt(max(p[0] for p in pts), 2),
                slope=fmt(slope), at0=fmt(a), window=fmt(2 * slope), fixed=fmt(a - none))


def hard_note(res, none, hard):
    s = text("note-hard", hard=fmt(hard), more=fmt(hard - none)) + sigma_fit(res, none, hard)
    mp = dict(sweep(res, "map").get(("fwd", "hard", "truncated"), []))
    if 64 in mp and 256 in mp:
        s += text("note-hard-map", big=fmt(mp[256]), small=fmt(mp[64]))
    return s


def dense_note(res, profiles, peak):
    """The exact note's sentence on the dense case (σ_s = DENSE_SIGMA_S), or ""."""
    dense = res.render("fwd", shadows="hard", sampling="exact", sigma_s=DENSE_SIGMA_S)
    if not (dense and dense.get("gflops") and peak):
        return ""
    dm = matmul_rate(res, profiles, dense=True)
    kernels = (text("note-exact-dense-kernels", ms=fmt(dm[1]), gflops=fmt(dm[0]),
                    share=fmt(dm[0] / peak * 100, 2)) if dm and dm[0] else "")
    return text("note-exact-dense", sigma=f"{DENSE_SIGMA_S:g}", ms=fmt(ms(dense)),
                gflops=fmt(dense["gflops"]), share=fmt(dense["gflops"] / peak * 100, 2),
                kernels=kernels)


def exact_note(res, f, peak, exp_rate, profiles):
    ex, gm, none = f[("hard", "exact")], f[("hard", "gemm")], f[("none", "truncated")]
    r = res.render("fwd", shadows="hard", sampling="exact")
    flops = r["gflops"] * ex * 1e-3 if r.get("gflops") else None
    s = text("note-exact", exact=fmt(ex), more=fmt(ex - none), fragments=fmt(r.get("fragments")),
             flops=text("note-exact-flops", flops=fmt(flops)) if flops else "")
    mm = matmul_rate(res, profiles)
    if mm and mm[0]:
        rate, mm_ms, w_ms, total_ms = mm
        s += text("note-exact-profile", mm_ms=fmt(mm_ms), rate=fmt(rate), w_ms=fmt(w_ms),
                  total_ms=fmt(total_ms))
        s += dense_note(res, profiles, peak)
        if exp_rate and r.get("fragments"):
            exps = weight_exps(r)
            s += text("note-exact-exps", exps=si(exps), ms=fmt(exps / exp_rate * 1e3))
    elif flops:
        s += text("note-exact-bound", gflops=fmt(flops / ((ex - none) * 1e-3)))
    if gm:
        s += text("note-gemm", gemm=fmt(gm), times=fmt(gm / ex))
    return s


def quotient_note(res):
    parts = []
    for k, label in ((("none", "truncated"), "none"), (("hard", "truncated"), "hard truncated"),
                     (("soft", "truncated"), "soft truncated"), (("hard", "exact"), "hard exact"),
                     (("hard", "gemm"), "hard gemm")):
        ratio = bwd_over_fwd(res, *k)[1]
        if ratio:
            parts.append(f"{label} {fmt(ratio)}×")
    return [text("note-quotients", quotients=", ".join(parts))] if parts else []


def accurate_notes(res):
    acc = []
    for sh in ("hard", "soft"):
        f, b = (res.render(p, shadows=sh, sampling="truncated", model="accurate")
                for p in ("fwd", "bwd"))
        if ms(f) and ms(b):
            acc.append(f"{sh} forward {fmt(ms(f))} ms, backward {fmt(ms(b))} ms "
                       f"({fmt(ms(b) / ms(f))}×)")
    out = [text("note-accurate", cases="; ".join(acc))] if acc else []
    big = [(sh, step(res, shadows=sh, sampling="truncated", faces=100852, model=model))
           for model in ("paper", "accurate") for sh in ("hard", "soft")]
    big = [f"{s['model']} {sh} {fmt(s['ms_median'])} ms (forward {fmt(s['ms_fwd'])}, backward "
           f"{fmt(s['ms_bwd'])})" for sh, s in big if s and s.get("ms_fwd")]
    return out + ([text("note-big", cases="; ".join(big))] if big else [])


def scaling_notes(res):
    out = []
    fc = sweep(res, "faces").get(("fwd", "none", "truncated"), [])
    if len(fc) >= 2:
        (f0, t0), (f1, t1) = fc[0], fc[-1]
        out.append(text("note-faces", f0=f0, f1=f1, ratio=fmt(f1 / f0), t0=fmt(t0), t1=fmt(t1),
                        times=fmt(t1 / t0)))
    rs = sweep(res, "img").get(("fwd", "none", "truncated"), [])
    if len(rs) >= 2:
        (x0, t0), (x1, t1) = rs[0], rs[-1]
        out.append(text("note-pixels", x0=x0, x1=x1, ratio=fmt((x1 / x0) ** 2), t0=fmt(t0),
                        t1=fmt(t1), times=fmt(t1 / t0)))
    return out


def stage_notes(res, peak, exp_rate, profiles):
    """Stage attribution from differences between cases (no per-kernel timers)."""
    f = {k: ms(res.render("fwd", shadows=k[0], sampling=k[1])) for k in MODES}
    out = []
    none, hard, soft = f[("none", "truncated")], f[("hard", "truncated")], f[("soft", "truncated")]
    if none and hard:
        out += [text("note-none", none=fmt(none)), hard_note(res, none, hard)]
    if soft and hard:
        out.append(text("note-soft", soft=fmt(soft), more=fmt(soft - hard)))
    if f[("hard", "exact")] and none:
        out.append(exact_note(res, f, peak, exp_rate, profiles))
    out += quotient_note(res) + accurate_notes(res) + scaling_notes(res)
    return "\n".join(out) if out else "(not enough cases measured)"


def profile_row(res, mode, p, peak, exp_rate):
    sh, sa = mode
    if not p["kernels"]:
        return (f"{sh} / {sa}", text("profile-unavailable", status=p["status"]), "", "", "")
    total = sum(ns for _, _, ns in p["kernels"])
    stages = stage_times(p["kernels"])
    stage_txt = ", ".join(f"{k} {fmt(v / 1e6)} ms ({v * 100 / total:.0f} %)"
                          for k, v in sorted(stages.items(), key=lambda kv: -kv[1]))
    top = ", ".join(f"`{n}` {fmt(ns / 1e6)} ms ×{l:g}" for n, l, ns in
                    sorted(p["kernels"], key=lambda k: -k[2])[:4])
    rates = kernel_rates(profiled_case(res, mode) if res else None, p["kernels"], peak, exp_rate)
    return (f"{sh} / {sa}", f"{fmt(total / 1e6)} ms", stage_txt, top, rates)


def dominant_stages(profiles):
    dominant = []
    for (sh, sa), p in profiles.items():
        if p["kernels"]:
            total = sum(ns for _, _, ns in p["kernels"])
            top = max(stage_times(p["kernels"]).items(), key=lambda kv: kv[1])
            dominant.append(f"{sh} / {sa}: {top[0]} ({top[1] * 100 / total:.0f} %)")
    return block("profile-dominant", stages="; ".join(dominant)) if dominant else []


def profile_section(res, profiles, peak=None, exp_rate=None):
    if not profiles:
        return None
    frames = sorted({p["frames"] for p in profiles.values() if p["kernels"]})
    L = block("profile", frames="–".join(str(f) for f in (frames[0], frames[-1]))
              if frames else "none")
    if any(sa == "accurate" and p["kernels"] for (_, sa), p in profiles.items()):
        L += block("profile-accurate")
    L.append("")
    rows = [profile_row(res, mode, p, peak, exp_rate) for mode, p in profiles.items()]
    L.append(table(("mode", "kernel time", "by stage", "largest kernels (time × launches per frame)",
                    "against the ceiling"), rows))
    return "\n".join(L + dominant_stages(profiles))
