#!/usr/bin/env bash
# The area criterion's CUDA tests alone (after a change to the area kernels).
python3 -m pytest -q -p no:cacheprovider -rfEs -k cuda tests/test_area.py 2>&1 | tee "$OUT/pytest_cuda_area_only.log" | tail -4
