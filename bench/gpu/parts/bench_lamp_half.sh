#!/usr/bin/env bash
# Half of warp-lamp bench (bench/experiments/bench_split.py --part $BENCH_PART: lamp or modes) on this GPU; merge
# the two halves' JSON afterwards with bench_split.py --merge and plot with warp-lamp bench --from-json.
part="${BENCH_PART:-lamp}"
timeout 560 python3 bench/experiments/bench_split.py --part "$part" --out "$OUT/bench_$part.json" 2>&1 \
  | grep -v "^Module\|^Warp\|^   CUDA\|^   Devices\|^     \"\|^   Kernel cache\|^     /" | tail -5
echo "rc=$? $(ls -la "$OUT/bench_$part.json" 2>/dev/null)"
