#!/usr/bin/env bash
# Final lease, part C: the SphereTest at four resolutions (whole cycle in one CUDA graph), the triaxial test at
# 10,000 particles (following grid, captured cycles), and the wetted-surface mode's stages beside "first".
source "$(dirname "$0")/preamble.sh"
python3 examples/sphere_test.py --device cuda:0 --steps 40000 --json "$OUT/sphere_test.json" 2>&1 \
  | grep -v "unbalanced ratio" | tee "$OUT/sphere_test.log" | tail -8
python3 examples/triaxial.py --device cuda:0 --time --json "$OUT/triaxial.json" --plot "$OUT/triaxial.png" 2>&1 \
  | grep -v "compression cycle" | tee "$OUT/triaxial.log" | tail -45
python3 bench/experiments/wetted_bench.py --device cuda:0 --out "$OUT/wetted.json" 2>&1 | tee "$OUT/wetted.log" | tail -6
