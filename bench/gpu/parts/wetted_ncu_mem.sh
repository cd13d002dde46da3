#!/usr/bin/env bash
# Nsight Compute on the queued exact tests (wet_classify_queued), specimen and 1M lattice (rho = r-bar): where the
# time goes in memory: local (the frame: spills and local vectors) against global bytes, L1 hit rates, stall reasons.
# NCU_TREES ("tag:dir ...", dir "." this tree, else a carried `git archive` of warp_lamp) and NCU_SCENES choose.
NCU="$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)"
if [ -z "$NCU" ]; then echo "ncu: not found on this machine"; exit 0; fi
for tree in ${NCU_TREES:-here:.}; do
tag="${tree%%:*}"; dir="${tree#*:}"; pp="/root/site:$PWD"; [ "$dir" != "." ] && pp="$PWD/$dir:/root/site"
for scene in ${NCU_SCENES:-specimen lattice}; do
  PYTHONPATH="$pp" timeout 240 "$NCU" --target-processes all -k "regex:wet_classify_queued" --launch-skip 2 --launch-count 1 \
    --section MemoryWorkloadAnalysis --section MemoryWorkloadAnalysis_Tables --section WarpStateStats --section LaunchStats \
    --metrics gpu__time_duration.sum,smsp__inst_executed.sum,l1tex__t_bytes_pipe_lsu_mem_local_op_ld.sum,l1tex__t_bytes_pipe_lsu_mem_local_op_st.sum,l1tex__t_bytes_pipe_lsu_mem_global_op_ld.sum,l1tex__t_bytes_pipe_lsu_mem_global_op_st.sum,smsp__thread_inst_executed_per_inst_executed.ratio \
    --csv --page details python3 bench/experiments/ncu_probe.py wetted --updates 3 --scene $scene \
    > "$OUT/ncu-mem-$tag-$scene.csv" 2> "$OUT/ncu-mem-$tag-$scene.err"
  echo "== $tag $scene rc=$?"
  python3 bench/gpu/parts/ncu_table.py "$OUT/ncu-mem-$tag-$scene.csv" time local global Hit Stall Registers Stack \
    Throughput inst_executed Local thread_inst "Warp Cycles"
  tail -2 "$OUT/ncu-mem-$tag-$scene.err"
done
done
