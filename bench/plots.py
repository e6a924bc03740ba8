"""The pictures of docs/benchmarks.md: time and memory against each swept parameter, error
against time, and the accuracy group's comparison strips (copied)."""
import os
import sys

import docfile
from measures import ACC_PICTURED, ACC_SCENES, ACC_TARGETS, SERIES, acc_ref, device_mib, fmt, ms, sweep


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


def tradeoff_legend(plt, ax):
    from matplotlib.lines import Line2D
    handles = [Line2D([], [], color=c, marker="o", ls="", label=l)
               for c, l in (("C2", "accurate"), ("C3", "paper"))]
    handles += [Line2D([], [], color="k", marker=m, ls="", mfc=f, label=l)
                for m, f, l in (("o", "k", "hard, truncated"), ("o", "none", "soft, truncated"),
                                ("s", "k", "exact"), ("^", "k", "gemm"))]
    ax.legend(handles=handles, fontsize=6)


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
    tradeoff_legend(plt, axes[0][-1])
    fig.tight_layout()
    docfile.save_figure(fig, path, dpi=100)
    plt.close(fig)
    return True


def make_plots(plt, res, image_dir):
    """Every plot of the page: {name: whether it was drawn}."""
    at = lambda name: os.path.join(image_dir, name)
    return {
        "res": plot_sweep(plt, res, "img", "image size W = H (pixels)",
                          at("bench_time_vs_resolution.png")),
        "map": plot_sweep(plt, res, "map", "shadow-map size W_s = H_s (texels)",
                          at("bench_time_vs_map.png")),
        "faces": plot_sweep(plt, res, "faces", "faces", at("bench_time_vs_faces.png")),
        "memory": plot_sweep(plt, res, "faces", "faces", at("bench_memory_vs_faces.png"),
                             value=device_mib, ylabel="device memory of one call (MiB)"),
        "sigma_s": plot_sweep(plt, res, "sigma_s", "σ_s (texel²)",
                              at("bench_time_vs_sigma_s.png")),
        "tradeoff": plot_tradeoff(plt, res, at("bench_error_vs_time.png")),
    }


def copy_comparisons(folder, image_dir):
    """truth | penumbra | difference strips of the accurate model (compare_*_accurate_*.png
    written by the accuracy group under $PENUMBRA_BENCH_IMAGES) → image_dir/accuracy_*.png,
    for the scenes a page shows (ACC_PICTURED)."""
    copied = []
    for sc in ACC_PICTURED:
        for sh in ("hard", "soft"):
            src = os.path.join(folder or "", f"compare_{sc}_accurate_{sh}.png")
            if folder and os.path.exists(src):
                docfile.copy_file(src, os.path.join(image_dir, f"accuracy_{sc}_{sh}.png"))
                copied.append((sc, sh))
    return copied
