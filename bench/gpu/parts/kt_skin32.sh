#!/usr/bin/env bash
# Per-kernel GPU times of one wetted update from scratch and with the skin at rest (bench/experiments/kernel_times.py),
# on the specimen and the slot block: which kernels make the skin's classification stage at rest.
timeout 300 python3 bench/experiments/kernel_times.py --device cuda:0 --only specimen slot --skin 0 1 \
  --out "$OUT/kt_skin32.json" 2>&1 | grep -v "^Module\|^Warp\|^   CUDA\|^   Devices\|^     \"\|^   Kernel cache\|^     /" \
  | tee "$OUT/kt_skin32.log"
