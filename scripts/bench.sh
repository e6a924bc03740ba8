#!/usr/bin/env bash
# Benchmarks, from a fresh Debian machine to docs/benchmarks.md:
#   1. installs the packages (scripts/setup.sh, which includes libembree-dev for the ray-traced
#      ground truth, plus python3-matplotlib for the plots),
#   2. builds penumbra_bench (Release) into build/ (or $PENUMBRA_BUILD_DIR),
#   3. runs the default suite (a few minutes on two cores) with JSON output in out/bench/,
#   4. profiles the forward case of each shadow mode, and the accurate model's truncated ones
#      (PENUMBRA_PROFILE=1: device time per kernel, per frame), into out/bench/profile_*.txt,
#   5. times the first render of new processes with the kernel caches cold and warm, and
#      PoCL's floor for as many programs of trivial kernels (bench/first_call.py, which runs
#      penumbra_bench --build-floor) into out/bench/first_call.json,
#   6. runs bench/report.py, which writes docs/benchmarks.md and docs/images/bench_*.png.
#
#   scripts/bench.sh                 the default suite
#   scripts/bench.sh --large         also the large/ cases (much longer)
#   scripts/bench.sh --scaling       also the large/ cases of the face and image sweeps (to 1M
#                                    faces and 2048² images, truncated sampling: 37 s more on
#                                    the 2-core machine of docs/benchmarks.md)
#   scripts/bench.sh --smoke         two tiny cases, report into out/bench/smoke/ (seconds)
#   scripts/bench.sh --accuracy      only the accuracy group; rewrites only the accuracy section
#                                    of docs/benchmarks.md and its pictures (no profiles)
#   scripts/bench.sh --no-report     run only; JSON in out/bench/bench.json
#   scripts/bench.sh --profile-only  redo the per-kernel profiles and the report of the last run
#   scripts/bench.sh -- ARGS...      extra arguments for penumbra_bench (e.g. a filter)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

large=0 smoke=0 report=1 run=1 accuracy=0 scaling=0
extra=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --large) large=1 ;;
    --scaling) scaling=1 ;;
    --smoke) smoke=1 ;;
    --accuracy) accuracy=1 ;;
    --no-report) report=0 ;;
    --profile-only) run=0 ;;
    --) shift; extra=("$@"); break ;;
    -h|--help) awk 'NR > 1 && /^#/ { print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    *) echo "bench: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done

# --- packages ------------------------------------------------------------------------------
./scripts/setup.sh
missing=()
for p in python3-matplotlib; do
  status=$(dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "installed" ]] || missing+=("$p")
done
if [[ ${#missing[@]} -gt 0 ]]; then
  echo "bench: installing ${missing[*]}"
  SUDO=()
  if [[ $(id -u) -ne 0 ]]; then
    if command -v sudo >/dev/null 2>&1; then SUDO=(sudo); else
      echo "bench: not root and no sudo; install as root: apt-get install ${missing[*]}" >&2
      exit 1
    fi
  fi
  export DEBIAN_FRONTEND=noninteractive
  "${SUDO[@]}" apt-get update
  "${SUDO[@]}" apt-get install -y --no-install-recommends "${missing[@]}"
fi

# The Python that has matplotlib (the Debian one, if another python3 comes first on PATH).
PYTHON=python3
if ! python3 -c 'import matplotlib' >/dev/null 2>&1 && [[ -x /usr/bin/python3 ]]; then
  PYTHON=/usr/bin/python3
fi

# --- build ---------------------------------------------------------------------------------
BUILD=${PENUMBRA_BUILD_DIR:-build}
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD" --target penumbra_bench penumbra
BENCH="$BUILD/penumbra_bench"

if [[ $smoke -eq 1 ]]; then
  "$PYTHON" bench/report.py --smoke --bench "$BENCH" --out-dir out/bench/smoke
  exit 0
fi

# --- run -----------------------------------------------------------------------------------
if [[ $run -eq 1 ]]; then
  mkdir -p out/bench/images
  args=(--benchmark_out=out/bench/bench.json --benchmark_out_format=json)
  [[ $large -eq 1 ]] && args+=("--benchmark_filter=.")
  [[ $scaling -eq 1 ]] && args+=("--scaling")
  [[ $accuracy -eq 1 ]] && args+=("--benchmark_filter=^accuracy/")
  args+=("${extra[@]}")

  pocl=$(dpkg-query -W -f='${Version}' libpocl2 2>/dev/null || true)
  [[ -n "$pocl" ]] || pocl=$(clinfo 2>/dev/null | sed -n 's/^ *Platform Version *//p' | head -1)
  load_before=$(cut -d' ' -f1-3 /proc/loadavg)
  cmd="$BENCH ${args[*]}"
  echo "bench: $cmd"
  start=$(date +%s)
  PENUMBRA_BENCH_IMAGES=out/bench/images "$BENCH" "${args[@]}"
  wall=$(( $(date +%s) - start ))
  load_after=$(cut -d' ' -f1-3 /proc/loadavg)

  "$PYTHON" - "$pocl" "$load_before" "$load_after" "$cmd" "$wall" <<'EOF'
import json, os, subprocess, sys
pocl, before, after, cmd, wall = sys.argv[1:]
model = ""
for line in subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines():
    if line.startswith("Model name"):
        model = line.split(":", 1)[1].strip()
nproc = subprocess.run(["nproc"], capture_output=True, text=True).stdout.strip()
json.dump({"cpu_model": model, "nproc": nproc, "pocl_version": pocl, "loadavg_before": before,
           "loadavg_after": after, "command": cmd, "wall_seconds": float(wall)},
          open("out/bench/machine.json", "w"), indent=1)
EOF
  echo "bench: JSON in out/bench/bench.json (${wall} s)"
fi

if [[ $accuracy -eq 1 ]]; then
  [[ $report -eq 1 ]] && "$PYTHON" bench/report.py --json out/bench/bench.json \
    --machine out/bench/machine.json --doc docs/benchmarks.md --images docs/images \
    --accuracy-images out/bench/images --accuracy-only
  exit 0
fi

# --- per-kernel profile --------------------------------------------------------------------
# The suite's forward case of each mode at the reference point (bundled scene, 256², 256² map,
# the paper's shadow model), run by penumbra_bench with PENUMBRA_PROFILE=1: every launch waits
# for its kernel and the device time per kernel, summed over the case's frames (its warm-up
# included), is printed at exit; the report divides by the frames (PoCL's own POCL_TRACING=cq
# profiler corrupts memory in PoCL 3.1: docs/faults.md). A failed run's exit status is recorded
# and the report says the profile is unavailable.
# exact-dense is the exact case at σ_s = 400, where no Gaussian weight is 0 (the products run
# on every weight); accurate the truncated case of the accurate model.
rm -f out/bench/profile_*.txt
while read -r shadows sampling sigma; do
  f="out/bench/profile_fwd_${shadows}_${sampling}.txt"
  status=0
  case=${sampling%-dense} model=
  [[ $sampling == accurate ]] && case=truncated model=/model:accurate
  PENUMBRA_PROFILE=1 timeout 600 "$BENCH" --benchmark_min_time=0.5 \
    --benchmark_filter="^fwd/$shadows/$case/img:256/map:256/faces:1312/sigma_s:$sigma/lights:1$model/manual_time" \
    > "$f" 2>&1 || status=$?
  echo "exit status $status" >> "$f"
  echo "bench: profile $shadows/$sampling: exit status $status"
done <<'MODES'
none truncated 2
hard truncated 2
hard exact 2
hard exact-dense 400
hard gemm 2
soft truncated 2
hard accurate 2
soft accurate 2
MODES

# --- first call in a new process ------------------------------------------------------------
if [[ $run -eq 1 ]]; then
  "$PYTHON" bench/first_call.py --cli "$BUILD/penumbra" --bench "$BUILD/penumbra_bench" --runs 5 \
    --out out/bench/first_call.json
fi

# --- report --------------------------------------------------------------------------------
if [[ $report -eq 1 ]]; then
  "$PYTHON" bench/report.py --json out/bench/bench.json --machine out/bench/machine.json \
    --doc docs/benchmarks.md --images docs/images --accuracy-images out/bench/images \
    --profiles out/bench --first-call out/bench/first_call.json
fi
