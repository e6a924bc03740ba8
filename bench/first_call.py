#!/usr/bin/env python3
"""The first render in a new process: how much of it is building kernels, with and without the
caches of compiled programs (penumbra's kernel cache and PoCL's own).

Each run is a new `penumbra render` process of the bundled scene (default options, 256² image)
with PENUMBRA_PROFILE=1, which prints one line per program built (from source or loaded from
the kernel cache) with its time. Four states:

  cold             empty kernel cache (PENUMBRA_CACHE_DIR), empty PoCL cache (POCL_CACHE_DIR)
  kernel cache     the kernel cache filled by an earlier process, PoCL's cache empty
  both warm        both filled by an earlier process
  PoCL cache only  PENUMBRA_CACHE_DIR=off, PoCL's cache filled (how a new process started
                   before penumbra had its own cache)

Then PoCL's floor: programs of trivial kernels, as many programs and kernels as the cold render
compiled (counted in its PoCL cache), built by `penumbra_bench --build-floor` in new processes
with an empty PoCL cache.

Writes JSON (every run) to --out and prints a Markdown table; with --doc, also writes the
section "First call in a new process" of that page (bench/report.py writes the same section
when given --first-call JSON). scripts/bench.sh runs it before the report.

    python3 bench/first_call.py --cli build/penumbra --runs 5 --out out/bench/first_call.json \
        [--bench build/penumbra_bench] [--doc docs/benchmarks.md]
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import docfile  # bench/docfile.py, next to this script

STATES = ("cold", "kernel cache", "both warm", "PoCL cache only")


def run_once(cli, penumbra_cache, pocl_cache, out_png):
    env = dict(os.environ, PENUMBRA_CACHE_DIR=penumbra_cache, POCL_CACHE_DIR=pocl_cache,
               PENUMBRA_PROFILE="1")
    start = time.monotonic()
    p = subprocess.run([cli, "render", "-o", out_png], env=env, capture_output=True, text=True)
    wall = time.monotonic() - start
    if p.returncode != 0:
        sys.exit(f"first_call: render failed ({p.returncode}):\n{p.stderr}")
    render_ms = float(re.search(r", ([0-9.]+) ms \(", p.stdout).group(1))
    builds = [(m.group(2), float(m.group(3))) for m in
              re.finditer(r"program (\S+) (built from source|loaded from the cache) in ([0-9.]+) ms",
                          p.stderr)]
    return {"render_ms": render_ms, "build_ms": sum(ms for _, ms in builds),
            "from_source": sum(how == "built from source" for how, _ in builds),
            "from_cache": sum(how != "built from source" for how, _ in builds),
            "process_s": wall}


def measure(cli, runs, scratch):
    """Every state `runs` times; a fresh folder for each cache that must be empty."""
    out_png = os.path.join(scratch, "first_call.png")
    filled_kernels, filled_pocl = (os.path.join(scratch, d) for d in ("kernels", "pocl"))
    run_once(cli, filled_kernels, filled_pocl, out_png)  # fills both (untimed)
    results = {s: [] for s in STATES}
    for i in range(runs):
        fresh = lambda name: tempfile.mkdtemp(prefix=f"{name}{i}_", dir=scratch)
        cold_pocl = fresh("p")
        results["cold"].append(run_once(cli, fresh("k"), cold_pocl, out_png))
        results["kernel cache"].append(run_once(cli, filled_kernels, fresh("p"), out_png))
        results["both warm"].append(run_once(cli, filled_kernels, filled_pocl, out_png))
        results["PoCL cache only"].append(run_once(cli, "off", filled_pocl, out_png))
    return results, program_kernels(cold_pocl)


def program_kernels(pocl_cache):
    """Kernels per program that PoCL compiled into `pocl_cache` (its layout: XX/HASH/KERNEL/),
    largest first; empty for another driver."""
    subdirs = lambda path: [os.path.join(path, d) for d in sorted(os.listdir(path))
                            if os.path.isdir(os.path.join(path, d))]
    counts = [len(subdirs(prog)) for top in subdirs(pocl_cache) for prog in subdirs(top)]
    return sorted((c for c in counts if c > 0), reverse=True)


def measure_floor(bench, counts, runs, scratch):
    """penumbra_bench --build-floor: programs of trivial kernels, `counts` of them, each run a
    new process with an empty PoCL cache; the milliseconds of each program, per run."""
    arg = ",".join(map(str, counts))
    per_run = []
    for i in range(runs):
        env = dict(os.environ, POCL_CACHE_DIR=tempfile.mkdtemp(prefix=f"floor{i}_", dir=scratch))
        p = subprocess.run([bench, "--build-floor", arg], env=env, capture_output=True, text=True)
        if p.returncode != 0:
            sys.exit(f"first_call: {bench} --build-floor {arg} failed ({p.returncode}):\n{p.stderr}")
        per_run.append(json.loads(p.stdout)["programs_ms"])
    return {"kernels": counts, "command": f"{bench} --build-floor {arg}", "programs_ms": per_run}


def median(rows, key):
    return statistics.median(r[key] for r in rows)


def table(results):
    lines = ["| state | programs from source / cache | kernel build, ms | first render, ms "
             "| whole process, s |", "|---|---|---|---|---|"]
    for state in STATES:
        rows = results[state]
        lines.append(f"| {state} | {rows[0]['from_source']} / {rows[0]['from_cache']} "
                     f"| {median(rows, 'build_ms'):,.0f} | {median(rows, 'render_ms'):,.0f} "
                     f"| {median(rows, 'process_s'):.2f} |")
    return "\n".join(lines)


TITLE = "## First call in a new process"


def section(doc):
    """The page's section for the JSON `doc` written by this script."""
    r = doc["states"]
    cold, warm = median(r["cold"], "render_ms"), median(r["both warm"], "render_ms")
    return [
        TITLE, "",
        "The first `Renderer::render` of a process builds the OpenCL programs its stages use",
        "(only those, when first needed). Each row is a new `penumbra render` process of the",
        f"bundled scene (default options), the median of {doc['runs']} runs{machine(doc)}",
        f"(`bench/first_call.py`, {doc['date']}, `{doc['command']}`).",
        "*Kernel build* sums the time spent getting the programs (compiled from source or",
        "loaded from the kernel cache), *first render* is the whole call as the tool prints it.",
        "*cold*: empty kernel cache (`PENUMBRA_CACHE_DIR`) and empty PoCL cache",
        "(`POCL_CACHE_DIR`); *kernel cache*: penumbra's filled by an earlier process, PoCL's",
        "empty; *both warm*: both filled; *PoCL cache only*: `PENUMBRA_CACHE_DIR=off` and",
        "PoCL's filled (how a new process started before penumbra had its own cache).",
        "", table(r), "",
        f"Load average (1, 5, 15 min) {doc['loadavg_before']} before the runs and",
        f"{doc['loadavg_after']} after (two shared cores: above 2, other processes competed).",
        f"From cold to both warm the first render goes from {cold:,.0f} ms to {warm:,.0f} ms.",
        "The build fills the kernel cache (`penumbra kernels --warm`, README), so a user's",
        "first render after setup is the *kernel cache* row.",
        "",
        "On PoCL, asking for a program's binary compiles every kernel of it for any",
        "work-group size, and the binary holds that code. By default PoCL compiles each kernel",
        "once more at its first launch, for that launch's sizes; penumbra sets",
        "`POCL_WORK_GROUP_SPECIALIZATION=0` (unless the variable is set), so launches run the",
        "code the binary holds: a process that fills the kernel cache compiles each kernel once,",
        "and one that loads it compiles nothing (the *kernel cache* row).",
        "What keeps the cold row above a second is PoCL compiling the kernels a first render",
        f"uses{kernel_count(doc.get('floor'))}: work-group generation and code generation",
        "(`POCL_DEBUG=llvm,timing`), most of it for pcf_sample and raster_fragments, then",
        "face_setup, raster_resolve and raster_count, besides loading PoCL's built-in library.",
        "PoCL inlines each kernel into",
        "two work-group launchers and compiles both; the raster's long kernels are built as a",
        "call to a body of their own (`KERNEL_BODY`, kernels/common/real.clh), compiled once.",
        "PoCL compiles one program at a time: the programs a first render uses, built from four",
        "threads sharing one context, take as long as one after another, and so do two threads",
        "with a context each, so the second core cannot shorten the cold call (the measurements:",
        "[benchmarks-log.md](benchmarks-log.md)).",
        "",
    ] + floor_paragraph(doc.get("floor"))


def cpu_model():
    """The CPU's model name as /proc/cpuinfo gives it ('' where it gives none)."""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return ""


def machine(doc):
    """' on <CPU>, <n> cores' for the section, where the JSON records them."""
    return f" on {doc['cpu']}, {doc['cores']} cores" if doc.get("cpu") else ""


def kernel_count(floor):
    """How many kernels the cold first render compiled, as the floor's programs hold them."""
    return f" ({sum(floor['kernels'])} in this run)" if floor else ""


def floor_paragraph(floor):
    """What PoCL spends on programs of trivial kernels shaped like a first render's."""
    if not floor:
        return []
    totals = [sum(run) for run in floor["programs_ms"]]
    total, first = statistics.median(totals), statistics.median(r[0] for r in floor["programs_ms"])
    k = floor["kernels"]
    verdict = ("so on this machine and PoCL version it cannot take under a second whatever its "
               "kernels compute." if total >= 1000 else
               f"which leaves {1000 - total:,.0f} ms of a second for compiling its kernels' own "
               "code and rendering.")
    return [
        f"PoCL's floor: {len(k)} programs of {', '.join(map(str, k))} trivial kernels (each",
        "stores a constant), as many as the cold first render compiled, each built and asked",
        "for its binary as penumbra builds a stage, in a new process with an empty PoCL cache",
        f"(`{floor['command']}`), took {total:,.0f} ms (median of",
        f"{len(totals)} runs, {min(totals):,.0f}–{max(totals):,.0f}; the first program",
        f"{first:,.0f} ms of it, as it loads PoCL's kernel library). A cold first call spends",
        f"that before any of its kernels' own code, {verdict}",
        "",
    ]


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli", default="build/penumbra")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", default="out/bench/first_call.json")
    ap.add_argument("--bench", help="penumbra_bench, for its --build-floor (default: next to "
                    "--cli)")
    ap.add_argument("--doc", help="also write the section into this page")
    a = ap.parse_args()
    bench = a.bench or os.path.join(os.path.dirname(a.cli), "penumbra_bench")
    scratch = tempfile.mkdtemp(prefix="penumbra_first_call_")
    try:
        load_before = open("/proc/loadavg").read().split()[:3]
        results, kernels = measure(a.cli, a.runs, scratch)
        floor = measure_floor(bench, kernels, a.runs, scratch) if kernels else None
        load_after = open("/proc/loadavg").read().split()[:3]
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    doc = {"runs": a.runs, "command": f"{a.cli} render -o PNG (PENUMBRA_PROFILE=1)",
           "loadavg_before": " ".join(load_before), "loadavg_after": " ".join(load_after),
           "date": time.strftime("%Y-%m-%dT%H:%M:%S+00:00", time.gmtime()),
           "cpu": cpu_model(), "cores": os.cpu_count(),
           "states": results, "floor": floor}
    docfile.write_text(a.out, json.dumps(doc, indent=1))
    print(table(results))
    print("\n".join(floor_paragraph(floor)))
    print(f"load average before {doc['loadavg_before']}, after {doc['loadavg_after']}")
    if a.doc:
        docfile.replace_section(a.doc, section(doc), before="## Large cases")


if __name__ == "__main__":
    main()
