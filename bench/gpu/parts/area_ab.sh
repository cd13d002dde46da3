#!/usr/bin/env bash
# The area criterion's per-kernel times before ($BEFORE, a checkout carried beside the tree) and after, in one run on
# one GPU (bench/experiments/area_kernel_times.py); counts hashed per row.
BEFORE="${BEFORE:-.base4}"
for side in before after; do
  if [ "$side" = before ]; then pp="$BEFORE:$PYTHONPATH"; else pp="$PYTHONPATH"; fi
  echo "=== $side"
  PYTHONPATH="$pp" timeout 280 python3 bench/experiments/area_kernel_times.py --device cuda:0 \
    --out "$OUT/akt_$side.json" 2>&1 | grep -v "^Module\|^Warp\|^   CUDA\|^   Devices\|^     \"\|^   Kernel cache\|^     /" \
    | tee "$OUT/akt_$side.log" | grep "^=="
done
