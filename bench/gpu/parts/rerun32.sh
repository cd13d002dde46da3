#!/usr/bin/env bash
# After a lease whose CUDA tests timed out compiling: the named tests again (RERUN_TESTS, space-separated node ids),
# the skin's CUDA tests and the hash scenes, with the carried kernel cache (PTX for this driver).
python3 -m pytest -q -p no:cacheprovider -rfEs ${RERUN_TESTS:-} 2>&1 | tee "$OUT/pytest_rerun.log" | tail -6
python3 -m pytest -q -p no:cacheprovider -rfEs -k cuda tests/test_wetted_skin.py 2>&1 | tail -3
timeout 150 python3 bench/experiments/wetted32.py hashes --device cuda:0 --out "$OUT/hashes.json" 2>&1 | tail -4
