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


#: (label, WetBox.skip, WetBox.gather or None for the default): the exact test's parts,
#: timed by what skipping them saves (answers wrong where skip is not 0).
# (The once-per-update triple points, timed here on 2026-11-28 at 3.6x the per-voxel search, were removed.)
PROFILE = (
    ("whole exact test", 0, None),
    ("no vertex candidates", 1, None),
    ("no edge or vertex candidates", 3, None),
    ("no candidates (neighbour walk and pruning)", 16, None),
    ("neighbour walk only", 8, None),
    ("bins walked per candidate (no gather)", 0, 0),
)


def profile(args):
    """The classify stage (exposure, the exact tests) with parts of the exact test skipped, on the specimen and
    the slot block at rho = r-bar: graph replay on CUDA, thread time on the CPU (best of the repeats)."""
    import warp as wp
    from wetted_knobs import stage_time

    import warp_lamp as wl
    from warp_lamp.scenes import scene_lattice_box, scene_slot_block, scene_sphere_specimen
    from warp_lamp.wetted import WettedSurface

    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    device = wp.get_device(args.device)
    scenes = (
        [("small lattice", scene_lattice_box(8))]
        if args.quick
        else [("specimen", scene_sphere_specimen()), ("slot", scene_slot_block())]
    )
    rows = []
    for name, sc in scenes:
        rho = float(sc.radii.mean())
        grid = wl.LampGrid.enclosing(sc.centers, sc.radii, cells_per_diameter=4, margin=2.0 * rho + rho)
        pos = wp.array((sc.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
        rad = wp.array(sc.radii.astype(np.float32), dtype=wp.float32, device=device)
        surf = WettedSurface(grid, probe_radius=rho, device=device)
        surf.update(pos, rad)
        gather0 = surf._box.gather

        def timed(stop, surf=surf, pos=pos, rad=rad):
            return stage_time(surf, pos, rad, stop, device, args.repeats)

        base = timed("dilate")
        for label, skip, gather in PROFILE:
            surf._box.skip = skip
            surf._box.gather = gather0 if gather is None else gather
            t = timed("classify") - base
            rows.append(dict(scene=name, part=label, skip=skip, gather=surf._box.gather, classify_s=t))
            print(f"{name:14s} {label:44s} classify {t * 1e3:8.3f} ms", flush=True)
        surf._box.skip, surf._box.gather = 0, gather0
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
    pr = _load(args.profile) if args.profile else None
    result = {"issue": 32, "before_bench": bb, "after_bench": ab, "before_hashes": bh, "after_hashes": ah}
    result["profile"] = pr
    rk = _load(args.rockcut) if args.rockcut else None
    brk = _load(args.before_rockcut) if args.before_rockcut else None
    result["rockcut"], result["before_rockcut"] = rk, brk
    share = _load(args.share) if args.share else None
    result["rockcut_share"] = share
    same = None
    if bh and ah:
        hb = {r["case"]: r["hash"] for r in bh["rows"]}
        ha = {r["case"]: r["hash"] for r in ah["rows"]}
        same = {k: hb[k] == ha.get(k) for k in hb}
        result["bitwise"] = same
    with open(args.out, "w") as f:
        json.dump(result, f, indent=1)
    print("== issue 32: wetted surface before (4149365) and after, same card, graph replay ==")
    if ab:
        print(f"device: {ab.get('name', '')} ({ab.get('device')})")
        stages = ["rasterize", "connect", "dilate", "classify", "cross", "thin"]
        print(f"{'scene':10s} {'rho/d':>5s} {'':6s} {'total':>8s} " + " ".join(f"{s[:8]:>8s}" for s in stages))
        after = {(r["scene"], r["rho_over_d"]): r for r in ab["rows"]}
        for r in (bb or {"rows": []})["rows"] or ab["rows"]:
            a = after.get((r["scene"], r["rho_over_d"]))
            for tag, row in (("before", r if bb else None), ("after", a)):
                if row is None or ("all_replay_s" not in row and "all_eager_s" not in row):
                    continue
                tot = row.get("all_replay_s", row.get("all_eager_s"))
                st = " ".join(f"{row.get(f'all_{s}_s', float('nan')) * 1e3:8.3f}" for s in stages)
                print(f"{r['scene'][:10]:10s} {r['rho_over_d']:5.2f} {tag:6s} {tot * 1e3:8.3f} {st}")
            if a is not None and bb:
                print(f"{'':10s} {'':5s} hash   {'same' if r['fluid_hash'] == a['fluid_hash'] else 'DIFFERENT'}")
    if pr:
        print("classify stage with parts of the exact test skipped (after; rho = r-bar):")
        for r in pr["rows"]:
            print(f"  {r['scene']:14s} {r['part']:44s} {r['classify_s'] * 1e3:8.3f} ms")
    if brk and rk:
        same = dict(same or {})
        for a, b in zip(brk["rows"], rk["rows"], strict=False):
            same[f"rock cut slab, debris {a['debris']:.2f}"] = a.get("hash") == b.get("hash")
        result["bitwise"] = same
        with open(args.out, "w") as f:
            json.dump(result, f, indent=1)
    for tag, data in (("before", brk), ("after", rk)):
        if not data:
            continue
        print(f"rock cut's slab on its lamp grid ({tag}), per update:")
        for r in data["rows"]:
            st = " ".join(f"{k[:-2]} {v * 1e3:.3f}" for k, v in r.items() if k.endswith("_s"))
            print(f"  debris {r['debris']:.2f}, {r['tested']} tested, {r['rounds']} rounds: {st} ms")
    if share:
        for mode in ("first", "all"):
            t = share.get(mode)
            if t:
                print(
                    f"rock cut cycle ({mode}, after): {t['cycle_s'] * 1e6:.1f} us, without the lamp "
                    f"{t['cycle_without_lamp_s'] * 1e6:.1f} us: lamp share {t['lamp_share']:.1%}"
                )
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
    p = sub.add_parser("profile")
    p.add_argument("--device", default=None)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--out", required=True)
    c = sub.add_parser("combine")
    for k in ("before-bench", "after-bench", "before-hashes", "after-hashes", "out"):
        c.add_argument(f"--{k}", required=True)
    c.add_argument("--profile", default=None)
    c.add_argument("--rockcut", default=None)
    c.add_argument("--before-rockcut", default=None)
    c.add_argument("--share", default=None)
    args = ap.parse_args()
    {"hashes": hashes, "profile": profile, "combine": combine}[args.cmd](args)


if __name__ == "__main__":
    main()
