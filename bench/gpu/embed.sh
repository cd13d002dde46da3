#!/usr/bin/env bash
# One device lease for embedding: the SphereTest at four resolutions with its step in one CUDA graph, and the
# Newton ball on CUDA (newton carried as a wheel).
source "$(dirname "$0")/preamble.sh"
python3 examples/sphere_test.py --device cuda:0 --steps 40000 --json "$OUT/sphere_test.json" 2>&1 \
  | tee "$OUT/sphere_test.log" | grep -v "unbalanced ratio"
python3 examples/newton_pressure.py --device cuda:0 --frames 200 2>&1 | tee "$OUT/newton.log"
