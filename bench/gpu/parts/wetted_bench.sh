#!/usr/bin/env bash
# The wetted surface's update per stage on the GPU (specimen, slot block, 1M lattice box; rho = 0.25, 0.5, 1 d).
python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters 0.25 0.5 1.0 --out "$OUT/wetted.json" \
  2>&1 | tail -30
