"""Issue 32's lease part, Python side: bitwise hashes of the wetted surface on the bench and test scenes (run once
with the code before and once with the code after, on one device), and the combined result file and table.

    PYTHONPATH=$PWD python bench/experiments/wetted32.py hashes --device cpu --quick --out /tmp/h.json
    python bench/experiments/wetted32.py combine --before-bench b.json --after-bench a.json \
        --before-hashes hb.json --after-hashes ha.json --out wetted32.json
"""

import argparse
import hashlib
import json
import sys

import numpy as np


def _cases(quick):
    from warp_lamp.scenes import scene_lattice_ball, scene_lattice_box, scene_slot_block, scene_sphere_specimen

    rng = np.random.default_rng(2111)
    c = rng.uniform(0.0, 5.0, (300, 3))
    r = rng.uniform(0.2, 0.6, 300)
    out = [("poly", c, r, 0.2, rho) for rho in (0.0, 0.1, 0.3, 0.7)]
    ball = scene_lattice_ball(diameter=0.05, particle_diameter=0.005)
    for f in (0.25, 0.5, 1.0):
        out.append(("ball", ball.centers, ball.radii, None, f * 2 * float(ball.radii.mean())))
    if quick:
        box = scene_lattice_box(8)
        out.append(("lattice8", box.centers, box.radii, 0.25, 0.45))
        return out
    spec = scene_sphere_specimen()
    slot = scene_slot_block()
    for f in (0.25, 0.5, 1.0):
        out.append(("specimen", spec.centers, spec.radii, None, f * 2 * float(spec.radii.mean())))
    out.append(("slot", slot.centers, slot.radii, None, float(slot.radii.mean())))
    return out


def hashes(args):
    import warp as wp

    import warp_lamp as wl
    from warp_lamp.wetted import WettedSurface

    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    device = wp.get_device(args.device)
    rows = []
    for name, c, r, cell, rho in _cases(args.quick):
        if cell is None:
            grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4, margin=2.0 * float(r.mean()) + rho)
        else:
            grid = wl.LampGrid(c.min(axis=0) - r.max() - cell - rho, c.max(axis=0) + r.max() + cell + rho, cell)
        surf = WettedSurface(grid, probe_radius=rho, device=device)
        pos = wp.array((c - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
        rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
        surf.update(pos, rad)
        d = surf.diagnostics()
        h = hashlib.sha1(surf.fluid.numpy().tobytes() + surf.counts_numpy().tobytes() + surf.rays.numpy().tobytes())
        rows.append(
            dict(case=f"{name} rho={rho:.6g}", hash=h.hexdigest(), tested=int(d.uncertain), rescued=int(d.rescued))
        )
        print(f"{rows[-1]['case']}: {rows[-1]['hash'][:12]} tested {d.uncertain} rescued {d.rescued}", flush=True)
    with open(args.out, "w") as f:
        json.dump({"device": str(device), "name": getattr(device, "name", ""), "rows": rows}, f, indent=1)


def _load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        print(f"missing {path}: {e}", file=sys.stderr)
        return None


def combine(args):
    bb, ab = _load(args.before_bench), _load(args.after_bench)
    bh, ah = _load(args.before_hashes), _load(args.after_hashes)
    result = {"issue": 32, "before_bench": bb, "after_bench": ab, "before_hashes": bh, "after_hashes": ah}
    same = None
    if bh and ah:
        hb = {r["case"]: r["hash"] for r in bh["rows"]}
        ha = {r["case"]: r["hash"] for r in ah["rows"]}
        same = {k: hb[k] == ha.get(k) for k in hb}
        result["bitwise"] = same
    with open(args.out, "w") as f:
        json.dump(result, f, indent=1)
    print("== issue 32: wetted surface before (4149365) and after, same card, graph replay ==")
    if bb and ab:
        print(f"device: {ab.get('name', '')} ({ab.get('device')})")
        stages = ["rasterize", "connect", "dilate", "classify", "cross", "thin"]
        print(f"{'scene':10s} {'rho/d':>5s} {'':6s} {'total':>8s} " + " ".join(f"{s[:8]:>8s}" for s in stages))
        after = {(r["scene"], r["rho_over_d"]): r for r in ab["rows"]}
        for r in bb["rows"]:
            a = after.get((r["scene"], r["rho_over_d"]))
            for tag, row in (("before", r), ("after", a)):
                if row is None or ("all_replay_s" not in row and "all_eager_s" not in row):
                    continue
                tot = row.get("all_replay_s", row.get("all_eager_s"))
                st = " ".join(f"{row.get(f'all_{s}_s', float('nan')) * 1e3:8.3f}" for s in stages)
                print(f"{r['scene'][:10]:10s} {r['rho_over_d']:5.2f} {tag:6s} {tot * 1e3:8.3f} {st}")
            if a is not None:
                print(f"{'':10s} {'':5s} hash   {'same' if r['fluid_hash'] == a['fluid_hash'] else 'DIFFERENT'}")
    if same is not None:
        print(
            f"bitwise cases: {sum(same.values())} of {len(same)} equal"
            + "".join(f"\n  DIFFERENT: {k}" for k, v in same.items() if not v)
        )


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    h = sub.add_parser("hashes")
    h.add_argument("--device", default=None)
    h.add_argument("--quick", action="store_true")
    h.add_argument("--out", required=True)
    c = sub.add_parser("combine")
    for k in ("before-bench", "after-bench", "before-hashes", "after-hashes", "out"):
        c.add_argument(f"--{k}", required=True)
    args = ap.parse_args()
    hashes(args) if args.cmd == "hashes" else combine(args)


if __name__ == "__main__":
    main()
