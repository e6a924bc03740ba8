#!/usr/bin/env bash
# Fresh machine to pictures: installs the packages, builds, and runs the shadow demo on the
# bundled scene (a sphere on a plane lit by a point light, data/scenes/turnaround.json):
#   out/turnaround.png          one view with hard shadows
#   out/turnaround/             the 90-frame turnaround (frame_000.png ... and turnaround.gif)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
./scripts/setup.sh
./scripts/build.sh
build/penumbra render -o out/turnaround.png --shadows hard
build/penumbra turnaround -o out/turnaround --shadows hard --frames 90
echo "demo: the picture is at $(pwd)/out/turnaround.png"
echo "demo: the animation is at $(pwd)/out/turnaround/turnaround.gif (frames: out/turnaround/frame_*.png)"
