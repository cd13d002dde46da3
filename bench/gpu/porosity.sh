#!/usr/bin/env bash
# One device lease for porosity: the full porosity bench with the target scene and the paper's experiments.
source "$(dirname "$0")/preamble.sh"
WARP_LAMP_COMMIT="${WARP_LAMP_COMMIT:-unknown}" python3 -m warp_lamp bench porosity --target --paper \
  --json "$OUT/porosity.json" --no-progress 2>&1 | tee "$OUT/porosity.log"
echo "== summary =="
grep -E "^\| cuda|^Target" "$OUT/porosity.log"
