#!/usr/bin/env bash
# Lease: depth-pass A/B (v5e: literal axes, single-slot specialisation, culling back with literal axes).
source "$(dirname "$0")/preamble.sh"
python3 bench/experiments/depth_blocks.py --json "$OUT/depth_blocks.json" 2>&1 | tee "$OUT/depth_blocks.log"
python3 bench/experiments/sphere_share.py --cells 4 16 --json "$OUT/sphere_share.json" 2>&1 | tee "$OUT/sphere_share.log"
echo "== before the refactor (.old) =="; (cd .old && PYTHONPATH=/root/site:$PWD python3 bench/gpu_iter.py 100)
echo "== after, v4 path =="; python3 bench/experiments/gpu_iter.py --v4 100
