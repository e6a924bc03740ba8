#!/usr/bin/env bash
# fit-shadows on targets ray-traced by the ground truth (penumbra_truth_shadows, Embree), not
# rendered by penumbra: the accurate model's hard-shadow fit must reach IoU >= 0.95 on every
# view (docs/applications.md).
# Usage: test_fit_from_truth.sh TRUTH_SHADOWS PENUMBRA DATA_DIR OUT_DIR
set -euo pipefail
truth=$1 tool=$2 data=$3 out=$4
rm -rf "$out"
mkdir -p "$out"
"$truth" "$data/targets/shadow_shape.obj" 96 "$out"
line=$("$tool" fit-shadows --target "$out/shadow_0.png" --target "$out/shadow_1.png" \
  -o "$out/fit" 2>/dev/null | tail -n 1)
echo "$line"
ious=${line##*iou=[}
ious=${ious%]}
[[ -n $ious ]] || { echo "no IoU in the last line" >&2; exit 1; }
for v in ${ious//,/ }; do
  awk -v v="$v" 'BEGIN { exit !(v >= 0.95) }' || { echo "IoU $v below 0.95" >&2; exit 1; }
done
