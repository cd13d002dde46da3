#!/usr/bin/env bash
# The drained triaxial test (10,000 particles) in the memo's mode and the wetted mode.
python3 examples/triaxial.py --device cuda:0 --time --json "$OUT/triaxial.json" --plot "$OUT/triaxial.png" 2>&1 \
  | grep -v "compression cycle" > "$OUT/triaxial.txt"; tail -12 "$OUT/triaxial.txt"
python3 examples/triaxial.py --device cuda:0 --surfaces all --time --json "$OUT/triaxial_all.json" \
  --plot "$OUT/triaxial_all.png" 2>&1 | grep -v "compression cycle" > "$OUT/triaxial_all.txt"; tail -12 "$OUT/triaxial_all.txt"
