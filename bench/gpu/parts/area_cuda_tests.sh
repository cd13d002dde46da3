#!/usr/bin/env bash
# The CUDA tests of the files the area kernels and the frame transform touch (after a change there).
python3 -m pytest -q -p no:cacheprovider -rfEs -k cuda tests/test_area.py tests/test_lamp.py tests/test_tolerance.py \
  tests/test_frames.py tests/test_distributed.py 2>&1 | tee "$OUT/pytest_cuda_area.log" | tail -6
