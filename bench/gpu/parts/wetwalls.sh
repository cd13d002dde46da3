#!/usr/bin/env bash
# Walls that bound the fluid in the wetted mode (issue 19, part 2) on CUDA: the CUDA cases of tests/test_walls.py and
# tests/test_wetted.py (kernels = reference with walls, CPU = CUDA bitwise with walls, graph replay after moving a
# wall), then the platen and top-only figures on the GPU, compared with the CPU's committed ones (they must be equal:
# every decision is float64 with fuse_fp off, the counts are integers).
# Run from the repository root with warp installed and PYTHONPATH set; logs and JSON go to $OUT (default /tmp/out).
#   bash bench/gpu/parts/wetwalls.sh                 # on the GPU machine (a few minutes at most)
#   DEVICE=cpu bash bench/gpu/parts/wetwalls.sh      # a CPU smoke run of the figures (no tests)
set -o pipefail
export PYTHONUNBUFFERED=1
OUT="${OUT:-/tmp/out}"
DEVICE="${DEVICE:-cuda:0}"
mkdir -p "$OUT"
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
if [ "$DEVICE" != "cpu" ]; then
  source "$(dirname "$0")/../preamble.sh"
  timeout 420 python3 -m pytest -q -p no:cacheprovider -rfE -k cuda tests/test_walls.py tests/test_wetted.py 2>&1 \
    | tee "$OUT/wetwalls-pytest.log" | tail -8
fi
python3 bench/experiments/wetted_walls.py --device "$DEVICE" --out "$OUT/wetwalls.json" 2>&1 | tee "$OUT/wetwalls.log"
echo "== summary =="
[ -f "$OUT/wetwalls-pytest.log" ] && tail -1 "$OUT/wetwalls-pytest.log"
python3 - "$OUT/wetwalls.json" bench/results/cpu-dev-2026-11-25-walls.json <<'PY'
import json, sys
new, cpu = (json.load(open(p)) for p in sys.argv[1:3])
print(f"device {new['device']} {new['name']}, commit {new['commit']} (CPU figures: commit {cpu['commit']})")
print("| case | mode | rho / r | Fz / (-P footprint) | update [ms] | forces = CPU's |")
for a, b in zip(new["rows"], cpu["rows"]):
    same = a["force"] == b["force"] and a.get("wall_forces") == b.get("wall_forces")
    k = a.get("rho_over_mean_radius") or ""
    print(f"| {a['case']} | {a['mode']} | {k} | {a['fz_over_minus_P_footprint']:.4f} | {1e3 * a['seconds']:.2f} | {same} |")
PY
