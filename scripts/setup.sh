#!/usr/bin/env bash
# Installs the Debian packages penumbra builds and runs with (PoCL gives an OpenCL CPU device).
# Skips apt entirely when every package is already installed, so re-runs are fast.
#   scripts/setup.sh          install what is missing
#   scripts/setup.sh --list   print the package names, one line (for .ci/run's apt-get)
set -euo pipefail

# clang-15 (with libclang-common-15-dev: libFuzzer and the ASan/UBSan runtimes) builds the
# fuzzers of scripts/fuzz.sh and compiles every kernel variant for SPIR (scripts/spir_check.sh,
# a ctest test); PoCL depends on it already, so listing it costs nothing. The
# sanitizer build of the test suite uses g++'s own runtimes (libasan, libubsan). Embree 3
# (libembree-dev) ray-traces the ground truth of the accuracy benchmarks and their test. The
# Python module (scripts/python.sh) builds against python3-dev in a python3-venv environment
# that sees Debian's python3-numpy, python3-torch and python3-pytest. clang-format-14 and
# clang-tidy-14 (Debian 12's default versions) check the style and lint the C++
# (scripts/lint.sh); the output of clang-format depends on its version, so it is pinned.
# Assimp (libassimp-dev) reads the mesh formats other than OBJ; its own test models
# (assimp-testmodels) are the mesh readers' test fixtures.
# oclgrind (21.10), a second OpenCL implementation that interprets every work-item, checks the
# kernels for out-of-bounds accesses, data races and API misuse (scripts/oclgrind.sh).
PACKAGES=(
  pocl-opencl-icd ocl-icd-opencl-dev opencl-headers opencl-clhpp-headers
  libclblast-dev libglm-dev libbenchmark-dev libgtest-dev libtinyobjloader-dev libstb-dev libgif-dev
  libcli11-dev nlohmann-json3-dev libassimp-dev assimp-testmodels libembree-dev cmake ninja-build
  g++ pkg-config clinfo clang-15
  clang-format-14 clang-tidy-14 oclgrind
  python3 python3-dev python3-venv python3-numpy python3-torch python3-pytest
)

if [[ "${1:-}" == "--list" ]]; then
  echo "${PACKAGES[*]}"
  exit 0
fi

missing=()
for p in "${PACKAGES[@]}"; do
  status=$(dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "installed" ]] || missing+=("$p")
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "setup: all ${#PACKAGES[@]} packages already installed"
  exit 0
fi

echo "setup: installing ${missing[*]}"
SUDO=()
if [[ $(id -u) -ne 0 ]]; then
  if command -v sudo >/dev/null 2>&1; then
    SUDO=(sudo)
  else
    echo "setup: not root and no sudo; install as root: apt-get install ${missing[*]}" >&2
    exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update
"${SUDO[@]}" apt-get install -y --no-install-recommends "${missing[@]}"
