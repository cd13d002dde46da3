"""Dump the forces, counts and diagnostics of every lamp mode on the test scenes, to compare two versions bitwise.

Issue 21 rebuilt the lamp without changing what it computes: this script runs every mode (criteria 0 and 1, the
area criterion with both resolvers and every ``depth_slots``, the wetted surface at several probe radii, lamp
subsets, masks, frame averaging, the following grid over moving steps, rotated grids, stress tensors, the split
and order variants, invalid and outside particles) through the public API only, and saves every array into one
``.npz``. Run it on the old and the new code, on each device, and compare:

    python bench/experiments/mode_dump.py --device cpu --out old.npz      # in a checkout of the old commit
    python bench/experiments/mode_dump.py --device cpu --out new.npz
    python bench/experiments/mode_dump.py --compare old.npz new.npz
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.scenes import scene_lattice_ball, scene_slot_block, scene_sphere_specimen


def _scenes():
    rng = np.random.default_rng(2111)
    c = rng.uniform(0.0, 5.0, (300, 3))
    r = rng.uniform(0.2, 0.6, 300)
    bad_c, bad_r = c.copy(), r.copy()
    bad_c[7, 1] = np.nan
    bad_r[11] = -1.0
    bad_r[13] = np.inf
    ball = scene_lattice_ball(diameter=0.05, particle_diameter=0.005)
    spec = scene_sphere_specimen()
    slot = scene_slot_block()
    return {
        "poly": (c, r),
        "bad": (bad_c, bad_r),
        "ball": (ball.centers, ball.radii),
        "specimen": (spec.centers, spec.radii),
        "slot": (slot.centers, slot.radii),
    }


def _cases():
    """(name, scene, grid builder keywords, ShiningLamp keywords, pressure, steps)."""
    R = np.array([[0.36, 0.48, -0.8], [-0.8, 0.6, 0.0], [0.48, 0.64, 0.6]])
    sigma = np.array([[3e6, 1e6, 0.0], [1e6, 2e6, 0.5e6], [0.0, 0.5e6, 1e6]])
    out = []
    for scene in ("poly", "bad", "ball", "specimen"):
        for crit in (0, 1):
            out.append((f"{scene}-c{crit}", scene, {}, dict(criterion=crit), 1e6, 1))
        for res in ("subpoints", "exact"):
            out.append((f"{scene}-area-{res}", scene, {}, dict(criterion="area", resolver=res), 1e6, 1))
    for d in (1, 2, 3, 4):
        out.append((f"poly-area-D{d}", "poly", {}, dict(criterion="area", depth_slots=d), 1e6, 1))
    out.append(("poly-area-S5", "poly", {}, dict(criterion="area", subpoints=5), 1e6, 1))
    for lamps in (["-x", "+x", "-y", "+y", "+z"], ["+z"], ["-x", "+y"]):
        tag = "".join(lamps)
        out.append((f"poly-lamps{tag}", "poly", {}, dict(lamps=lamps), (1e6, 2e6, 3e6), 1))
        out.append((f"poly-area-lamps{tag}", "poly", {}, dict(criterion="area", lamps=lamps), 1e6, 1))
    out.append(("poly-mask", "poly", {}, dict(active="half"), 1e6, 1))
    out.append(("poly-rot", "poly", dict(rotation=R), {}, 1e6, 1))
    out.append(("poly-area-rot", "poly", dict(rotation=R), dict(criterion="area"), 1e6, 1))
    out.append(("poly-stress", "poly", dict(stress=sigma), {}, sigma, 1))
    for split, order in ((0, False), (1, False), (4, True), (16, False)):
        out.append((f"spec-split{split}-{order}", "specimen", {}, dict(split=split, order=order), 1e6, 1))
    out.append(("spec-area-split0", "specimen", {}, dict(criterion="area", split=0), 1e6, 1))
    for k in (2, 4):
        out.append((f"ball-frames{k}", "ball", {}, dict(frames=k), 1e6, 1))
        out.append((f"ball-area-frames{k}", "ball", {}, dict(criterion="area", frames=k), 1e6, 1))
    for opts in ({}, dict(criterion=0), dict(criterion="area"), dict(surfaces="all", probe_radius=0.3)):
        tag = "-".join(f"{k}{v}" for k, v in opts.items()) or "c1"
        out.append((f"poly-follow-{tag}", "poly", dict(follow_box=True), dict(follow=True, **opts), 1e6, 4))
    for scene, rhos in (("poly", (0.0, 0.1, 0.3, 0.8)), ("ball", (0.0005, 0.0025)), ("slot", (0.45,))):
        for rho in rhos:
            out.append((f"{scene}-wet{rho}", scene, dict(probe=rho), dict(surfaces="all", probe_radius=rho), 1e6, 1))
    out.append(
        ("poly-wet-lamps", "poly", dict(probe=0.3), dict(surfaces="all", probe_radius=0.3, lamps=["+z"]), 1e6, 1)
    )
    out.append(
        ("poly-wet-mask", "poly", dict(probe=0.3), dict(surfaces="all", probe_radius=0.3, active="half"), 1e6, 1)
    )
    out.append(("spec-wet", "specimen", dict(probe=0.0025), dict(surfaces="all", probe_radius=0.0025), 1e6, 1))
    return out


def _flatten(prefix, obj, out):
    if obj is None:
        return
    if isinstance(obj, dict):
        for k, v in obj.items():
            _flatten(f"{prefix}.{k}", v, out)
        return
    if isinstance(obj, (bool, int, float, np.integer, np.floating, np.bool_)):
        out[prefix] = np.asarray(obj)
        return
    if isinstance(obj, np.ndarray):
        out[prefix] = obj.copy()  # on the CPU a warp array's .numpy() is a view the next update overwrites
        return
    if hasattr(obj, "__dataclass_fields__"):
        for k in obj.__dataclass_fields__:
            _flatten(f"{prefix}.{k}", getattr(obj, k), out)


def dump(device: str) -> dict:
    scenes = _scenes()
    out = {}
    for name, scene, gkw, lkw, pressure, steps in _cases():
        c, r = scenes[scene]
        lkw = dict(lkw)
        mask = None
        if lkw.pop("active", None) == "half":
            mask = (np.arange(len(r)) % 2).astype(np.int32)
        gkw = dict(gkw)
        probe = gkw.pop("probe", 0.0)
        stress = gkw.pop("stress", None)
        follow_box = gkw.pop("follow_box", False)
        finite = np.isfinite(c).all(axis=1) & np.isfinite(r) & (r > 0)
        cells = 4
        if stress is not None:
            gkw["rotation"] = wl.frames.lamp_stress_frame(stress)[0]
        if follow_box:
            lo = c[finite].min(axis=0) - 1.5
            hi = c[finite].max(axis=0) + 1.5 + probe
            grid = wl.LampGrid(lo - probe, hi, 0.2)
        else:
            grid = wl.LampGrid.enclosing(c[finite], r[finite], cells_per_diameter=cells, probe_radius=probe, **gkw)
        lamp = wl.ShiningLamp(grid, device=device, **lkw)
        act = None if mask is None else wp.array(mask, dtype=wp.int32, device=device)
        rng = np.random.default_rng(7)
        for step in range(steps):
            x = c + (0.37 * step) * np.array([1.0, -0.5, 0.25]) + rng.normal(0.0, 0.01, c.shape) * (step > 0)
            pos = wp.array(x.astype(np.float32), dtype=wp.vec3, device=device)
            rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
            forces = wp.zeros(len(r), dtype=wp.vec3, device=device)
            lamp.update(pos, rad, act)
            p = pressure
            lamp.add_forces(forces, p)
            key = f"{name}.s{step}"
            out[f"{key}.forces32"] = forces.numpy().copy()
            out[f"{key}.forces64"] = lamp.forces_numpy(p).copy()
            out[f"{key}.counts"] = lamp.counts_numpy().copy()
            xd = x if np.isfinite(x).all() else None
            if lkw.get("frames", 1) > 1:
                for k, child in enumerate(lamp.frames):
                    _flatten(f"{key}.frame{k}.diag", child.diagnostics(xd, p if np.ndim(p) == 0 else None), out)
            else:
                _flatten(f"{key}.diag", lamp.diagnostics(xd, p if np.ndim(p) < 2 else None), out)
            if lkw.get("follow"):
                out[f"{key}.frame_origin"] = lamp.frame_origin()
        # lamp_forces, the host path
        if not follow_box and lkw.get("split") is None:
            kw = {k: v for k, v in lkw.items() if k not in ("follow",)}
            if stress is None:
                kw["grid"] = grid
            try:
                f = wl.lamp_forces(c, r, pressure, active=mask, device=device, **kw)
                out[f"{name}.lamp_forces"] = f
            except ValueError as e:  # NaN centres are refused by lamp_forces (documented)
                out[f"{name}.lamp_forces_error"] = np.array(str(e).split(":")[0])
    return out


def compare(a_path: str, b_path: str) -> int:
    a, b = np.load(a_path), np.load(b_path)
    keys = sorted(set(a.files) | set(b.files))
    bad = added = 0
    groups = {}
    for k in keys:
        if k not in b.files:
            print(f"only in old: {k}")
            bad += 1
            continue
        if k not in a.files:
            added += 1  # a field the new version adds (e.g. wall counts) is not a difference
            continue
        x, y = a[k], b[k]
        same = (
            x.shape == y.shape
            and x.dtype == y.dtype
            and (np.array_equal(x, y, equal_nan=True) if x.dtype.kind in "fc" else np.array_equal(x, y))
        )
        if not same:
            bad += 1
            groups[k.split(".")[0]] = groups.get(k.split(".")[0], 0) + 1
            print(f"DIFFERS: {k} {x.shape} {y.shape}")
    if groups:
        print("differing cases: " + ", ".join(f"{g} ({n})" for g, n in sorted(groups.items())))
    print(f"{len(keys) - added} arrays compared, {bad} differ ({added} only in the new dump)")
    return 1 if bad else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out")
    ap.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"))
    args = ap.parse_args(argv)
    if args.compare:
        return compare(*args.compare)
    wp.config.log_level = wp.LOG_WARNING
    out = dump(args.device)
    np.savez_compressed(args.out, **out)
    print(f"{len(out)} arrays written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
