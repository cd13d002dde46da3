#!/usr/bin/env bash
# The wetted surface's skin in the rock-cutting example: 400 lamp updates of a shortened cut, each compared bitwise with a from-scratch lamp, then the cycle's lamp share mid-cut (skin on / off).
# bench/experiments/skin_rockcut.py on the study's slab (about 4,900 particles, 2.5M voxels), the cutter at one mean
# diameter per 300 cycles so that the cut starts within the run; writes $OUT/skinrock.json, the log is the lease's
# $OUT/skinrock.log. About 2-3 minutes on an H100 (the DEM's modules compile on a bare machine).
python3 bench/experiments/skin_rockcut.py --device cuda:0 --updates 400 --out "$OUT/skinrock.json" ${SKINROCK_ARGS:-} 2>&1 \
  | grep -v "^Module "
