#!/usr/bin/env bash
# Every test on the CPU and on CUDA (the CUDA-only tests run here and nowhere else).
python3 -m pytest -q -p no:cacheprovider -rfE tests 2>&1 | tee "$OUT/pytest.log" | tail -15
