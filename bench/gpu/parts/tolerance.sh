#!/usr/bin/env bash
# tolerance='s speed-error table: this GPU's times merged into the package's table (errors are the CPU's).
python3 -m warp_lamp.bench.tolerance --device cuda:0 --times-only --merge warp_lamp/data/speed_error.json \
  --out "$OUT/speed_error.json" 2>&1 | tail -25
