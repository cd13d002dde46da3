#!/usr/bin/env bash
# The wetted surface's update per stage on the GPU (specimen, slot block, 1M lattice box), per probe radius
# (WETTED_RHO, mean diameters), the exact tests queued or not (WETTED_QUEUE "0 1": an A/B in one run).
python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters ${WETTED_RHO:-0.25 0.5 1.0} \
  --queue ${WETTED_QUEUE:-1} --out "$OUT/wetted.json" 2>&1 | tail -30
