#!/usr/bin/env bash
# Per-kernel GPU times of one wetted update (bench/experiments/kernel_times.py): the bench's scenes, the thin list on and off.
timeout 300 python3 bench/experiments/kernel_times.py --device cuda:0 --thin-list 1 0 --out "$OUT/kernel_times.json" 2>&1 \
  | grep -v "^Module\|^Warp\|^   CUDA\|^   Devices\|^     \"\|^   Kernel cache\|^     /" | tee "$OUT/kernel_times.log"
