#!/usr/bin/env bash
# Issue 8/11 lease: CUDA tests, the depth-pass A/B, the lamp's share of a DEM cycle, and the replay of the code
# before the refactor (carried in .old/) against today's, in one run. Logs and JSON go to $OUT.
source "$(dirname "$0")/preamble.sh"
[ -n "${SKIP_TESTS:-}" ] || python3 -m pytest -q -p no:cacheprovider -x tests 2>&1 | tee "$OUT/pytest.log" | tail -4
python3 bench/experiments/depth_blocks.py --json "$OUT/depth_blocks.json" 2>&1 | tee "$OUT/depth_blocks.log"
python3 bench/experiments/sphere_share.py --json "$OUT/sphere_share.json" 2>&1 | tee "$OUT/sphere_share.log"
if [ -d .old ]; then
  echo "== before the refactor (.old) =="; (cd .old && PYTHONPATH=/root/site:$PWD python3 bench/gpu_iter.py 100)
fi
echo "== after, v4 path =="; python3 bench/experiments/gpu_iter.py --v4 100
echo "== after, default =="; python3 bench/experiments/gpu_iter.py 100
[ -f "$OUT/pytest.log" ] && tail -2 "$OUT/pytest.log"
