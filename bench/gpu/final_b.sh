#!/usr/bin/env bash
# Final lease, part B: the full lamp benchmark on every device (its JSON and plot), and the porosity benchmark.
source "$(dirname "$0")/preamble.sh"
WARP_LAMP_COMMIT="${WARP_LAMP_COMMIT:-unknown}" python3 -m warp_lamp bench --json "$OUT/bench.json" \
  --plot "$OUT/bench_lamp.png" --no-progress 2>&1 | tee "$OUT/bench.log"
echo "== summary =="; grep -E "^\| cuda" "$OUT/bench.log" | head -40
