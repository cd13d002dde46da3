#!/usr/bin/env bash
# One device lease: CUDA tests, the lamp benchmark, the fuse_fp measurement. Logs and JSON go to $OUT.
#   bash bench/gpu_session.sh        (after the stage-warp steps; PYTHONPATH must hold warp)
set -o pipefail
export PYTHONUNBUFFERED=1
OUT="${OUT:-/tmp/out}"
mkdir -p "$OUT"
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv | tee "$OUT/gpu.txt"
python3 -m pytest -q -p no:cacheprovider tests 2>&1 | tee "$OUT/pytest.log" | tail -15
WARP_LAMP_COMMIT="${WARP_LAMP_COMMIT:-unknown}" python3 -m warp_lamp bench --json "$OUT/bench.json" --no-progress 2>&1 | tee "$OUT/bench.log"
python3 bench/fuse_fp.py 2>&1 | tee "$OUT/fuse_fp.log"
echo "== summary =="
tail -3 "$OUT/pytest.log"
grep -E "^\| cuda" "$OUT/bench.log" | head -12
cat "$OUT/fuse_fp.log"
