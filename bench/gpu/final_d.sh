#!/usr/bin/env bash
# Final lease, part D (after the triaxial capture fix): the triaxial tests and the full triaxial run on CUDA; the
# issue-8 replay of today's v4 path; the depth-pass A/B and the lamp's share of the SphereTest cycle.
source "$(dirname "$0")/preamble.sh"
python3 -m pytest -q -p no:cacheprovider tests/test_triaxial.py tests/test_catch_*.py 2>&1 | tee "$OUT/pytest_d.log" | tail -4
python3 examples/triaxial.py --device cuda:0 --time --json "$OUT/triaxial.json" --plot "$OUT/triaxial.png" 2>&1 \
  | grep -v "compression cycle" | tee "$OUT/triaxial.log" | tail -42
echo "== today, v4 path =="; python3 bench/experiments/gpu_iter.py --v4 100 2>&1 | tee -a "$OUT/replay.log"
python3 bench/experiments/depth_blocks.py --json "$OUT/depth_final.json" 2>&1 | tee "$OUT/depth_final.log" | tail -40
python3 bench/experiments/sphere_share.py --json "$OUT/sphere_share_final.json" 2>&1 | tee "$OUT/sphere_share.log" | tail -12
echo "== summary =="; tail -3 "$OUT/pytest_d.log"; grep "n=" "$OUT/replay.log"
