#!/usr/bin/env bash
# Issue 32: the bench and test scenes' hashes alone (bench/experiments/wetted32.py hashes), on this tree.
timeout 120 python3 bench/experiments/wetted32.py hashes --device cuda:0 --out "$OUT/hashes.json" 2>&1 | tail -4
