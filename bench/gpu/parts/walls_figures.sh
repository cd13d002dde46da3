#!/usr/bin/env bash
# The platen and top-only figures on the GPU, compared with the CPU's committed ones (they must be equal: float64
# decisions, fuse_fp off, integer counts); the walls' CUDA tests run in the tests part.
DEVICE=cuda:0 python3 bench/experiments/wetted_walls.py --device cuda:0 --out "$OUT/wetwalls.json" > "$OUT/wetwalls.log" 2>&1
python3 - "$OUT/wetwalls.json" bench/results/cpu-dev-2026-11-25-walls.json <<'PY'
import json, sys
new, cpu = (json.load(open(p)) for p in sys.argv[1:3])
print("| case | mode | rho / r | Fz / (-P footprint) | update [ms] | forces = CPU's |")
for a, b in zip(new["rows"], cpu["rows"]):
    same = a["force"] == b["force"] and a.get("wall_forces") == b.get("wall_forces")
    k = a.get("rho_over_mean_radius") or ""
    print(f"| {a['case']} | {a['mode']} | {k} | {a['fz_over_minus_P_footprint']:.4f} | {1e3 * a['seconds']:.2f} | {same} |")
PY
