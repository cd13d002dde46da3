#!/usr/bin/env bash
# Walls in every mode: the walls' tests on CUDA and the CPU, then bench/experiments/walls_rule.py (the platen at
# rest and lifted, the single-sphere cases) on the GPU, compared with the CPU's committed results: they must be
# equal (float64 decisions, fuse_fp off, integer counts). About 1-2 minutes on one H100 (mostly compilation).
set -o pipefail
OUT="${OUT:-/tmp/out}"
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
{
  python3 -m pytest -q -p no:cacheprovider -rfEs tests/test_walls.py 2>&1 | tail -6
  python3 -m pytest -q -p no:cacheprovider -rfEs tests/test_distributed.py -k walls 2>&1 | tail -3
  python3 bench/experiments/walls_rule.py --device cuda:0 --out "$OUT/walls_rule.json" 2>&1 | grep "^|"
} > "$OUT/walls.log" 2>&1
python3 - "$OUT/walls_rule.json" bench/results/cpu-dev-2026-11-28-walls-rule.json <<'PY' | tee -a "$OUT/walls.log"
import json, sys
try:
    new, cpu = (json.load(open(p)) for p in sys.argv[1:3])
except Exception as e:  # the log above says why the run gave no JSON
    print(f"walls: no comparison ({e})")
    sys.exit(0)
print(f"device {new['name']}, commit {new['commit']}")
print("| lift / r | memo Fz / (-P A) | wetted Fz / (-P A) | forces = CPU's (memo, wetted) |")
print("| --- | --- | --- | --- |")
for a, b in zip(new["rows"], cpu["rows"]):
    same = [a[m]["fz"] == b[m]["fz"] and a[m]["wall_fz"] == b[m]["wall_fz"] for m in ("memo", "wetted")]
    print(f"| {a['lift_over_mean_radius']:g} | {a['memo']['ratio']:.4f} | {a['wetted']['ratio']:.4f} | {same} |")
same = all(x["got"] == y["got"] for x, y in zip(new["spheres"], cpu["spheres"]))
print(f"single-sphere cases equal to the CPU's: {same}")
PY
tail -40 "$OUT/walls.log"
