#!/usr/bin/env bash
# Lease: depth-pass A/B (v5d), and the helpers' branches (carried in .wt/) tested and timed on CUDA.
source "$(dirname "$0")/preamble.sh"
python3 bench/experiments/depth_blocks.py --json "$OUT/depth_blocks.json" 2>&1 | tee "$OUT/depth_blocks.log"
python3 bench/experiments/sphere_share.py --json "$OUT/sphere_share.json" 2>&1 | tee "$OUT/sphere_share.log"
echo "== before the refactor (.old) =="; (cd .old && PYTHONPATH=/root/site:$PWD python3 bench/gpu_iter.py 100)
echo "== after, v4 path =="; python3 bench/experiments/gpu_iter.py --v4 100
echo "== wetted branch =="
(cd .wt/wetted && PYTHONPATH=/root/site:$PWD python3 -m pytest -q -p no:cacheprovider tests/test_wetted.py 2>&1 | tail -4
 PYTHONPATH=/root/site:$PWD python3 bench/experiments/wetted_bench.py --device cuda:0 --out "$OUT/wetted.json" 2>&1 | tail -25)
echo "== area branch =="
(cd .wt/area && PYTHONPATH=/root/site:$PWD python3 -m pytest -q -p no:cacheprovider tests/test_area_kernel.py 2>&1 | tail -4)
