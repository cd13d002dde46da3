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
  python3 - "$OUT/ncu-$kern.csv" <<'PY'
import csv, sys
keep = ("Duration", "Registers Per Thread", "Local Memory", "Achieved Occupancy", "Theoretical Occupancy",
        "Memory Throughput", "Compute (SM) Throughput", "Block Limit", "Warp Cycles Per Issued", "Stall",
        "Grid Size", "Block Size", "L1/TEX Hit", "L2 Hit", "DRAM Throughput")
try:
    rows = list(csv.DictReader(l for l in open(sys.argv[1]) if l.startswith('"')))
except Exception as e:
    print("no csv:", e); sys.exit(0)
for r in rows:
    name = r.get("Metric Name", "")
    if any(k in name for k in keep):
        print(f"  {r.get('Kernel Name','')[:28]:28s} {name[:60]:60s} {r.get('Metric Value','')} {r.get('Metric Unit','')}")
PY
  tail -2 "$OUT/ncu-$kern.err"
done
