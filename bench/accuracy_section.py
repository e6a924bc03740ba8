"""The page's "Accuracy beside cost": every shadow model, mode and sampling against the
ray-traced truth, and the accurate model's targets."""
from measures import (ACC_CONTRASTS, ACC_SCENES, ACC_SCENE_WORDS, ACC_TARGETS, acc_case, acc_ratio,
                      fmt, ms)
from page_template import block, table
from plots import copy_comparisons


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


def target_checks(a, ratio):
    """(name, measured, met?) of the accurate model's targets for one scene and mode."""
    return [("area", a.get("area_ratio"), lambda x: abs(x - 1) <= ACC_TARGETS["area"]),
            ("lit", a.get("lit_error"), lambda x: x <= ACC_TARGETS["lit"]),
            ("rmse", a.get("rmse_shadow"), lambda x: x <= ACC_TARGETS["rmse"]),
            ("leak", a.get("leak"), lambda x: x <= ACC_TARGETS["leak"]),
            ("time", ratio["time_ratio"] if ratio else None, lambda x: x <= ACC_TARGETS["time"])]


def accuracy_target_rows(res):
    """The targets for the accurate model, truncated, per scene and mode."""
    rows, misses = [], []
    for sc in (sc for sc in ACC_SCENES if sc not in ACC_CONTRASTS):
        for sh in ("hard", "soft"):
            a = acc_case(res, sc, "accurate", sh, "truncated")
            if not a:
                continue
            cells = []
            for name, x, ok in target_checks(a, acc_ratio(res, sc, sh)):
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


def time_ratios(res):
    """The accurate/paper forward time, medians summed over the scenes, per mode: at equal
    maps (against the target) and at each model's default map."""
    sums, defaults = [], []
    for sh in ("hard", "soft"):
        for default_maps, out in ((False, sums), (True, defaults)):
            pairs = [acc_ratio(res, sc, sh, default_maps) for sc in ACC_SCENES
                     if sc not in ACC_CONTRASTS]
            if not (pairs and all(pairs)):
                continue
            ratio = sum(r["ms_accurate"] for r in pairs) / sum(r["ms_paper"] for r in pairs)
            missed = not default_maps and ratio > ACC_TARGETS["time"]
            out.append(f"{sh} {fmt(ratio)}" + (" (**missed**)" if missed else ""))
    return sums, defaults


def targets_part(res):
    rows, misses = accuracy_target_rows(res)
    if not rows:
        return []
    L = block("accuracy-targets", area=f"{100 * ACC_TARGETS['area']:g}",
              lit=f"{100 * ACC_TARGETS['lit']:g}", rmse=f"{ACC_TARGETS['rmse']}",
              time=f"{ACC_TARGETS['time']}")
    L.append(table(("scene", "shadows", "area ratio", "lit error", "shadow RMSE", "leak",
                    "time / paper"), rows))
    L += block("accuracy-missed", count=len(misses), misses="; ".join(misses) if misses else "none")
    sums, defaults = time_ratios(res)
    if sums:
        L += block("accuracy-sums", ratios=", ".join(sums))
    if defaults:
        L += block("accuracy-defaults", ratios=", ".join(defaults))
    return L


def accuracy_section(res, tradeoff_plot, rel_images, accuracy_images, image_dir):
    L = block("accuracy")
    acc = res.all("accuracy")
    if not acc:
        return L + block("accuracy-none")
    L += block("accuracy-intro")
    L += [f"- `{sc}`: {ACC_SCENE_WORDS[sc]};" for sc in ACC_SCENES
          if any(r["scene"] == sc for r in acc)]
    L += block("accuracy-measures") + targets_part(res) + block("accuracy-all")
    L += [table(("scene", "model", "shadows / sampling", "map", "σ_s", "forward ms", "area ratio",
                 "lit error", "shadow RMSE", "leak"), accuracy_rows(res)), ""]
    if tradeoff_plot:
        L += block("accuracy-plot", images=rel_images)
    if copy_comparisons(accuracy_images, image_dir):
        L += block("accuracy-pictures")
    return L
