#!/usr/bin/env bash
# One device lease for porosity: every test on CPU and CUDA, then the full porosity bench with the target scene
# and the paper's experiments. Logs and JSON go to $OUT.
set -o pipefail
export PYTHONUNBUFFERED=1
OUT="${OUT:-/tmp/out}"
mkdir -p "$OUT"
nvidia-smi --query-gpu=name,driver_version --format=csv | tee "$OUT/gpu.txt"
python3 -m pytest -q -p no:cacheprovider tests 2>&1 | tee "$OUT/pytest.log" | tail -8
WARP_LAMP_COMMIT="${WARP_LAMP_COMMIT:-unknown}" python3 -m warp_lamp bench porosity --target --paper \
  --json "$OUT/porosity.json" --no-progress 2>&1 | tee "$OUT/porosity.log"
echo "== summary =="
tail -2 "$OUT/pytest.log"
grep -E "^\| cuda|^Target" "$OUT/porosity.log"
