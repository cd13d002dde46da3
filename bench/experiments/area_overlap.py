"""The area criterion on overlapping spheres (issue 19, part 3): per-particle RMS against a float64 raster.

The raster: per lamp axis, rays on a square lattice of ``rays`` per mean diameter over the body's footprint; each
ray goes to the sphere whose *surface* it meets first (low lamp: the smallest entry depth ``z - s``; high lamp:
the largest exit depth ``z + s``), ties to the lowest index, and carries its pixel's area. Written here from
scratch (no warp_lamp code), so that it can measure any version of the library, the original one included:

    PYTHONPATH=. python bench/experiments/area_overlap.py --save-scene /tmp/overlap.npz --json after.json
    PYTHONPATH=/tmp/a7331c6 python bench/experiments/area_overlap.py --scene /tmp/overlap.npz --json before.json

Errors are :func:`warp_lamp.measures.visible_area_error`'s: per particle ``|F - F_raster| / (P pi rbar^2)``,
RMS over the surface particles; also over the particles that overlap no other sphere.
"""

from __future__ import annotations

import argparse
import itertools
import json
import platform
import time

import numpy as np

P = 1.0


def raster_areas(centers, radii, rays=128, *, chunk=2_000_000) -> np.ndarray:
    """Visible area of every sphere from each of the six lamps [m^2], shape (N, 6), by a first-surface raster.

    Args:
        centers: Sphere centres [m], shape (N, 3).
        radii: Radii [m], shape (N,).
        rays: Rays per mean diameter (the pixel is ``2 rbar / rays`` square).
    """
    c = np.asarray(centers, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    n = len(r)
    h = 2.0 * r.mean() / rays
    out = np.zeros((n, 6))
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        u0 = (c[:, u] - r).min() - h
        v0 = (c[:, v] - r).min() - h
        nu = int(np.ceil(((c[:, u] + r).max() + h - u0) / h))
        nv = int(np.ceil(((c[:, v] + r).max() + h - v0) / h))
        # Each sphere's pixels: i in [i0, i1], j in [j0, j1].
        i0 = np.floor((c[:, u] - r - u0) / h - 0.5).astype(np.int64)
        i1 = np.ceil((c[:, u] + r - u0) / h - 0.5).astype(np.int64)
        j0 = np.floor((c[:, v] - r - v0) / h - 0.5).astype(np.int64)
        j1 = np.ceil((c[:, v] + r - v0) / h - 0.5).astype(np.int64)
        cnt = (i1 - i0 + 1) * (j1 - j0 + 1)
        best = [np.full(nu * nv, np.inf), np.full(nu * nv, np.inf)]
        owner = [np.full(nu * nv, n, dtype=np.int64), np.full(nu * nv, n, dtype=np.int64)]
        # Sphere batches of at most ``chunk`` (sphere, pixel) pairs.
        bounds = np.r_[0, np.flatnonzero(np.diff(np.cumsum(cnt) // chunk)) + 1, n]
        for pass_ in range(2):
            for b0, b1 in itertools.pairwise(bounds):
                ids = np.arange(b0, b1)
                k = cnt[ids]
                sph = np.repeat(ids, k)
                local = np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)
                ni = i1[sph] - i0[sph] + 1
                ii = i0[sph] + local % ni
                jj = j0[sph] + local // ni
                du = u0 + (ii + 0.5) * h - c[sph, u]
                dv = v0 + (jj + 0.5) * h - c[sph, v]
                s2 = r[sph] ** 2 - du * du - dv * dv
                hit = s2 >= 0
                sph, pix, s = sph[hit], (jj * nu + ii)[hit], np.sqrt(s2[hit])
                for side in range(2):
                    depth = c[sph, a] - s if side == 0 else -(c[sph, a] + s)
                    if pass_ == 0:
                        np.minimum.at(best[side], pix, depth)
                    else:
                        first = depth == best[side][pix]
                        np.minimum.at(owner[side], pix[first], sph[first])
        for side in range(2):
            got = owner[side][owner[side] < n]
            out[:, 2 * a + side] = np.bincount(got, minlength=n) * h * h
    return out


def isolated(centers, radii) -> np.ndarray:
    """Particles that overlap no other sphere, shape (N,) bool (brute force over pairs in blocks)."""
    c = np.asarray(centers, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    alone = np.ones(len(r), dtype=bool)
    for b in range(0, len(r), 256):
        d = np.linalg.norm(c[b : b + 256, None, :] - c[None], axis=2)
        over = d < r[b : b + 256, None] + r[None]
        over[np.arange(over.shape[0]), np.arange(b, b + over.shape[0])] = False
        alone[b : b + 256] = ~over.any(axis=1)
    return alone


def errors(forces, areas, rbar, mask) -> dict:
    exact = P * (areas[:, 0::2] - areas[:, 1::2])
    err = np.linalg.norm(forces - exact, axis=1) / (P * np.pi * rbar**2)
    surface = areas.sum(axis=1) > 0
    sel = surface & mask
    return {
        "rms": float(np.sqrt(np.mean(err[surface] ** 2))),
        "worst": float(err.max()),
        "rms_isolated": float(np.sqrt(np.mean(err[sel] ** 2))) if sel.any() else None,
        "surface": int(surface.sum()),
        "surface_isolated": int(sel.sum()),
    }


def completeness(c, r, areas, alone, cpds) -> list:
    """The estimator reference (exact resolver) with the gathered seeds (D = 3, 4) and with every sphere whose disk
    meets the cell (``area_study.all_candidates``): what the gather misses where spheres overlap."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from area_study import all_candidates

    import warp_lamp as wl
    from warp_lamp.reference import area_estimate_reference

    rows = []
    rbar = float(r.mean())
    for cpd in cpds:
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=cpd)
        for label, kw in (
            ("gathered, D = 3", dict(depth_slots=3)),
            ("gathered, D = 4", dict(depth_slots=4)),
            ("complete seeds", dict(depth_slots=1, max_seeds=256, _extra=all_candidates(c, r, grid))),
        ):
            est = area_estimate_reference(c, r, grid, resolver="exact", **kw)
            f = P * est.units * (grid.cell_area / est.unit)
            rows.append({"cells_per_diameter": cpd, "seeds": label, **errors(f, areas, rbar, alone)})
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", help="npz with centers, radii (default: scene_overlapping_polydisperse())")
    ap.add_argument("--save-scene", help="write the scene to this npz")
    ap.add_argument("--rays", type=int, default=128, help="raster rays per mean diameter")
    ap.add_argument("--cpd", type=float, nargs="+", default=[4.0], help="cells per mean diameter")
    ap.add_argument("--depth-slots", type=int, default=3)
    ap.add_argument("--reference", action="store_true", help="also compare with visible_area_reference")
    ap.add_argument("--completeness", action="store_true", help="estimator reference: gathered against complete seeds")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()

    import warp_lamp as wl

    if args.scene:
        data = np.load(args.scene)
        c, r = data["centers"], data["radii"]
    else:
        from warp_lamp.scenes import scene_overlapping_polydisperse

        s = scene_overlapping_polydisperse()
        c, r = s.centers, s.radii
    if args.save_scene:
        np.savez(args.save_scene, centers=c, radii=r)
    rbar = float(r.mean())
    t0 = time.perf_counter()
    areas = raster_areas(c, r, args.rays)
    raster_s = time.perf_counter() - t0
    alone = isolated(c, r)
    out = {"n": len(r), "rays_per_diameter": args.rays, "raster_s": raster_s, "isolated": int(alone.sum()), "rows": []}
    out["machine"] = platform.platform()
    if args.reference:
        from warp_lamp.reference import visible_area_reference

        t0 = time.perf_counter()
        ref = visible_area_reference(c, r)
        out["reference_s"] = time.perf_counter() - t0
        out["reference_vs_raster"] = errors(P * (ref[:, 0::2] - ref[:, 1::2]), areas, rbar, alone)
        out["reference_vs_raster_max_abs_area"] = float(np.abs(ref - areas).max() / (np.pi * rbar**2))
    for cpd in args.cpd:
        for resolver in ("exact", "subpoints"):
            t0 = time.perf_counter()
            f = wl.lamp_forces(
                c, r, P, cells_per_diameter=cpd, criterion="area", resolver=resolver, depth_slots=args.depth_slots
            )
            row = {"cells_per_diameter": cpd, "resolver": resolver, "depth_slots": args.depth_slots}
            row["seconds"] = time.perf_counter() - t0
            row["balanced"] = bool(np.all(f.sum(axis=0) == 0.0))
            row.update(errors(f, areas, rbar, alone))
            out["rows"].append(row)
        f = wl.lamp_forces(c, r, P, cells_per_diameter=cpd)
        row = {"cells_per_diameter": cpd, "resolver": "criterion 1"}
        row.update(errors(f, areas, rbar, alone))
        out["rows"].append(row)
    if args.completeness:
        out["completeness"] = completeness(c, r, areas, alone, args.cpd)
    print(f"{len(r)} spheres, {alone.sum()} overlap nothing; raster {args.rays} rays/d in {raster_s:.1f} s")
    for row in out.get("completeness", []):
        print("completeness:", row)
    if args.reference:
        print("visible_area_reference against the raster:", out["reference_vs_raster"])
    print("| estimator | cells/d | RMS | worst | RMS, particles overlapping nothing |")
    print("| --- | --- | --- | --- | --- |")
    for row in out["rows"]:
        iso = row["rms_isolated"]
        print(
            f"| {row['resolver']} | {row['cells_per_diameter']:g} | {100 * row['rms']:.3f}% | "
            f"{100 * row['worst']:.2f}% | {'-' if iso is None else f'{100 * iso:.3f}%'} |"
        )
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
