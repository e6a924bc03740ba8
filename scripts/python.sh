#!/usr/bin/env bash
# The Python module in a virtual environment, .venv/:
#   1. creates .venv/ from Debian's python3 with its site packages, so that Debian's
#      python3-numpy, python3-torch and python3-pytest (scripts/setup.sh) are the ones used;
#   2. installs the build tools from PyPI into it: nanobind and scikit-build-core;
#   3. builds and installs penumbra into it: pip install . (scikit-build-core runs CMake, in
#      build-python/, reused by the next run).
# Then: .venv/bin/python -c 'import penumbra'; .venv/bin/python -m pytest (tests/python/).
# Usage: scripts/python.sh    (after scripts/setup.sh)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

NANOBIND=nanobind==2.9.2
SKBUILD=scikit-build-core==0.11.6
PYTHON=/usr/bin/python3  # Debian's: the one python3-torch and python3-numpy are installed for

if [[ ! -x .venv/bin/python ]]; then
  "$PYTHON" -m venv --system-site-packages .venv
fi
if ! .venv/bin/pip show --quiet nanobind scikit-build-core >/dev/null 2>&1; then
  .venv/bin/pip install --quiet --disable-pip-version-check "$NANOBIND" "$SKBUILD"
fi
# No build isolation: the build uses the tools installed above (and no other download).
.venv/bin/pip install --quiet --disable-pip-version-check --no-build-isolation .
.venv/bin/python -c 'import penumbra; print("python: penumbra", penumbra.__file__)'
