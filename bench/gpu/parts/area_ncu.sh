#!/usr/bin/env bash
# Nsight Compute's source counters on one kernel (default: the area criterion's cell pass, area_sides; specimen,
# sub-points D4 deep, 4 cells/d; NCU_MODE=wetted NCU_KERNEL=wet_classify_queued for the wetted surface's exact tests):
# instructions executed and warp stalls per SASS instruction ($OUT/<kernel>_source_sass.csv).
NCU="$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)"
if [ -z "$NCU" ]; then echo "ncu: not found on this machine"; exit 0; fi
mode="${NCU_MODE:-area}"; kern="${NCU_KERNEL:-area_sides}"
"$NCU" --version | tail -1
timeout 200 "$NCU" --target-processes all -k "regex:$kern" --launch-skip 2 --launch-count 1 \
  --section SourceCounters --section WarpStateStats --section InstructionStats --section SpeedOfLight \
  --section LaunchStats --section Occupancy --import-source yes -f -o "$OUT/$kern" \
  python3 bench/experiments/ncu_probe.py "$mode" > "$OUT/${kern}_ncu.log" 2>&1
echo "ncu rc=$?"; tail -3 "$OUT/${kern}_ncu.log"
"$NCU" --import "$OUT/$kern.ncu-rep" --page details --csv > "$OUT/${kern}_details.csv" 2>&1
grep -E "Duration|Executed Instructions\"|Registers Per|Achieved Occ|Warp Cycles Per Issued" \
  "$OUT/${kern}_details.csv" | cut -c1-200 | head -30
"$NCU" --import "$OUT/$kern.ncu-rep" --page source --csv --print-source sass > "$OUT/${kern}_source_sass.csv" 2>&1
echo "source sass rc=$? lines=$(wc -l < "$OUT/${kern}_source_sass.csv")"
rm -f "$OUT/$kern.ncu-rep"
