#!/usr/bin/env bash
# Per-kernel GPU times of one area-criterion update (bench/experiments/area_kernel_times.py): specimen and 1M lattice.
timeout 300 python3 bench/experiments/area_kernel_times.py --device cuda:0 --out "$OUT/area_kernel_times.json" 2>&1 \
  | grep -v "^Module\|^Warp\|^   CUDA\|^   Devices\|^     \"\|^   Kernel cache\|^     /" | tee "$OUT/area_kernel_times.log"
