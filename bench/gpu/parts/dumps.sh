#!/usr/bin/env bash
# Issue 21's "behaviour bitwise unchanged" on CUDA: every mode's arrays, code before (.before/, a7331c6) and now.
if [ -d .before/warp_lamp ]; then
  PYTHONPATH="/root/site:$PWD/.before" python3 bench/experiments/mode_dump.py --device cuda:0 --out "$OUT/dump_before.npz"
fi
python3 bench/experiments/mode_dump.py --device cuda:0 --out "$OUT/dump_after.npz"
python3 bench/experiments/mode_dump.py --device cpu --out /tmp/dump_after_cpu.npz
echo "== before (CUDA) vs now (CUDA) =="; python3 bench/experiments/mode_dump.py --compare "$OUT/dump_before.npz" "$OUT/dump_after.npz" | tail -2
echo "== now: CPU vs CUDA =="; python3 bench/experiments/mode_dump.py --compare /tmp/dump_after_cpu.npz "$OUT/dump_after.npz" | tail -2
