#!/usr/bin/env bash
# Nsight Compute on the area cell pass and the wetted classification (specimen, 4 cells/d), where ncu is present.
NCU="$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)"
if [ -z "$NCU" ]; then echo "ncu: not found on this machine"; exit 0; fi
echo "ncu: $NCU"
for spec in "area:area_sides" "wetted:wet_classify"; do
  mode="${spec%%:*}"; kern="${spec#*:}"
  timeout 240 "$NCU" --target-processes all -k "regex:$kern" --launch-skip 2 --launch-count 1 \
    --section SpeedOfLight --section Occupancy --section LaunchStats --section WarpStateStats \
    --section MemoryWorkloadAnalysis --csv --page details \
    python3 bench/experiments/ncu_probe.py "$mode" > "$OUT/ncu-$mode.csv" 2> "$OUT/ncu-$mode.err"
  echo "$mode rc=$?"; grep -E "Duration|Registers|Local Memory|Achieved Occupancy|Theoretical Occupancy|Memory Throughput|Compute \(SM\) Throughput|Stall|Block Limit|Warp Cycles Per Issued" "$OUT/ncu-$mode.csv" | cut -c1-220 | head -40
  tail -3 "$OUT/ncu-$mode.err"
done
