#!/usr/bin/env bash
# The wetted surface's update per stage on the GPU (specimen, slot block, 1M lattice box), per probe radius
# (WETTED_RHO, mean diameters) and exact-test lanes (WETTED_LANES; 0 is one thread per voxel: an A/B in one run).
python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters ${WETTED_RHO:-0.25 0.5 1.0} \
  --lanes ${WETTED_LANES:-32} --out "$OUT/wetted.json" 2>&1 | tail -30
