#!/usr/bin/env bash
# Prints a fingerprint of everything the renderer computes: the SHA-256 of every raw output
# (`penumbra render --raw`) and every gradient (`penumbra backward`, fed the render's own
# outputs as dL/d(outputs)) of the bundled scene at 64², over each precision, shadow mode,
# shadow model and sampling. Two builds compute the same bits when their fingerprints are equal:
#   scripts/fingerprint.sh build-before/penumbra > before.txt
#   scripts/fingerprint.sh build/penumbra > after.txt && diff before.txt after.txt
# Usage: scripts/fingerprint.sh [PENUMBRA]      (default: build/penumbra)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

penumbra=$(realpath "${1:-build/penumbra}")
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT

configs() {
  local p m s x
  for p in float double; do
    echo "$p-none --precision $p --shadows none"
    for m in accurate paper; do
      for s in hard soft; do
        for x in truncated exact; do
          echo "$p-$m-$s-$x --precision $p --shadow-model $m --shadows $s --sampling $x" \
            "--exact-backend kernels"
        done
      done
    done
    echo "$p-paper-hard-gemm --precision $p --shadow-model paper --shadows hard --sampling gemm"
  done
}

while read -r name args; do
  out="$dir/$name"
  # shellcheck disable=SC2086  # the arguments are words
  "$penumbra" render --width 64 --height 64 --map-size 64 $args -o "$out/view.png" \
    --raw "$out/raw" >/dev/null
  mkdir "$out/grad_in"
  cp "$out"/raw/{color,silhouette,depth}.npy "$out/grad_in/"
  # shellcheck disable=SC2086
  "$penumbra" backward --width 64 --height 64 --map-size 64 $args --grad-in "$out/grad_in" \
    -o "$out/grads" >/dev/null
done < <(configs)

(cd "$dir" && find . -path '*/grad_in' -prune -o -name '*.npy' -print | sort | xargs sha256sum)
