#!/usr/bin/env bash
# Issue 32: the queued exact tests as queued, sorted by voxel, and sorted by the fluid voxels around each: classify
# in graph replay and the fluid hash per order, specimen, slot block and 1M lattice (rho = r-bar).
(cd bench/experiments && timeout 400 python3 wetted_queue_order.py --device cuda:0 --repeats 20 --out "$OUT/queue_order.json") \
  2>&1 | grep -v "^Warp\|^   " | tail -20
