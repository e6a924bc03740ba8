#!/usr/bin/env bash
# Runs every kernel of penumbra on Oclgrind, a second OpenCL implementation that interprets
# each work-item, with its checks of memory accesses (always on), data races (--data-races)
# and API calls (--check-api): forward and backward, float and double, both shadow models,
# no, hard and soft shadows, truncated and exact sampling, and CLBlast's GEMM (--sampling
# gemm), each as a `penumbra gradcheck` of a random scene at tiny sizes (a render, its
# backward, and the renders of the finite differences), and a light's cube of six maps
# (--shadow-map cube). The double-precision cases must also
# pass the gradient check itself: the gradients proven on a second implementation. Float
# cases check the kernels only (--rtol 1: float differences are not what they test). The cpu-*
# cases run with a CPU's launch parameters instead of a GPU's. The uninit-* cases run the double
# cases again with Oclgrind's check of reads of memory never written (--uninitialized), around
# the faults of that check in Oclgrind 21.10 (docs/faults.md, "Oclgrind's --uninitialized").
#
# Usage: scripts/oclgrind.sh [PENUMBRA]      (default: build/penumbra)
# Environment:
#   PENUMBRA_OCLGRIND_JOBS  cases run at once (default 2), each on one Oclgrind thread
# A case fails on a non-zero exit status, on anything Oclgrind reports (its log, --log) and on
# anything on stderr (Oclgrind prints some fatal errors there); the failing case's command,
# log and stderr are printed. Prints one summary line
#   oclgrind: N cases in T s[, K failed]
# and exits with 1 when any failed. Without oclgrind it skips (status 77), except in CI
# (CI=true), where that is a failure.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

penumbra=$(realpath "${1:-build/penumbra}")
if ! command -v oclgrind >/dev/null 2>&1; then
  echo "oclgrind: oclgrind not found (install it: scripts/setup.sh)" >&2
  [[ "${CI:-}" == "true" ]] && exit 1
  exit 77
fi
jobs=${PENUMBRA_OCLGRIND_JOBS:-2}

# One line per case: a name, then penumbra's arguments. 12² images and maps keep each case
# small: Oclgrind interprets every work-item.
size="--random-scene --width 12 --height 12 --map-size 12"
checked_cases() {
  local p m s
  for p in double float; do
    local check="--precision $p --samples 2"
    [[ $p == float ]] && check="--precision $p --samples 1 --rtol 1"
    echo "$p-none gradcheck $size $check --shadows none"
    for m in accurate paper; do
      for s in hard soft; do
        echo "$p-$m-$s-truncated gradcheck $size $check --shadow-model $m --shadows $s"
        # Penumbra's own exact kernels: Oclgrind calls itself a GPU, where CLBlast's is the default.
        echo "$p-$m-$s-exact gradcheck $size $check --shadow-model $m --shadows $s" \
          "--sampling exact --exact-backend kernels"
      done
    done
    echo "$p-paper-hard-gemm gradcheck $size $check --shadow-model paper --shadows hard" \
      "--sampling gemm"
    # Six maps of a light's cube, their shares and the seams between them.
    for m in accurate paper; do
      echo "$p-$m-soft-cube gradcheck $size $check --shadow-model $m --shadows soft" \
        "--shadow-map cube"
    done
    # The launch parameters of a CPU (cpu_tuning below), in the shadow stages that use them.
    for m in accurate paper; do
      echo "cpu-$p-$m-soft-truncated gradcheck $size $check --shadow-model $m --shadows soft"
      echo "cpu-$p-$m-hard-exact gradcheck $size $check --shadow-model $m --shadows hard" \
        "--sampling exact"
    done
  done
}
# The double cases again under --uninitialized.
cases() {
  checked_cases
  checked_cases | grep '^double-' | sed 's/^/uninit-/'
}

dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
# Oclgrind calls itself a GPU and gets a GPU's launch parameters; the cpu-* cases run with those
# of a CPU (PoCL's: host/src/cl/device.hpp), given as a tuning database entry for Oclgrind.
cat >"$dir/cpu_tuning.json" <<'JSON'
{"version": 1, "entries": {"Oclgrind Simulator": {
  "raster": {"pixels_per_item": 8, "face_lanes": 1},
  "gather": {"group": 1, "width": 16, "height": 8}, "exact": {"clblast": false}}}}
JSON

# Oclgrind with --uninitialized, started as its launcher starts it but with
# oclgrind_keep_buffers.c's library preloaded ahead of its runtime (the launcher replaces
# LD_PRELOAD), and unoptimised kernels (Oclgrind's optimiser makes of float3 sums a shuffle that
# crashes the check: docs/faults.md).
oclgrind_uninitialized() {
  local dir=$1 log=$2
  shift 2
  OCLGRIND_UNINITIALIZED=1 OCLGRIND_DATA_RACES=1 OCLGRIND_CHECK_API=1 OCLGRIND_NUM_THREADS=1 \
    OCLGRIND_BUILD_OPTIONS=-cl-opt-disable OCLGRIND_LOG=$log LD_LIBRARY_PATH=$OCLGRIND_LIB \
    LD_PRELOAD=$dir/keep_buffers.so:$OCLGRIND_LIB/liboclgrind-rt.so "$@"
}
export -f oclgrind_uninitialized

# One case: Oclgrind's log and the tool's stderr must stay empty, the exit status 0.
run_case() {
  local dir=$1 penumbra=$2 name=$3
  shift 3
  local rc=0 tuning='' checks="oclgrind --data-races --check-api --num-threads 1 --log $dir/$name.log"
  [[ $name == cpu-* ]] && tuning=$dir/cpu_tuning.json
  [[ $name == uninit-* ]] && checks="oclgrind_uninitialized $dir $dir/$name.log"
  PENUMBRA_TUNING=$tuning PENUMBRA_CACHE_DIR=off PENUMBRA_PROGRESS_AFTER=1e9 \
    $checks "$penumbra" "$@" >"$dir/$name.out" 2>"$dir/$name.err" || rc=$?
  if [[ $rc -ne 0 || -s "$dir/$name.log" || -s "$dir/$name.err" ]]; then
    echo "FAILED: $name (exit status $rc): ${checks%% *} penumbra $*"
    head -c 4000 "$dir/$name.log" "$dir/$name.err" "$dir/$name.out" 2>/dev/null || true
    return 1
  fi
  echo "passed: $name: $(tail -n 1 "$dir/$name.out")"
}
export -f run_case

# Oclgrind's runtime, next to its launcher, and the library its --uninitialized cases preload.
export OCLGRIND_LIB
OCLGRIND_LIB=$(dirname "$(realpath "$(command -v oclgrind)")")/../lib/oclgrind
${CC:-cc} -shared -fPIC -o "$dir/keep_buffers.so" scripts/oclgrind_keep_buffers.c

start=$SECONDS
cases >"$dir/cases.txt"
n=$(wc -l <"$dir/cases.txt")
status=0
# shellcheck disable=SC2016  # expanded by the inner shell
xargs -L 1 -P "$jobs" bash -c 'run_case "$@"' run_case "$dir" "$penumbra" \
  <"$dir/cases.txt" >"$dir/results.txt" || status=$?
cat "$dir/results.txt"
failed=$(grep -c '^FAILED:' "$dir/results.txt" || true)
summary="oclgrind: $n cases in $((SECONDS - start)) s"
if [[ $status -ne 0 || $failed -ne 0 ]]; then
  echo "$summary, $failed failed"
  exit 1
fi
echo "$summary"
