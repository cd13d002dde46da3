#!/usr/bin/env bash
# Last lease: every test on the CPU and CUDA, on the merged code.
source "$(dirname "$0")/preamble.sh"
python3 -m pytest -q -p no:cacheprovider -rfE tests 2>&1 | tee "$OUT/pytest_final.log" | tail -15
