#!/usr/bin/env bash
# Lease E: the area criterion's stages; the triaxial tests (both lamp modes) and the full triaxial run in the
# wetted mode, beside part D's run in the memo's mode.
source "$(dirname "$0")/preamble.sh"
python3 bench/experiments/area_stages.py --json "$OUT/area_stages.json" 2>&1 | tee "$OUT/area_stages.log"
python3 -m pytest -q -p no:cacheprovider tests/test_triaxial.py 2>&1 | tail -3
python3 examples/triaxial.py --device cuda:0 --surfaces all --time --json "$OUT/triaxial_all.json" \
  --plot "$OUT/triaxial_all.png" 2>&1 | grep -v "compression cycle" > "$OUT/triaxial_all.log"; tail -40 "$OUT/triaxial_all.log"
