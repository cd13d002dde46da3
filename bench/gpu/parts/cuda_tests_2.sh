#!/usr/bin/env bash
# The CUDA tests, even-numbered files (with cuda_tests_1 on the other GPU).
CUDA_TEST_GROUP=2 source "$(dirname "${BASH_SOURCE[0]}")/cuda_tests.sh"
