#!/usr/bin/env bash
# Issue 32, after a change to the exact test: the wetted, walls and skin CUDA tests, then the bench and test scenes'
# hashes (bench/experiments/wetted32.py hashes), on this tree.
source bench/gpu/parts/wetted_cuda_tests.sh
source bench/gpu/parts/skin_tests.sh
timeout 120 python3 bench/experiments/wetted32.py hashes --device cuda:0 --out "$OUT/hashes.json" 2>&1 | tail -4
