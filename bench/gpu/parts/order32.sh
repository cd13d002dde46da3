#!/usr/bin/env bash
# Issue 32: the queued exact tests in voxel order (the default) and as the first pass's atomics take them: classify
# in graph replay and the fluid hash per order, specimen, slot block and 1M lattice (rho = r-bar), twice.
(cd bench/experiments && timeout 400 python3 wetted_knobs.py --knob order --device cuda:0 --repeats 20 --out "$OUT/queue_order.json") \
  2>&1 | grep -v "^Warp\|^   " | tail -20
