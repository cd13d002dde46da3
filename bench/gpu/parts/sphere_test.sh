#!/usr/bin/env bash
# The memo's SphereTest at four resolutions, whole DEM cycle in one CUDA graph (40,000 cycles each).
python3 examples/sphere_test.py --device cuda:0 --steps 40000 --json "$OUT/sphere_test.json" 2>&1 \
  | grep -v "unbalanced ratio" | tail -8
