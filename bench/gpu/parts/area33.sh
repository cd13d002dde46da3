#!/usr/bin/env bash
# Area criterion vs refinement: specimen and 1M rows with stages, speed-error times, area/tolerance tests (~5 min).
# Rows: criterion 1 at 4/16/32, sub-points D3 at 3/4, exact D4, and the new gathers (hidden rounds, both lamps).
# One JSON ($OUT/area33.json: rows, stages, the merged speed-error table under "speed_error", tolerance='s
# choices, the tests' tail); the lease writes the log ($OUT/area33.log). The lead copies "speed_error" into
# warp_lamp/data/speed_error.json:
#   python3 -c "import json; t=json.load(open('area33.json'))['speed_error']; json.dump(t, open('warp_lamp/data/speed_error.json','w'), indent=1)"
OUT="${OUT:-/tmp/out}"
mkdir -p "$OUT"
python3 bench/experiments/area33_gpu.py --device "${AREA33_DEVICE:-cuda:0}" --json "$OUT/area33.json" \
  --repeats 30 --tests-limit 200 2>&1 | grep -v "^Module " | tail -45
