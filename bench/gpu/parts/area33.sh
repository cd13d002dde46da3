#!/usr/bin/env bash
# The area criterion against refinement: specimen and 1M-lattice rows with stage tables, the speed-error table's times for this GPU kind, the area and tolerance tests on CUDA (~5 min on one H100).
# One JSON ($OUT/area33.json: rows, stages, the merged speed-error table under "speed_error", tolerance='s
# choices, the tests' tail); the lease writes the log ($OUT/area33.log). The lead copies "speed_error" into
# warp_lamp/data/speed_error.json:
#   python3 -c "import json; t=json.load(open('area33.json'))['speed_error']; json.dump(t, open('warp_lamp/data/speed_error.json','w'), indent=1)"
OUT="${OUT:-/tmp/out}"
mkdir -p "$OUT"
python3 bench/experiments/area33_gpu.py --device "${AREA33_DEVICE:-cuda:0}" --json "$OUT/area33.json" \
  --repeats 30 --tests-limit 200 2>&1 | grep -v "^Module " | tail -45
