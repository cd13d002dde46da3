#!/usr/bin/env bash
# Lease G (specimens now packed on the CPU by default): the SphereTest at four resolutions and the triaxial test in
# both lamp modes, re-measured on the specimens a user gets.
source "$(dirname "$0")/preamble.sh"
python3 examples/sphere_test.py --device cuda:0 --steps 40000 --json "$OUT/sphere_test.json" 2>&1 \
  | grep -v "unbalanced ratio" | tee "$OUT/sphere_test.log" | tail -8
python3 examples/triaxial.py --device cuda:0 --time --json "$OUT/triaxial.json" --plot "$OUT/triaxial.png" 2>&1 \
  | grep -v "compression cycle" > "$OUT/triaxial.log"; tail -12 "$OUT/triaxial.log"
python3 examples/triaxial.py --device cuda:0 --surfaces all --time --json "$OUT/triaxial_all.json" \
  --plot "$OUT/triaxial_all.png" 2>&1 | grep -v "compression cycle" > "$OUT/triaxial_all.log"; tail -12 "$OUT/triaxial_all.log"
