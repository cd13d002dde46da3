#!/usr/bin/env bash
# The benchmark CLI on this GPU (plot it here with --from-json: no matplotlib there): speed, small bodies, area, wetted and frames sections, JSON and plot.
WARP_LAMP_COMMIT="${WARP_LAMP_COMMIT:-unknown}" python3 -m warp_lamp bench --json "$OUT/bench.json" \
  --device "${BENCH_DEVICE:-cuda:0}" --no-progress > "$OUT/bench.txt" 2>&1
echo "rc=$?"; grep -E "^\| cuda" "$OUT/bench.txt" | head -60
