#!/usr/bin/env bash
# Issue 33: the side pass with the decided partial lamps listed (branch area-partial, DEFER_PARTIAL) against main, in
# one run on one GPU: bench/experiments/area_kernel_times.py for main's tree (.tMain) and the branch's with
# DEFER_PARTIAL = True (.aP, a copy of its warp_lamp), each run twice; counts hashed per row (equal = bitwise).
for run in 1 2; do
  for t in main:.tMain partial:.aP; do
    tag="${t%%:*}"; dir="${t#*:}"
    PYTHONPATH="$PWD/$dir:/root/site" timeout 200 python3 bench/experiments/area_kernel_times.py --device cuda:0 \
      --out "$OUT/akt_${tag}_$run.json" 2>&1 | grep -v "^Module\|^Warp\|^   CUDA\|^   Devices\|^     \"\|^   Kernel cache\|^     /" \
      | tee "$OUT/akt_${tag}_$run.log" | grep "^==" | sed "s/^/$tag-$run /"
  done
done
