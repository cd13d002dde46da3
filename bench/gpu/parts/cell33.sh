#!/usr/bin/env bash
# Area cell pass per cell vs per (lamp, cell), hidden rounds cold vs warm: same run, bitwise check, candidate table (~4 min).
# Specimen at 3 and 4 cells/d (sub-points D3, sub-points D4 deep, exact D4), criterion 1 at 4 and 32, the 1M lattice
# (criterion 1, sub-points D3, sub-points D4 deep); six variants per area row, graph replay, every variant's counts
# checked bitwise against the old code's ("old": one thread per cell, rounds from emptied slots). Then the speed-error
# table's times for this kind re-measured with the fastest variant ($OUT/cell33_table.json: the shipped table with this
# kind's times replaced; its "kinds" entry names the variant) and the area tests of both passes on every device.
# One JSON ($OUT/cell33.json); the lease writes $OUT/cell33.log. To ship the JSON's "faster_pass" variant: set
# AreaSplit.CELL_PASS / SUBPOINT_ROWS / HIDDEN_WARM (warp_lamp/estimators.py) as the table's kinds entry says, and
# cp cell33_table.json warp_lamp/data/speed_error.json
OUT="${OUT:-/tmp/out}"
mkdir -p "$OUT"
python3 bench/experiments/cell33_gpu.py --device "${CELL33_DEVICE:-cuda:0}" --json "$OUT/cell33.json" \
  --table "$OUT/cell33_table.json" --repeats 30 --budget 240 --tests-limit 150 2>&1 | grep -v "^Module " | tail -40
