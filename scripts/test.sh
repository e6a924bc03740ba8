#!/usr/bin/env bash
# Fresh machine to green tests: installs the packages, builds, runs the whole test suite.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
./scripts/setup.sh
./scripts/build.sh
ctest --preset default
