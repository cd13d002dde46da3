#!/usr/bin/env bash
# Nsight Compute on the queued exact tests (specimen, 4 cells/d; NCU_MODE=area NCU_KERNEL=area_sides: the area
# criterion's cell pass): how many of a warp's 32 lanes each executed instruction runs for (SIMT efficiency), warps
# resident and eligible per scheduler, and the stall reasons.
NCU="$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)"
if [ -z "$NCU" ]; then echo "ncu: not found on this machine"; exit 0; fi
mode="${NCU_MODE:-wetted}"; kern="${NCU_KERNEL:-wet_classify_queued}"
timeout 200 "$NCU" --target-processes all -k "regex:$kern" --launch-skip 2 --launch-count 1 \
  --section WarpStateStats --section SchedulerStats --section InstructionStats --section Occupancy \
  --metrics smsp__thread_inst_executed_per_inst_executed.ratio,smsp__thread_inst_executed_pred_on_per_inst_executed.ratio,smsp__inst_executed.sum,gpu__time_duration.sum,smsp__warps_active.avg.per_cycle_active,smsp__warps_eligible.avg.per_cycle_active \
  --csv --page details python3 bench/experiments/ncu_probe.py "$mode" > "$OUT/ncu-div-$kern.csv" 2> "$OUT/ncu-div-$kern.err"
echo "== $kern rc=$?"
python3 bench/gpu/parts/ncu_table.py "$OUT/ncu-div-$kern.csv"
tail -2 "$OUT/ncu-div-$kern.err"
