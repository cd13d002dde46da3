#!/usr/bin/env bash
# The tests' CUDA half only (ids with cuda, and the CUDA-only tests): a quick check between full runs.
timeout "${CUDA_TESTS_TIMEOUT:-420}" python3 -m pytest -q -p no:cacheprovider -rfE -k cuda tests 2>&1 \
  | tee "$OUT/pytest_cuda.log" | tail -25
