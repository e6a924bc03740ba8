#!/usr/bin/env bash
# Builds the libFuzzer targets (CMake preset `fuzz`: clang, -fsanitize=fuzzer,address,undefined)
# and runs each for a bounded time, starting from the seed corpus in tests/fuzz/<target>/:
#
#   fuzz_obj    load_obj on the bytes (written to a scratch file)
#   fuzz_scene  parse_scene on the bytes (mesh paths resolve to two scratch meshes)
#   fuzz_image  load_image on the bytes (stb_image compiled in, instrumented)
#   fuzz_npy    load_npy on the bytes
#
# Usage: scripts/fuzz.sh [TARGET...]        (default: obj scene image npy)
# Environment:
#   PENUMBRA_FUZZ_SECONDS    seconds per target (default 25; CI runs the default)
#   PENUMBRA_FUZZ_BUILD_DIR  build folder (default build-fuzz)
#   PENUMBRA_FUZZ_CXX        the clang++ to use (default clang++-15, which PoCL depends on on
#                            Debian 12, else clang++)
#   PENUMBRA_FUZZ_SEED       libFuzzer's random seed. Default: random, except in CI (CI=true),
#                            where it is 1, so that every CI run tries the same inputs in the
#                            same order (a finding there is reproducible, not a matter of luck;
#                            new ground is for longer local runs)
# A crash, a sanitizer report, an uncaught exception other than penumbra::Error, a timeout
# (10 s per input) or a memory blow-up (2 GiB) fails the run: the input is saved as
# <build>/fuzz/artifacts/<target>-crash-<sha1> (or -timeout-, -oom-, ...), its first bytes are
# printed, and the script exits with status 1. Reproduce with
#   <build>/fuzz/fuzz_<target> <artifact>
# The fuzzers grow a working corpus in <build>/fuzz/corpus/<target>/ (reused by the next run);
# the seeds in tests/fuzz/ are only read.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

seconds=${PENUMBRA_FUZZ_SECONDS:-25}
build=${PENUMBRA_FUZZ_BUILD_DIR:-build-fuzz}
seed=${PENUMBRA_FUZZ_SEED:-}
[[ -n "$seed" || "${CI:-}" != "true" ]] || seed=1
targets=("$@")
[[ ${#targets[@]} -gt 0 ]] || targets=(obj scene image npy)

cxx=${PENUMBRA_FUZZ_CXX:-}
if [[ -z "$cxx" ]]; then
  for c in clang++-15 clang++; do
    if command -v "$c" >/dev/null 2>&1; then cxx=$c; break; fi
  done
fi
if [[ -z "$cxx" ]]; then
  echo "fuzz: no clang++ found (Debian: apt-get install clang-15)" >&2
  exit 1
fi

cmake --preset fuzz -B "$build" -DCMAKE_CXX_COMPILER="$cxx" >/dev/null
cmake --build "$build" --target penumbra_fuzzers

# The fuzzers link no OpenCL, so LeakSanitizer works here: leaks count as findings.
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:check_initialization_order=1:strict_init_order=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}

status=0
mkdir -p "$build/fuzz/artifacts"
for t in "${targets[@]}"; do
  bin="$build/fuzz/fuzz_$t"
  seeds="tests/fuzz/$t"
  corpus="$build/fuzz/corpus/$t"
  log="$build/fuzz/fuzz_$t.log"
  [[ -x "$bin" && -d "$seeds" ]] || { echo "fuzz: unknown target '$t'" >&2; exit 2; }
  mkdir -p "$corpus"
  echo "fuzz: $t for ${seconds}s (seeds: $seeds, $(ls "$seeds" | wc -l) files; random seed ${seed:-random})"
  start=$(date +%s)
  set +e
  "$bin" "$corpus" "$seeds" -dict="tests/fuzz/$t.dict" -max_total_time="$seconds" \
    -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 ${seed:+-seed="$seed"} \
    -artifact_prefix="$build/fuzz/artifacts/$t-" >"$log" 2>&1
  rc=$?
  set -e
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | cut -d' ' -f2)
  echo "fuzz: target=$t rc=$rc runs=${runs:-?} coverage=${cov:-?} corpus=$(ls "$corpus" | wc -l)" \
       "seconds=$(( $(date +%s) - start ))"
  if [[ $rc -ne 0 ]]; then
    status=1
    echo "fuzz: $t FAILED; the end of its log ($log):"
    tail -n 60 "$log"
    artifact=$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log" | tail -1)
    if [[ -n "$artifact" && -f "$artifact" ]]; then
      echo "fuzz: reproducer $artifact ($(wc -c <"$artifact") bytes), first 512 bytes:"
      od -A d -c "$artifact" | head -n 32 || true
      echo "fuzz: reproduce with: $bin $artifact"
    fi
  fi
done
exit $status
