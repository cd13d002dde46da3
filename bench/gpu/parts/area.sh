#!/usr/bin/env bash
# Issue 19, the area criterion on overlapping spheres: the area tests (CUDA and CPU), then the benchmark's area
# section on the GPU (specimen at 2/3/4 cells/d, criterion 1 to 32, the overlapping ball, the lone sphere, the 1M
# lattice box). About 3-4 minutes on one H100. Logs and JSON in $OUT. On a machine without a GPU:
#   AREA_DEVICE=cpu bash bench/gpu/parts/area.sh   (criterion 1 to 16, no lattice box)
set -o pipefail
OUT="${OUT:-/tmp/out}"
DEVICE="${AREA_DEVICE:-cuda:0}"
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
if command -v nvidia-smi >/dev/null; then
  nvidia-smi --query-gpu=name,driver_version --format=csv | tee "$OUT/area_gpu.txt"
fi
python3 -m pytest -q -p no:cacheprovider -rfEs tests/test_area.py tests/test_area.py 2>&1 \
  | tee "$OUT/area_pytest.log" | tail -8
LARGE=""
if [[ "$DEVICE" == cuda* ]]; then LARGE="--large"; fi
python3 bench/run_area_section.py --device "$DEVICE" $LARGE --json "$OUT/area_section.json" 2>&1 \
  | tee "$OUT/area_section.log" | tail -60
