#!/usr/bin/env bash
# Issue 21's rebuild alone on CUDA: every mode's arrays at a7331c6 (.before/) and at the rebuild's commit 719cb10 (.mid/).
PYTHONPATH="/root/site:$PWD/.before" python3 bench/experiments/mode_dump.py --device cuda:0 --out "$OUT/dump_a7331c6.npz"
PYTHONPATH="/root/site:$PWD/.mid" python3 bench/experiments/mode_dump.py --device cuda:0 --out "$OUT/dump_719cb10.npz"
echo "== a7331c6 (CUDA) vs 719cb10 (CUDA) =="
python3 bench/experiments/mode_dump.py --compare "$OUT/dump_a7331c6.npz" "$OUT/dump_719cb10.npz" | tail -3
