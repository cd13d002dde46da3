#!/usr/bin/env bash
# The exact test's lanes, A/B in one run, on the 1M lattice box (0: one thread per voxel; 1: the queue alone; 4).
python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters 0.5 --lanes 0 1 4 \
  --only lattice --out "$OUT/wetted_ab_lattice.json" 2>&1 | grep lanes | sed 's/first_replay.*all_classify/classify/'
