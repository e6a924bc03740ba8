"""Renders with PoCL's worker threads pinned to the cores (penumbra's default where every CPU is
allowed) against unpinned (POCL_AFFINITY=0, PoCL's default): new processes, alternated, each
timing rounds of calls of penumbra.torch.render with a batch of 8 shapes of the bundled scene
at 128² (bench/python_calls.py's batch), as JSON: every round's ms per call, and per setting
the rounds slower than --slow ms, the processes with such a round, and the median.

    .venv/bin/python bench/pocl_pinning.py [-o out/bench/pocl_pinning.json] [--processes 8]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import time

import docfile


def rounds_of_one_process(rounds, calls, pinned):
    env = dict(os.environ)
    env.pop("POCL_AFFINITY", None)
    if not pinned:
        env["POCL_AFFINITY"] = "0"
    command = [sys.executable, os.path.abspath(__file__), "--child", f"{rounds},{calls}"]
    p = subprocess.run(command, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"pocl_pinning: a timing process failed ({p.returncode}):\n{p.stderr}")
    return json.loads(p.stdout)


def child(rounds, calls):
    import penumbra
    from python_calls import batch_calls
    one_call, _ = batch_calls(penumbra.Context(), 8, 128, "none")
    one_call()
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        for _ in range(calls):
            one_call()
        times.append(1e3 * (time.perf_counter() - start) / calls)
    print(json.dumps(times))


def summary(processes, slow):
    times = [t for p in processes for t in p]
    return {"rounds": len(times), "slow_rounds": sum(t > slow for t in times),
            "processes_with_slow_rounds": sum(any(t > slow for t in p) for p in processes),
            "processes": len(processes), "median_ms": statistics.median(times),
            "max_ms": max(times), "ms_per_call": processes}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="out/bench/pocl_pinning.json")
    parser.add_argument("--processes", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=12)
    parser.add_argument("--calls", type=int, default=20)
    parser.add_argument("--slow", type=float, default=9.0)
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(*map(int, args.child.split(",")))
        return
    runs = {True: [], False: []}
    for _ in range(args.processes):
        for pinned in (False, True):
            runs[pinned].append(rounds_of_one_process(args.rounds, args.calls, pinned))
    results = {"load": os.getloadavg()[0], "slow_ms": args.slow,
               "unpinned": summary(runs[False], args.slow), "pinned": summary(runs[True], args.slow)}
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    docfile.write_text(args.output, json.dumps(results, indent=1))
    for name in ("unpinned", "pinned"):
        r = results[name]
        print(f"{name}: {r['slow_rounds']} of {r['rounds']} rounds over {args.slow} ms a call, in "
              f"{r['processes_with_slow_rounds']} of {r['processes']} processes; median "
              f"{r['median_ms']:.2f} ms, max {r['max_ms']:.2f} ms")


if __name__ == "__main__":
    main()
