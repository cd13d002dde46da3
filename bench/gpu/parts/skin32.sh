#!/usr/bin/env bash
# The wetted surface's skin (dry decisions kept between updates) on one GPU, rho = rbar, 4 cells per diameter:
# the SphereTest specimen and the slot block; per scene the stage table from scratch and with the skin at rest
# (graph replay), the reset update, and a DEM-like run of 200 steps (random walk of 2e-4 rbar per step and
# coordinate, one particle jumping a mean radius every 50 steps) replayed as graphs with and without the skin,
# bitwise compared at every step (fluid words, counts, hits, per-ray crossings, the exact test's counters).
# Writes $OUT/skin32.json and $OUT/skin32.log; the table last. About 2-4 minutes on an H100, of which the exact
# test's module (kernels/wetted.py, changed by the skin) compiles for 1-2 minutes on a bare machine (NVRTC for sm_90
# took 111 s on the loaded 2-core dev machine: wp.compile_aot_module(warp_lamp.kernels.wetted, arch=90) builds it
# ahead, as the lease's kernel cache). SKIN32_ARGS adds arguments (e.g. "--only specimen" to halve the run).
LOG="$OUT/skin32.log"
: >"$LOG"
t0=$SECONDS
timeout 330 python3 bench/gpu/parts/skin32_run.py --device cuda:0 --out "$OUT/skin32.json" ${SKIN32_ARGS:-} \
  >>"$LOG" 2>&1
rc=$?
echo "skin32: rc $rc in $((SECONDS - t0)) s" | tee -a "$LOG"
tail -n 24 "$LOG"
