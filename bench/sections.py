"""The page's sections but the time and accuracy ones (time_section.py, accuracy_section.py):
each returns its lines, its prose from bench/report_template.md."""
from measures import (DENSE_SIGMA_S, FRAME_TARGETS, PAPER, SERIES, best, bwd_over_fwd,
                      dense_products, device_mib, fmt, fwd_plus_bwd, ms, ns_per_fragment, si,
                      sweep, verdict)
from page_template import block, named, table, text

# The section bench/mitsuba_side_by_side.py writes (report.py keeps it when it rewrites the page).
SIDE_BY_SIDE = "## Beside a ray tracer: Mitsuba 3"
# The section of `penumbra_bench --host-stages`'s table, written by hand (report.py keeps it).
HOST_STAGES = "## Host work per render"
# The sweeps' sections: key, title, the x axis's name, the plot.
SWEEPS = (("img", "Image size", "image", "res"), ("map", "Shadow-map size", "map", "map"),
          ("faces", "Face count", "faces", "faces"), ("sigma_s", "σ_s", "σ_s", "sigma_s"),
          ("lights", "Lights", "lights", None))
# The series the sweeps' tables add to SERIES.
TABLE_SERIES = SERIES + [("fwd", "soft", "exact", "forward, soft exact", "", ""),
                         ("bwd", "soft", "exact", "backward, soft exact", "", ""),
                         ("bwd", "hard", "gemm", "backward, hard gemm", "", "")]


def intro(smoke):
    return block("intro", smoke=text("smoke") if smoke else "")


def machine(context, machine_json, res):
    m = machine_json or {}
    rows = [("CPU (`lscpu \\| grep 'Model name'`)", m.get("cpu_model") or context.get("cpu_model", "–")),
            ("cores (`nproc`)", m.get("nproc", context.get("num_cpus", "–"))),
            ("OpenCL device", context.get("device", "–")),
            ("PoCL", m.get("pocl_version", "–")),
            ("device version", context.get("device_version", "–"))]
    if m.get("command"):
        rows.append(("command", f"`{m['command']}`"))
    rows.append(("date", context.get("date", "–")))
    if m.get("wall_seconds") is not None:
        rows.append(("suite wall time", f"{m['wall_seconds']:.0f} s"))
    rows.append(("load average (1, 5, 15 min) before the run",
                 m.get("loadavg_before") or context.get("loadavg_at_start", "–")))
    if m.get("loadavg_after"):
        rows.append(("load average after the run", m["loadavg_after"]))
    loads = sorted(r["loadavg_1min"] for r in res.records if r.get("loadavg_1min") is not None)
    if loads:
        rows.append(("1-min load average at the end of each case",
                     f"median {fmt(loads[len(loads) // 2])}, range {fmt(loads[0])}–{fmt(loads[-1])} "
                     f"({len(loads)} cases)"))
    rows.append(("memory figure", context.get("peak_memory", "–")))
    return block("machine") + [table(("", ""), rows), ""] + block("machine-notes")


def ceiling(res):
    fma, ex, nex = (res.find("ceiling", what=w) for w in ("fma", "exp", "native_exp"))
    rows = []
    if fma:
        rows.append(("FMA, float32", f"{fmt(fma['gflops'])} GFLOP/s",
                     f"{fmt(best(fma, 'gflops'))} GFLOP/s"))
    for r, label in ((ex, "`exp`, float32"), (nex, "`native_exp`, float32")):
        if r:
            rows.append((label, f"{fmt(r['gexp_per_s'])} G exp/s",
                         f"{fmt(best(r, 'gexp_per_s'))} G exp/s"))
    body = table(("kernel", "median", "best (the ceiling)"), rows) if rows else "(not measured)"
    return block("ceiling") + [body, ""] + block("ceiling-notes")


def against(res, r, peak, exp_rate):
    """A case's throughput against the ceiling that measures its work."""
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


def turnaround_rows(res):
    """The targets on the 90-frame turnaround."""
    ta = {sh: res.find("turnaround", shadows=sh) for sh in ("none", "hard", "soft")}
    soft_s = ta["soft"]["seconds"] if ta["soft"] else None
    rows = [("90-frame soft turnaround ≤ 3 s", f"{fmt(soft_s)} s", *verdict(soft_s, 3.0), "–")]
    for sh, limit in (("hard", 3.0), ("soft", 8.0)):
        ratio = (ta[sh]["seconds"] / ta["none"]["seconds"]) if ta[sh] and ta["none"] else None
        rows.append((f"turnaround {sh}/none ≤ {limit:g}", fmt(ratio), *verdict(ratio, limit), "–"))
    return rows


def target_rows(res, peak, exp_rate):
    rows = []
    for label, want, limit in FRAME_TARGETS:
        r = res.render("fwd", **want)
        rows.append((f"{label} ≤ {limit:g} ms", f"{fmt(ms(r))} ms", *verdict(ms(r), limit),
                     against(res, r, peak, exp_rate)))
    for sh, sa in (("none", "truncated"), ("hard", "truncated"), ("soft", "truncated"),
                   ("hard", "exact"), ("hard", "gemm")):
        bwd_ms, ratio = bwd_over_fwd(res, sh, sa)
        rows.append((f"backward ≤ 3× forward ({sh}, {sa})",
                     f"{fmt(bwd_ms)} ms = {fmt(ratio)}× forward" if ratio else "–",
                     *verdict(ratio, 3.0),
                     against(res, res.render("bwd", shadows=sh, sampling=sa), peak, exp_rate)))
    rows += turnaround_rows(res)
    big = res.render("fwd", shadows="none", sampling="truncated", img=512, faces=100852)
    rows.append(("512², 100 852 faces, no shadows, forward ≤ 30 ms", f"{fmt(ms(big))} ms",
                 *verdict(ms(big), 30.0), against(res, big, peak, exp_rate)))
    both = fwd_plus_bwd(res, faces=100852)
    rows.append(("256², 100 852 faces, hard shadows, forward + backward ≤ 200 ms",
                 f"{fmt(both)} ms" if both is not None else "–", *verdict(both, 200.0), "–"))
    return rows


def miss_reasons(missed):
    """Why each missed target is missed: the template's `why: <label start>` blocks (each one
    paragraph there, a blank line apart)."""
    exact_backward = text("exact-backward").strip()
    reasons = []
    for start, _ in named("why: "):
        hits = [m for m in missed if m.startswith(start)]
        if hits:
            reasons.append(f"- *{'; '.join(hits)}*: "
                           + text("why: " + start, exact_backward=exact_backward).strip())
    return reasons


def targets(res, peak, exp_rate):
    rows = target_rows(res, peak, exp_rate)
    L = block("targets") + [table(("target", "measured (median)", "", "by how much",
                                   "throughput (against the ceiling where one applies)"), rows), ""]
    if res.all("step"):
        L += block("targets-steps")
    reasons = miss_reasons([row[0] for row in rows if row[2] == "**missed**"])
    if reasons:
        L += block("targets-missed") + ["\n\n".join(reasons), ""]  # each reason a paragraph
    return L


def matrix_row(pass_, sa, mp, r, peak, exp_rate):
    g, sps = r.get("gflops"), r.get("samples_per_s")
    # Products are compared with the FMA peak; exact sums skip the texels of weight 0.
    exp_sps = sps if not g and sa != "exact" else None
    return ("forward" if pass_ == "fwd" else "backward", f"{r['shadows']} / {sa}", f"{mp}²",
            fmt(ms(r)), fmt(r.get("ms_min")), fmt(r.get("frames_per_s")),
            si(r.get("pixel_face_pairs_per_s")), si(sps),
            f"{fmt(exp_sps / exp_rate * 100, 2)} %" if exp_sps and exp_rate else "–",
            (fmt(g) if dense_products(r) else f"{fmt(g)} (dense-eq.)") if g else "–",
            f"{fmt(g / peak * 100, 2)} %" if g and peak and dense_products(r) else "–",
            f"{fmt(r.get('peak_rss_MiB'))} ({fmt(r.get('rss_at_start_MiB'))})"
            if r.get("rss_at_start_MiB") else fmt(r.get("peak_rss_MiB")))


def matrix(res, peak, exp_rate):
    rows = []
    for pass_ in ("fwd", "bwd"):
        for sh, sa, mp in (("none", "truncated", 256), ("hard", "truncated", 256),
                           ("hard", "exact", 256), ("hard", "gemm", 256),
                           ("soft", "truncated", 256), ("soft", "exact", 64),
                           ("soft", "exact", 256)):
            r = res.render(pass_, shadows=sh, sampling=sa, map=mp)
            if r:
                rows.append(matrix_row(pass_, sa, mp, r, peak, exp_rate))
    return block("matrix") + [table(
        ("pass", "shadows / sampling", "map", "median ms", "best ms", "frames/s",
         "pixel·face pairs/s", "samples/s", "% of exp", "GFLOP/s", "% of peak",
         "peak RSS MiB (at start)"), rows), ""] + block("matrix-notes", dense=f"{DENSE_SIGMA_S:g}")


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
    return block("work", table=table([f"ns per fragment \\ {xname}"] + [str(x) for x in xs], rows),
                 n0=fmt(kept[xs[0]]), n1=fmt(kept[xs[-1]]), spans="; ".join(spans))


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
    L = block("memory", table=table(["device MiB \\ faces"] + [str(x) for x in xs], rows),
              x0=xs[0], x1=xs[-1], slopes="; ".join(slopes))
    return L + (block("memory-plot", images=rel_images) if plotted else [])


def sweep_section(res, key, title, xname, plotted, plots, rel_images):
    """One swept parameter's section: the times of every series, its plot, and for the image
    and face sweeps the work per fragment (and for faces the memory)."""
    data = sweep(res, key)
    xs = sorted({x for pts in data.values() for x, _ in pts})
    if len(xs) < 2:
        return []
    rows = []
    for pass_, sh, sa, label, *_ in TABLE_SERIES:
        pts = dict(data.get((pass_, sh, sa), []))
        if len(pts) < 1 or any(r[0] == label for r in rows):
            continue
        rows.append([label] + [fmt(pts.get(x)) for x in xs])
    L = [f"## {title}", ""] + block("sweep-" + key, dense=f"{DENSE_SIGMA_S:g}") + [""]
    L += [table([f"median ms \\ {xname}"] + [fmt(x) if key == "sigma_s" else str(x) for x in xs],
                rows), ""]
    if plotted:
        L += [f"![time vs {xname}]({rel_images}/bench_time_vs_{plotted}.png)", ""]
    if key in ("img", "faces"):
        L += work_lines(res, key, xname)
    if key == "faces":
        L += memory_lines(res, plots.get("memory"), rel_images)
    return L


def sweeps(res, plots, rel_images):
    L = []
    for key, title, xname, plot in SWEEPS:
        drawn = plot and plots.get(plot)
        L += sweep_section(res, key, title, xname,
                           {"res": "resolution"}.get(plot, plot) if drawn else None, plots,
                           rel_images)
    return L


def turnaround(res):
    ta = {sh: res.find("turnaround", shadows=sh) for sh in ("none", "hard", "soft")}
    rows = []
    for sh in ("none", "hard", "soft"):
        r = ta[sh]
        if not r:
            continue
        ratio = r["seconds"] / ta["none"]["seconds"] if ta["none"] else None
        rows.append((sh, fmt(r["seconds"]), fmt(r["ms_median"]), fmt(ratio),
                     fmt(PAPER[sh][0]), fmt(PAPER[sh][1])))
    return block("turnaround") + [table(("shadows", "90 frames (s)", "median ms/frame",
                                         "ratio to none", "paper (s)", "paper ratio"), rows)
                                  if rows else "(not run)", ""]


def large_and_failed(res):
    large = [r for r in res.records if r["large"]]
    L = block("large")
    if large:
        L += block("large-run") + [table(("case", "median ms", "device MiB"), [
            (r["name"].replace("/manual_time", ""), fmt(ms(r)), fmt(device_mib(r)))
            for r in large])]
    else:
        L += block("large-none")
    L.append("")
    if res.errors:
        L += block("failed") + [table(("case", "error"), [(r["name"], r["error"])
                                                          for r in res.errors]), ""]
    return L


def files_section():
    return block("files")
