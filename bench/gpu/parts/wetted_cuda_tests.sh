#!/usr/bin/env bash
# The wetted surface's and the walls' CUDA tests alone (after a change to the wetted kernels).
python3 -m pytest -q -p no:cacheprovider -rfEs -k cuda tests/test_wetted.py tests/test_walls.py 2>&1 \
  | tee "$OUT/pytest_cuda_wetted.log" | tail -5
