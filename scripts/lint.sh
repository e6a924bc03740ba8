#!/usr/bin/env bash
# Lint of penumbra's C++ and docs (README, "Code style and lint"): four checks, all of them by
# default.
#   format  clang-format --dry-run -Werror with .clang-format over the C++ sources of host/,
#           apps/, tests/, bench/, python/ and examples/ (the kernels, kernels/, are left out);
#   tidy    clang-tidy with .clang-tidy and -warnings-as-errors='*' over every source of the
#           compilation database (build/compile_commands.json: the library, the tool, the
#           tests and the benchmarks), headers of the source tree included. It configures the
#           default preset first when that database is missing (configure only, no build).
#           readability-function-size is the function-length rule: 60 lines at most;
#   size    no source file over 500 lines (C++, OpenCL C, Python), and no kernel or Python
#           function over 60 lines (scripts/lint_findings.py measures those, as clang-tidy
#           does the C++'s);
#   refs    every "math.md §N" in the tree names a section of docs/math.md, and nothing cites a
#           document outside the tree (scripts/doc_refs.py; ctest runs it too, as doc_refs).
# A function or a file may be longer only when .lint-allow lists it, with a reason:
#   function <path> <name>   # <reason>     (a GoogleTest test: <name> is Suite.Test)
#   file <path>              # <reason>
# An entry that no longer matches anything fails the check too, so that the list shrinks.
# Usage: scripts/lint.sh [format|tidy|size|refs|all]
# Environment: PENUMBRA_LINT_BUILD_DIR (default build), PENUMBRA_LINT_JOBS (default nproc),
#              CLANG_FORMAT (default clang-format-14), CLANG_TIDY (default clang-tidy-14).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

build=${PENUMBRA_LINT_BUILD_DIR:-build}
jobs=${PENUMBRA_LINT_JOBS:-$(nproc)}
clang_format=${CLANG_FORMAT:-clang-format-14}
clang_tidy=${CLANG_TIDY:-clang-tidy-14}
max_file_lines=500
allow=.lint-allow

# The C++ sources, one per line (find, not git: CI may run on a tree without .git).
sources() {
  find host apps tests bench python examples -type f \( -name '*.cpp' -o -name '*.hpp' \
    -o -name '*.h' \) | LC_ALL=C sort
}

format() {
  local files
  mapfile -t files < <(sources)
  echo "lint: format: ${#files[@]} files ($("$clang_format" --version | grep -o 'version [0-9.]*'))"
  "$clang_format" --dry-run -Werror "${files[@]}"
}

# The findings of clang-tidy, one per line as path:line:col: message [check], deduplicated,
# then filtered by filter_findings.
tidy() {
  if [[ ! -f "$build/compile_commands.json" ]]; then
    cmake --preset default -B "$build" >/dev/null
  fi
  local root tmp
  root=$(pwd)
  tmp=$(mktemp -d)
  # shellcheck disable=SC2064  # expand now
  trap "rm -rf '$tmp'" RETURN
  # Translation units of the database that are ours (not the generated kernel sources).
  python3 - "$build/compile_commands.json" "$root" >"$tmp/units" <<'PY'
import json, os, sys
root = sys.argv[2]
seen = set()
for e in json.load(open(sys.argv[1])):
    f = os.path.normpath(os.path.join(e["directory"], e["file"]))
    rel = os.path.relpath(f, root)
    if rel.split(os.sep)[0] in ("host", "apps", "tests", "bench", "python", "examples") \
            and rel not in seen:
        seen.add(rel)
        print(rel)
PY
  local units
  units=$(cat "$tmp/units")
  echo "lint: tidy: $(wc -l <<<"$units") translation units, $jobs at a time" \
       "($("$clang_tidy" --version | grep -o 'version [0-9.]*'))"
  local start=$SECONDS
  # One log per unit; clang-tidy's exit status is judged below from the findings.
  xargs -P "$jobs" -I{} sh -c \
    '"$1" -p "$2" --quiet --warnings-as-errors="*" "$3" >"$4/$(echo "$3" | tr / _).log" 2>&1 || true' \
    _ "$clang_tidy" "$build" {} "$tmp" <<<"$units"
  echo "lint: tidy: $((SECONDS - start)) s"
  cat "$tmp"/*.log | LINT_UNITS=$units \
    python3 scripts/lint_findings.py "$root" "$allow" tidy
}

# The OpenCL C and Python sources, one per line: clang-tidy does not see them.
other_sources() {
  find kernels bench python scripts examples -type f \( -name '*.cl' -o -name '*.clh' \
    -o -name '*.py' \) | LC_ALL=C sort
}

size() {
  local files status=0
  mapfile -t files < <(sources; other_sources)
  wc -l "${files[@]}" | grep -v ' total$' | python3 scripts/lint_findings.py "$(pwd)" "$allow" \
    size "$max_file_lines" || status=1
  other_sources | python3 scripts/lint_findings.py "$(pwd)" "$allow" functions 60 || status=1
  return $status
}

refs() {
  python3 scripts/doc_refs.py
}

step() {
  local start=$SECONDS
  if "$1"; then
    echo "lint: $1 passed ($((SECONDS - start)) s)"
  else
    echo "lint: $1 FAILED" >&2
    status=1
  fi
}

status=0
case "${1:-all}" in
  format | tidy | size | refs) step "$1" ;;
  all) step format; step size; step refs; step tidy ;;
  *) echo "usage: scripts/lint.sh [format|tidy|size|refs|all]" >&2; exit 2 ;;
esac
exit $status
