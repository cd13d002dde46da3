#!/usr/bin/env bash
# Nsight Compute's per-instruction counters on the queued exact tests (specimen; NCU_SCENE=lattice: the 1M lattice
# box). The device's module carries no line info, so the report is mapped to functions and Python statements on the
# dev machine: bench/experiments/ncu_source_lines.py, with a lineinfo build of the same module. Writes
# $OUT/src_<scene>_details.csv and src_<scene>_sass.csv.gz (per instruction).
NCU="$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)"
if [ -z "$NCU" ]; then echo "ncu: not found on this machine"; exit 0; fi
scene="${NCU_SCENE:-specimen}"; kern=wet_classify_queued; tag="src_$scene"
timeout 400 "$NCU" --target-processes all -k "regex:$kern" --launch-skip 2 --launch-count 1 \
  --section SourceCounters --section WarpStateStats --section InstructionStats --section LaunchStats \
  -f -o "$OUT/$tag" python3 bench/experiments/ncu_probe.py wetted --updates 4 --scene "$scene" > "$OUT/${tag}_ncu.log" 2>&1
echo "ncu rc=$?"; tail -3 "$OUT/${tag}_ncu.log"
"$NCU" --import "$OUT/$tag.ncu-rep" --page details --csv > "$OUT/${tag}_details.csv" 2>&1
grep -E "Duration|Executed Instructions\"|Warp Cycles Per Issued" "$OUT/${tag}_details.csv" | cut -c1-200 | head
"$NCU" --import "$OUT/$tag.ncu-rep" --page source --csv --print-source sass > "$OUT/${tag}_sass.csv" 2>&1
echo "sass rc=$? lines=$(wc -l < "$OUT/${tag}_sass.csv")"
gzip -f "$OUT/${tag}_sass.csv"; rm -f "$OUT/$tag.ncu-rep"
