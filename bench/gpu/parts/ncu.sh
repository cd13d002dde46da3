#!/usr/bin/env bash
# Nsight Compute on the wetted stages' kernels (specimen, 4 cells/d; area_sides with the area mode), where ncu is present.
NCU="$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)"
if [ -z "$NCU" ]; then echo "ncu: not found on this machine"; exit 0; fi
echo "ncu: $NCU"
for spec in "wetted:wet_classify_queued" "wetted:wet_cross_listed" "wetted:wet_thin" "wetted:wet_expose"; do
  mode="${spec%%:*}"; kern="${spec#*:}"
  timeout 150 "$NCU" --target-processes all -k "regex:$kern" --launch-skip 2 --launch-count 1 \
    --section SpeedOfLight --section Occupancy --section LaunchStats --section WarpStateStats \
    --section MemoryWorkloadAnalysis --csv --page details \
    python3 bench/experiments/ncu_probe.py "$mode" > "$OUT/ncu-$kern.csv" 2> "$OUT/ncu-$kern.err"
  echo "== $kern rc=$?"
  python3 bench/gpu/parts/ncu_table.py "$OUT/ncu-$kern.csv" Duration "Registers Per Thread" "Local Memory" \
    "Achieved Occupancy" "Theoretical Occupancy" "Memory Throughput" "Compute (SM) Throughput" "Block Limit" \
    "Warp Cycles Per Issued" Stall "Grid Size" "Block Size" "L1/TEX Hit" "L2 Hit" "DRAM Throughput"
  tail -2 "$OUT/ncu-$kern.err"
done
