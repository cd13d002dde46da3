#!/usr/bin/env bash
# Issue 32: the exact test's reach masks by WetBox.mask_from (never, always, from 6 / 9 / 12 / 15 near spheres):
# classify in graph replay and the fluid hash per setting, specimen, slot block and 1M lattice (rho = r-bar).
(cd bench/experiments && timeout 400 python3 wetted_knobs.py --knob mask_from --device cuda:0 --repeats 20 --out "$OUT/mask_from.json") \
  2>&1 | grep -v "^Warp\|^   " | tail -20
