#!/usr/bin/env bash
# The speed-error table's rows added on the CPU (criterion 1 at 48 and 64 cells per diameter), timed on this GPU
# (merge_kind's missing_only: over criterion 1 at 4 timed again in the same run), then the table's choices checked
# here (errors measured on this device). Input: bench/results/experiments/speed_error_completed_cpu.json.
IN=bench/results/experiments/speed_error_completed_cpu.json
timeout 240 python3 -m warp_lamp.bench.tolerance --device cuda:0 --times-only --missing --merge "$IN" \
  --out "$OUT/speed_error_h200.json" 2>&1 | grep -v "^Module" | tail -34
timeout 240 python3 -m warp_lamp.bench.tolerance --check "$OUT/speed_error_h200.json" --device cuda:0 \
  --out "$OUT/tolerance_check_h200.json" 2>&1 | grep -v "^Module" | tail -12
