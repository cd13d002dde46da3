#!/usr/bin/env bash
# Lease H: the benchmark CLI on CPU and CUDA (its specimen now packed on the CPU by default).
source "$(dirname "$0")/preamble.sh"
WARP_LAMP_COMMIT="${WARP_LAMP_COMMIT:-unknown}" python3 -m warp_lamp bench --json "$OUT/bench.json" \
  --plot "$OUT/bench_lamp.png" --no-progress > "$OUT/bench.log" 2>&1
echo "rc=$?"; grep -E "^\| cuda" "$OUT/bench.log" | head -60
