#!/usr/bin/env bash
# One device lease: CUDA tests, the lamp benchmark. Logs and JSON go to $OUT.
source "$(dirname "$0")/preamble.sh"
python3 -m pytest -q -p no:cacheprovider tests 2>&1 | tee "$OUT/pytest.log" | tail -15
WARP_LAMP_COMMIT="${WARP_LAMP_COMMIT:-unknown}" python3 -m warp_lamp bench --json "$OUT/bench.json" --no-progress 2>&1 | tee "$OUT/bench.log"
echo "== summary =="
tail -3 "$OUT/pytest.log"
grep -E "^\| cuda" "$OUT/bench.log" | head -12
