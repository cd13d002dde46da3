#!/usr/bin/env bash
# Final lease, part A: every test on CPU and CUDA; issue 8's replay before the restructuring (.old, 76c0320), right
# after it (.refactor, e9f6e68) and today, one run; the depth-pass A/B and the lamp's share of the SphereTest cycle.
source "$(dirname "$0")/preamble.sh"
python3 -m pytest -q -p no:cacheprovider tests 2>&1 | tee "$OUT/pytest.log" | tail -6
echo "== 76c0320 =="; (cd .old && PYTHONPATH=/root/site:$PWD python3 bench/gpu_iter.py 100) 2>&1 | tee "$OUT/replay.log"
echo "== e9f6e68 =="; (cd .refactor && PYTHONPATH=/root/site:$PWD python3 bench/experiments/gpu_iter.py 100) 2>&1 | tee -a "$OUT/replay.log"
echo "== today, v4 path =="; python3 bench/experiments/gpu_iter.py --v4 100 2>&1 | tee -a "$OUT/replay.log"
echo "== today, default =="; python3 bench/experiments/gpu_iter.py 100 2>&1 | tee -a "$OUT/replay.log"
python3 bench/experiments/depth_blocks.py --json "$OUT/depth_final.json" 2>&1 | tee "$OUT/depth_final.log"
python3 bench/experiments/sphere_share.py --json "$OUT/sphere_share_final.json" 2>&1 | tee "$OUT/sphere_share.log"
echo "== summary =="; tail -3 "$OUT/pytest.log"; cat "$OUT/replay.log" | grep "n="
