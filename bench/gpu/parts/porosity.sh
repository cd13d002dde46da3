#!/usr/bin/env bash
# The porosity benchmark with the target scene and the paper's experiments.
WARP_LAMP_COMMIT="${WARP_LAMP_COMMIT:-unknown}" python3 -m warp_lamp bench porosity --target --paper \
  --json "$OUT/porosity.json" --no-progress 2>&1 | grep -E "^\| cuda|^Target"
