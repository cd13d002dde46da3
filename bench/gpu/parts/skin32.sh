#!/usr/bin/env bash
# The wetted surface's skin (dry decisions kept between updates) on one GPU, rho = rbar, 4 cells per diameter:
# the SphereTest specimen and the slot block; per scene the stage table from scratch and with the skin at rest
# (graph replay), the reset update, and a DEM-like run of 200 steps (random walk of 2e-4 rbar per step and
# coordinate, one particle jumping a mean radius every 50 steps) replayed as graphs with and without the skin,
# bitwise compared at every step (fluid words, counts, hits, per-ray crossings, the exact test's counters).
# Writes $OUT/skin32.json and $OUT/skin32.log; the table last. About 2-4 minutes on an H100 (the wetted kernel
# module's compile included: ~1-1.5 min on a bare machine). SKIN32_ARGS adds arguments (e.g. "--only specimen").
LOG="$OUT/skin32.log"
: >"$LOG"
t0=$SECONDS
timeout 330 python3 bench/gpu/parts/skin32_run.py --device cuda:0 --out "$OUT/skin32.json" ${SKIN32_ARGS:-} \
  >>"$LOG" 2>&1
rc=$?
echo "skin32: rc $rc in $((SECONDS - t0)) s" | tee -a "$LOG"
tail -n 24 "$LOG"
