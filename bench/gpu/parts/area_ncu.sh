#!/usr/bin/env bash
# Nsight Compute's source counters on the area criterion's cell pass (area_sides; specimen, sub-points D4 deep, 4 cells/d),
# modules built with line info: instructions executed and warp stalls per source line ($OUT/area_sides_source.csv).
NCU="$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)"
if [ -z "$NCU" ]; then echo "ncu: not found on this machine"; exit 0; fi
"$NCU" --version | tail -1
timeout 200 "$NCU" --target-processes all -k "regex:area_sides" --launch-skip 2 --launch-count 1 \
  --section SourceCounters --section WarpStateStats --section InstructionStats --section SpeedOfLight \
  --section LaunchStats --section Occupancy --import-source yes -f -o "$OUT/area_sides" \
  python3 bench/experiments/ncu_probe.py area --lineinfo > "$OUT/area_ncu.log" 2>&1
echo "ncu rc=$?"; tail -3 "$OUT/area_ncu.log"
"$NCU" --import "$OUT/area_sides.ncu-rep" --page details --csv > "$OUT/area_sides_details.csv" 2>&1
grep -E "Duration|Executed Instructions\"|Registers Per|Achieved Occ|Warp Cycles Per Issued|Issue Slots Busy|Stall" \
  "$OUT/area_sides_details.csv" | cut -c1-200 | head -30
for src in cuda sass; do
  "$NCU" --import "$OUT/area_sides.ncu-rep" --page source --csv --print-source "$src" > "$OUT/area_sides_source_$src.csv" 2>&1
  echo "source $src rc=$? lines=$(wc -l < "$OUT/area_sides_source_$src.csv")"; head -c 600 "$OUT/area_sides_source_$src.csv"; echo
done
