#!/usr/bin/env bash
# The CUDA tests, odd-numbered files (with cuda_tests_2 on the other GPU).
CUDA_TEST_GROUP=1 source "$(dirname "${BASH_SOURCE[0]}")/cuda_tests.sh"
