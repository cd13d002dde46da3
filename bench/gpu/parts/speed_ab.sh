#!/usr/bin/env bash
# Issue 22's A/B: stage times of the area and wetted passes beside criterion 1, and the variants under test.
python3 bench/experiments/speed_ab.py ${SPEED_AB_ARGS:---no-large} --json "$OUT/speed_ab.json" 2>&1 | tail -40
