#!/usr/bin/env bash
# The drained triaxial test (10,000 particles) in the wetted mode only (issue 19's re-measure; about 90 s on an H100).
python3 examples/triaxial.py --device cuda:0 --surfaces all --time --json "$OUT/triaxial_all.json" 2>&1 \
  | grep -v "compression cycle" > "$OUT/triaxial_all.txt"; tail -14 "$OUT/triaxial_all.txt"
