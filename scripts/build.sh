#!/usr/bin/env bash
# Configures and builds penumbra (Release, Ninja) into build/: library, CLI (build/penumbra),
# tests and benchmarks.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
cmake --preset default
cmake --build --preset default
