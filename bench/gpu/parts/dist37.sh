#!/usr/bin/env bash
# The distributed lamp's reach on every GPU the machine has (4 on nvidia-h100-x4, else 2): strong and weak scaling.
# One launch (torchrun, one process per GPU; NCCL through CuPy) runs everything, each run on the first k GPUs:
#   1. A one-rank warm-up at tiny sizes, alone: compiles every kernel the run needs (lamp, distributed, area,
#      porosity; not the wetted module) once, so that the ranks then load them from the cache.
#   2. bench/gpu/parts/dist37_run.py on all G GPUs: ShiningLamp 27M on one GPU (the baseline, same run, same card);
#      27M in x-slabs on 1, 2, 4 GPUs (strong); 27M per GPU side by side, up to 108M on 4 (weak); the area
#      criterion (8M) and porosity (1M, voxel and exact) across all G; each run bitwise against ShiningLamp on the
#      whole body on each rank's GPU (108M fits one H100: ~8 GB), and the reach's escape count.
# Writes $OUT/dist37.json (copy it to bench/results/<card>-x<G>-<date>-distributed.json); its output is the log
# (lease.sh keeps it as $OUT/dist37.log); prints the table last. About 2-4 minutes (plus ~2 minutes of compiling on a bare machine); DIST37_TIMEOUT caps it.
# NVLink multicast stays off: NCCL_NVLS_ENABLE=0 as the machine sets it (never overridden here).
: "${NCCL_NVLS_ENABLE:=0}"
export NCCL_NVLS_ENABLE TORCH_SYMM_MEM_DISABLE_MULTICAST=1 NVSHMEM_DISABLE_NVLS=1
RUN="python3 -m torch.distributed.run --standalone"
PART=bench/gpu/parts/dist37_run.py
G=$(python3 -c "import torch; print(torch.cuda.device_count())" 2>/dev/null || nvidia-smi -L | wc -l)
{
  echo "GPUs: $G, NCCL_NVLS_ENABLE=$NCCL_NVLS_ENABLE"
  nvidia-smi topo -m
  python3 -c "import cupy; from cupy.cuda import nccl; print('cupy', cupy.__version__, 'nccl', nccl.get_version() if nccl.available else 'missing')"
} 2>&1
t0=$(date +%s)
timeout 240 $RUN --nproc_per_node=1 $PART --n 16 --area-n 8 --porosity-n 8 --repeats 2 --out /tmp/dist37-warm.json 2>&1
rc=$?
echo "warm-up (compile): $(( $(date +%s) - t0 )) s, exit $rc"
timeout "${DIST37_TIMEOUT:-300}" $RUN --nproc_per_node="$G" $PART --out "$OUT/dist37.json" ${DIST37_ARGS:-} 2>&1
rc=$?
echo "run: exit $rc after $(( $(date +%s) - t0 )) s"
# The table (the run prints it last; printed again from the JSON in case the run was cut short).
python3 - "$OUT/dist37.json" <<'PY' 2>&1
import json, sys
sys.path.insert(0, "bench/gpu/parts")
from dist37_run import print_table
try:
    print_table(json.load(open(sys.argv[1])))
except Exception as e:
    print("no table:", type(e).__name__, e)
PY
