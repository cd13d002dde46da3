#!/usr/bin/env bash
# The wetted surface on CUDA (issue 19, part 1): its tests on the GPU (kernels = reference, CPU = CUDA bitwise,
# graph capture), then the update's speed per stage (graph replay) on the SphereTest specimen, the 1M lattice box
# and the slot block, at rho = 0.25, 0.5 and 1 mean diameter, beside the first-surface lamp.
# Run from the repository root with warp installed and PYTHONPATH set; logs and JSON go to $OUT (default /tmp/out).
#   bash bench/gpu/parts/wetted.sh            # on the GPU machine
#   DEVICE=cpu QUICK=1 bash bench/gpu/parts/wetted.sh   # a CPU smoke run of the same steps (small scenes)
set -o pipefail
export PYTHONUNBUFFERED=1
OUT="${OUT:-/tmp/out}"
DEVICE="${DEVICE:-cuda:0}"
mkdir -p "$OUT"
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
if [ "$DEVICE" != "cpu" ]; then
  # The lease preamble: the GPU named, the carried test extras (scipy, for the reference) installed.
  source "$(dirname "${BASH_SOURCE[0]}")/../preamble.sh"
  # The CUDA cases of the wetted tests (the CPU ones ran on the dev machine).
  python3 -m pytest -q -p no:cacheprovider tests/test_wetted.py -k "cuda" 2>&1 | tee "$OUT/wetted-pytest.log" | tail -5
fi
if [ -n "$QUICK" ]; then
  python3 bench/experiments/wetted_bench.py --device "$DEVICE" --quick --repeats 2 --rho-diameters 0.5 \
    --out "$OUT/wetted.json" 2>&1 | tee "$OUT/wetted-bench.log"
else
  python3 bench/experiments/wetted_bench.py --device "$DEVICE" --rho-diameters 0.25 0.5 1.0 \
    --out "$OUT/wetted.json" 2>&1 | tee "$OUT/wetted-bench.log"
fi
echo "== summary =="
[ -f "$OUT/wetted-pytest.log" ] && tail -1 "$OUT/wetted-pytest.log"
python3 - "$OUT/wetted.json" <<'PY'
import json, sys
res = json.load(open(sys.argv[1]))
print(f"device {res['device']} {res.get('name', '')}, commit {res.get('commit')}")
stages = ["rasterize", "connect", "dilate", "classify", "cross", "thin"]
print("| scene | rho/d | first [ms] | all [ms] | " + " | ".join(stages) + " | uncertain | thin |")
for r in res["rows"]:
    total = r.get("all_replay_s", r.get("all_eager_s"))
    first = r.get("first_replay_s", r.get("first_eager_s"))
    st = " | ".join(f"{1e3 * r.get('all_' + s + '_s', float('nan')):.3f}" for s in stages)
    print(f"| {r['scene'][:28]} | {r['rho_over_d']:g} | {1e3 * first:.3f} | {1e3 * total:.3f} | {st} | "
          f"{r.get('uncertain', '')} | {r.get('thin', '')} |")
PY
