#!/usr/bin/env bash
# Fresh machine to green tests: installs the packages, builds, runs the whole test suite: ctest,
# scripts/install_check.sh (the library installed and used by examples/cpp), then the Python
# module built into .venv/ (scripts/python.sh) and its tests (pytest, tests/python/).
# In CI (CI=true, as .ci/run sets it), with PENUMBRA_HARDENING=1 or with the argument `all`
# it then runs the hardening checks too (README, "Hardening"):
#   asan  the library, the tool and the whole test suite built with ASan+UBSan (preset `asan`,
#         build-asan/), every test run under the sanitizers;
#   fuzz  the libFuzzer targets of the file loaders, 25 s each (scripts/fuzz.sh, build-fuzz/);
#   oclgrind  every kernel on Oclgrind, a second OpenCL implementation, with its memory, race,
#         API and uninitialised-read checks, and double-precision gradient checks there
#         (scripts/oclgrind.sh, build/'s tool; 44 cases of a 12² random scene);
#   lint  clang-format's check, clang-tidy and the size rules over the C++ (scripts/lint.sh,
#         README, "Code style and lint"), with build/'s compilation database.
# Usage: scripts/test.sh [suite|asan|fuzz|oclgrind|lint|all]   (no argument: the suite, plus the rest in CI)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

suite() {
  ./scripts/setup.sh
  ./scripts/build.sh
  ctest --preset default
  ./scripts/install_check.sh
  ./scripts/python.sh
  PENUMBRA_CLI=build/penumbra .venv/bin/python -m pytest -q tests/python
}

# ASan+UBSan over the whole suite, with GCC's runtimes. PoCL compiles and runs the kernels
# inside the test process (its code and LLVM's are not instrumented); what that needs:
#   ASAN_OPTIONS
#     detect_leaks=0     LeakSanitizer's stop-the-world pass at exit races with PoCL's worker
#                        threads ("Tracer caught signal 11", in some processes only), and PoCL
#                        and LLVM keep allocations until exit. Also the compiled-in default of
#                        the build (cmake/sanitizer_defaults.cpp). The tests that never touch
#                        OpenCL run a second time below with detect_leaks=1.
#     check_initialization_order=1:strict_init_order=1:detect_stack_use_after_return=1
#                        stricter checks of our own code; no trouble with PoCL.
#   UBSAN_OPTIONS
#     print_stacktrace=1:halt_on_error=1  (the build also uses -fno-sanitize-recover=all, so
#                        any finding fails the test that hit it)
# No test is filtered out: the whole suite runs in about 70 s under ASan on 2 cores.
asan() {
  ./scripts/setup.sh
  local dir=${PENUMBRA_ASAN_BUILD_DIR:-build-asan}
  cmake --preset asan -B "$dir"
  cmake --build "$dir"
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=0:check_initialization_order=1:strict_init_order=1:detect_stack_use_after_return=1}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
  ctest --test-dir "$dir" --output-on-failure
  # Leak check where LeakSanitizer works: files, scenes, the CPU reference, GIF, the loaders'
  # regression inputs — none of them opens an OpenCL device.
  ASAN_OPTIONS=detect_leaks=1 "$dir/tests/penumbra_tests" \
    --gtest_filter='Io*:Gif.*:*Reference.*:ErrorsFuzz.*' --gtest_brief=1
}

fuzz() {
  ./scripts/setup.sh
  bash scripts/fuzz.sh
}

oclgrind() {
  ./scripts/setup.sh
  [[ -x build/penumbra ]] || ./scripts/build.sh
  ./scripts/oclgrind.sh build/penumbra
}

lint() {
  ./scripts/setup.sh
  ./scripts/lint.sh
}

# Runs one step and reports how long it took.
step() {
  local start=$SECONDS
  echo "test.sh: === $1 ==="
  "$1"
  echo "test.sh: === $1 passed in $((SECONDS - start)) s ==="
}

case "${1:-}" in
  suite) step suite ;;
  asan) step asan ;;
  fuzz) step fuzz ;;
  oclgrind) step oclgrind ;;
  lint) step lint ;;
  all) step suite; step asan; step fuzz; step oclgrind; step lint ;;
  "")
    step suite
    if [[ "${CI:-}" == "true" || "${PENUMBRA_HARDENING:-}" == "1" ]]; then
      step asan
      step fuzz
      step oclgrind
      step lint
    fi
    ;;
  *) echo "usage: scripts/test.sh [suite|asan|fuzz|oclgrind|lint|all]" >&2; exit 2 ;;
esac
echo "test.sh: all passed in ${SECONDS} s"
