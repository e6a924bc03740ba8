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

The page is put together from modules next to this script, one concern each: results.py
(loading the JSON and the profiles), measures.py (what is computed from them), plots.py,
sections.py, time_section.py and accuracy_section.py (the page's sections), with the page's
prose in report_template.md (page_template.py reads it).

Plain Python 3; the plots need matplotlib (Debian: python3-matplotlib) and are skipped with a
message when it is missing.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # bench/: its sibling modules
# The names the tests and other scripts use, from the modules that define them.
import docfile  # noqa: E402
import sections  # noqa: E402
from accuracy_section import accuracy_section  # noqa: E402,F401
from measures import (acc_ratio, bwd_over_fwd, ceilings, fmt, fwd_plus_bwd,  # noqa: E402,F401
                      kernel_rates, matmul_rate, verdict)
from page_template import block, text  # noqa: E402
from plots import get_plt, make_plots, plot_tradeoff  # noqa: E402
from results import Results, load, load_profiles, parse_name  # noqa: E402,F401
from sections import memory_lines  # noqa: E402,F401
from time_section import profile_section, stage_notes  # noqa: E402


def image_folder(doc_path, image_dir):
    """Creates the image folder; its path relative to the page, as the page links it."""
    os.makedirs(image_dir, exist_ok=True)
    return os.path.relpath(image_dir, os.path.dirname(os.path.abspath(doc_path)))


def write_report(context, records, machine, doc_path, image_dir, accuracy_images, smoke=False,
                 profiles=None, first_call=None):
    res = Results(records)
    profiles = profiles or {}
    plt = get_plt()
    rel_images = image_folder(doc_path, image_dir)
    _, peak, exp_rate = ceilings(res)
    L = sections.intro(smoke) + sections.machine(context, machine, res) + sections.ceiling(res)
    L += sections.targets(res, peak, exp_rate)
    L += block("time") + [stage_notes(res, peak, exp_rate, profiles), ""]
    prof = profile_section(res, profiles, peak, exp_rate)
    if prof:
        L += [prof, ""]
    L += sections.matrix(res, peak, exp_rate)
    plots = make_plots(plt, res, image_dir) if plt else {}
    L += sections.sweeps(res, plots, rel_images) + sections.turnaround(res)
    L += accuracy_section(res, plots.get("tradeoff"), rel_images, accuracy_images, image_dir)
    # The host's stage times and the side-by-side with Mitsuba come from runs of their own,
    # apart: the page keeps them.
    kept = [line for heading in (sections.HOST_STAGES, sections.SIDE_BY_SIDE)
            for line in docfile.section_lines(doc_path, heading)]
    L += (first_call or []) + kept + sections.large_and_failed(res)
    L += sections.files_section()
    docfile.write_text(doc_path, "\n".join(L))
    print(f"report: wrote {doc_path}" + (f" and plots in {image_dir}" if plt else ""))


def write_accuracy_only(context, records, machine, doc_path, image_dir, accuracy_images):
    """The accuracy section alone, from a run of that group, with the run's own machine lines."""
    res = Results(records)
    plt = get_plt()
    rel_images = image_folder(doc_path, image_dir)
    tradeoff = plt and plot_tradeoff(plt, res, os.path.join(image_dir, "bench_error_vs_time.png"))
    lines = accuracy_section(res, tradeoff, rel_images, accuracy_images, image_dir)
    m = machine or {}
    loads = sorted(r["loadavg_1min"] for r in res.records if r.get("loadavg_1min") is not None)
    run = block("accuracy-run", date=context.get("date", "–"), command=m.get("command", "–"),
                device=context.get("device", "–"), nproc=m.get("nproc", "–"),
                before=m.get("loadavg_before", context.get("loadavg_at_start", "–")),
                after=m.get("loadavg_after", "–"),
                loads=text("accuracy-run-loads", lo=fmt(loads[0]), hi=fmt(loads[-1]))
                if loads else "")
    docfile.replace_section(doc_path, lines[:2] + run + [""] + lines[2:])
    docfile.replace_section(doc_path, sections.files_section())


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
    page = open(doc).read()
    for needle in ("## Targets", "hard / truncated", "## The machine's ceiling"):
        if needle not in page:
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
