#!/usr/bin/env bash
# Compiles every kernel variant the renderer can build (`penumbra kernels --variants`: both
# precisions, every sampling variant, the launch parameters of every tuning the database, the
# heuristic and the tuner may choose, for a GPU-like and a CPU-like device) offline with clang
# for SPIR (-target spir64), so that constructs only one vendor's compiler accepts fail here,
# without a GPU. Float variants are compiled as for a device without cl_khr_fp64: a double
# constant or double arithmetic in a float program fails. -Wall -Werror: any warning fails.
#
# Usage: scripts/spir_check.sh [PENUMBRA]      (default: build/penumbra)
# Environment:
#   PENUMBRA_SPIR_CLANG  the clang to use (default clang-15, which scripts/setup.sh installs,
#                        else clang-14, else clang)
#   PENUMBRA_SPIR_JOBS   compilers run at once (default 2)
# Prints the diagnostics of every variant that fails and one summary line
#   spir_check: N variants compiled with CLANG (spir64) in T s[, K failed]
# and exits with 1 when any failed. Without a clang it skips (status 77, which ctest reports as
# skipped), except in CI (CI=true), where that is a failure.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

penumbra=${1:-build/penumbra}
clang=${PENUMBRA_SPIR_CLANG:-}
if [[ -z "$clang" ]]; then
  for c in clang-15 clang-14 clang; do
    if command -v "$c" >/dev/null 2>&1; then clang=$c; break; fi
  done
fi
if [[ -z "$clang" ]] || ! command -v "$clang" >/dev/null 2>&1; then
  echo "spir_check: no clang found (install clang-15: scripts/setup.sh)" >&2
  [[ "${CI:-}" == "true" ]] && exit 1
  exit 77
fi
jobs=${PENUMBRA_SPIR_JOBS:-2}

dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
start=$(date +%s.%N)
"$penumbra" kernels --variants "$dir/src" >"$dir/list.txt"

# One variant: its options file next to its source; diagnostics into <stem>.log on failure.
compile() {
  local clang=$1 src=$2
  local stem=${src%.cl} fp64=(-Xclang -cl-ext=-cl_khr_fp64)
  local options
  read -r -a options <"$stem.options"
  # How a device treats subnormals is no part of SPIR code: clang calls the option unused.
  local kept=() o
  for o in "${options[@]}"; do [[ "$o" == -cl-denorms-are-zero ]] || kept+=("$o"); done
  options=("${kept[@]}")
  [[ " ${options[*]} " == *" -DPENUMBRA_DOUBLE "* ]] && fp64=(-Xclang -cl-ext=+cl_khr_fp64)
  if ! "$clang" -x cl -target spir64 -Xclang -finclude-default-header "${fp64[@]}" -Wall -Werror \
      -O0 -c -emit-llvm -o /dev/null "${options[@]}" "$src" >"$stem.log" 2>&1; then
    echo "FAILED: $(basename "$src") ($(tr -d '\n' <"$stem.options"))"
    grep -m 8 -v "^ *\^\? *$" "$stem.log" || true
    return 1
  fi
}
export -f compile

n=$(find "$dir/src" -name '*.cl' | wc -l)
status=0
find "$dir/src" -name '*.cl' -print0 | sort -z |
  xargs -0 -n 1 -P "$jobs" bash -c 'compile "$0" "$1"' "$clang" >"$dir/failures.txt" || status=$?
failed=$(grep -c '^FAILED:' "$dir/failures.txt" || true)
cat "$dir/failures.txt"
seconds=$(echo "$(date +%s.%N) - $start" | bc)
summary="spir_check: $n variants compiled with $clang (spir64) in $(printf '%.0f' "$seconds") s"
if [[ $status -ne 0 || $failed -ne 0 || $n -eq 0 ]]; then
  echo "$summary, ${failed} failed"
  exit 1
fi
echo "$summary"
