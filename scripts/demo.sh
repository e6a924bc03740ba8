#!/usr/bin/env bash
# Fresh machine to picture: installs the packages, builds, and renders the bundled scene
# (a sphere on a plane, data/scenes/turnaround.json) to out/turnaround.png.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
./scripts/setup.sh
./scripts/build.sh
build/penumbra render -o out/turnaround.png
echo "demo: the picture is at $(pwd)/out/turnaround.png"
