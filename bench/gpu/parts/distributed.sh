#!/usr/bin/env bash
# Issue 23 on the 2-GPU kind (nvidia-h100-x2): the distributed lamp over NCCL, one process per GPU, started by
# torchrun (python3 -m torch.distributed.run; no MPI there). Needs warp staged (../shared/gpu/README.md) and nothing
# else: torch and cupy-cuda13x are on the machine; CuPy's NCCL is the capturable path, torch.distributed the fallback.
#   1. tests/test_distributed.py on CUDA (one rank: CUDA graphs of the update; torch Gloo).
#   2. One GPU: ShiningLamp and a one-rank DistributedLamp on the 8M, 27M and 13.5M lattice boxes.
#   3. Two GPUs: the 8M and 27M boxes in x-slabs (and the 8M box split at random): update replay and eager, its
#      steps, the all-reduce alone, each rank's counts bitwise against ShiningLamp; then every correctness case on
#      CUDA over CuPy NCCL and over torch NCCL.
#   4. Two GPUs: whether torch.distributed records into a Warp graph (its own run, last).
# Writes $OUT/h100-x2-distributed.json (copy it to bench/results/h100-x2-<date>-distributed.json) and prints a table.
# Run through bench/gpu/lease.sh (which sources the preamble): bash bench/gpu/lease.sh distributed
# NVLink multicast stays off (the device README): NCCL's NVLS, torch's symmetric memory, NVSHMEM.
export NCCL_NVLS_ENABLE=0 TORCH_SYMM_MEM_DISABLE_MULTICAST=1 NVSHMEM_DISABLE_NVLS=1
RUN="python3 -m torch.distributed.run --standalone"
PART=bench/gpu/parts/distributed_run.py
{
  nvidia-smi topo -m
  python3 -c "import torch, cupy; from cupy.cuda import nccl; print('torch', torch.__version__, 'cupy', cupy.__version__, 'nccl', nccl.get_version() if nccl.available else 'missing')"
} 2>&1 | tee "$OUT/run.log"
python3 -m pytest -q -p no:cacheprovider tests/test_distributed.py 2>&1 | tee "$OUT/pytest.log" | tail -4
timeout "${DIST_TIMEOUT:-300}" $RUN --nproc_per_node=1 $PART run --out "$OUT/ranks1.json" 2>&1 | tee -a "$OUT/run.log"
# Timings and the checks in separate runs: a rank that failed inside a collective would leave the other waiting.
timeout "${DIST_TIMEOUT:-300}" $RUN --nproc_per_node=2 $PART run --part scale --out "$OUT/ranks2.json" 2>&1 | tee -a "$OUT/run.log"
timeout "${DIST_TIMEOUT:-300}" $RUN --nproc_per_node=2 $PART run --part checks --out "$OUT/checks2.json" 2>&1 | tee -a "$OUT/run.log"
timeout 120 $RUN --nproc_per_node=2 $PART capture --out "$OUT/capture.json" 2>&1 | tee -a "$OUT/run.log"
echo "== summary =="
tail -1 "$OUT/pytest.log"
python3 $PART table "$OUT/ranks1.json" "$OUT/ranks2.json" "$OUT/checks2.json" "$OUT/capture.json" \
  --json "$OUT/h100-x2-distributed.json" 2>&1 | tee -a "$OUT/run.log"
