#!/usr/bin/env bash
# The tests' CUDA half (ids with cuda, and the CUDA-only tests), every test under its own time limit, verbose with
# the slowest listed. CUDA_TEST_GROUP=1 or 2 takes every other test file (two GPUs: cuda_tests_1, cuda_tests_2).
files=$(ls tests/test_*.py | sort)
case "${CUDA_TEST_GROUP:-all}" in
  1) files=$(echo "$files" | awk 'NR % 2 == 1') ;;
  2) files=$(echo "$files" | awk 'NR % 2 == 0') ;;
esac
to=""
python3 -c "import pytest_timeout" 2>/dev/null && to="--timeout=${CUDA_TEST_TIMEOUT:-150}"
python3 -m pytest -v -p no:cacheprovider -rfEs $to --durations=25 -k cuda $files 2>&1 \
  | tee "$OUT/pytest_cuda${CUDA_TEST_GROUP:-}.log" | grep -E "FAILED|ERROR|passed|failed|Timeout" | tail -40
