"""Study of the visible-area estimator (issue 15) against the exact visible areas, in float64 NumPy on the CPU.

For each scene: the exact visible area of every particle from every lamp (``visible_area_reference``), then the
error of criterion 1 (the lamp kernel, CPU) and of the estimator (``area_estimate_reference``) per particle.
Writes a JSON file of every number and prints the tables of ``AREA_STUDY.md``.

    PYTHONPATH=. python bench/experiments/area_study.py --quick   # a few minutes on one core
    PYTHONPATH=. python bench/experiments/area_study.py --json bench/results/area-study.json
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np

import warp_lamp as wl
from warp_lamp.lamp import LAMPS, lamp_update
from warp_lamp.reference.area import (
    _EMPTY,
    _frame,
    _sample_hits,
    area_depth_slots,
    area_estimate_reference,
    ordered_key,
    visible_area_reference,
)
from warp_lamp.scenes import Scene, scene_sphere_specimen

# --- scenes -------------------------------------------------------------------------------------------------


def scene_fcc_ball(radius=0.05, r=0.0025, spacing_r=0.0025) -> Scene:
    """FCC spheres (cube axes along x, y, z; touching when r = spacing_r) inside a ball: columns of coincident
    disks on every axis."""
    a = 2.0 * np.sqrt(2.0) * spacing_r
    k = int(np.ceil(radius / a)) + 1
    cube = np.stack(np.meshgrid(*[np.arange(-k, k + 1)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    pts = (cube[:, None, :] + basis[None]).reshape(-1, 3) * a
    keep = np.linalg.norm(pts, axis=1) + r <= radius
    return Scene("aligned FCC ball", pts[keep], np.full(int(keep.sum()), r), np.zeros(3), radius)


def scene_touching_lattice(n=8, r=0.5) -> Scene:
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3) * (2.0 * r)
    return Scene(f"touching cubic lattice {n}^3", g + 0.1234 * r, np.full(len(g), r), np.full(3, n * r), 0.0)


# --- error measures ---------------------------------------------------------------------------------------


def per_lamp_from_details(est, n):
    """Per-particle per-lamp units, shape (N, 6) (unsigned), from an estimate with details."""
    out = np.zeros((n, 6))
    for name, d in est.cells.items():
        m = d["seeds"] >= 0
        np.add.at(out[:, LAMPS.index(name)], d["seeds"][m], d["units"][m])
    return out


def per_lamp_criterion1(c, r, grid):
    lamp = lamp_update(c, r, grid=grid, criterion=1, device="cpu")
    diag = lamp.diagnostics()
    out = np.zeros((len(r), 6))
    for k, name in enumerate(LAMPS):
        own = diag.owners[name]
        np.add.at(out[:, k], own[own >= 0], 1.0)
    return out


def errors(lamp_area, exact, rbar):
    """RMS and max over particles of the net force error |F - F_exact| and of the six-lamp error, / (P pi rbar^2)."""
    scale = np.pi * rbar * rbar
    net = (lamp_area[:, 0::2] - lamp_area[:, 1::2]) - (exact[:, 0::2] - exact[:, 1::2])
    e_net = np.linalg.norm(net, axis=1) / scale
    e_lamp = np.linalg.norm(lamp_area - exact, axis=1) / scale
    surface = exact.sum(axis=1) > 0
    return {
        "rms": float(np.sqrt(np.mean(e_net**2))),
        "rms_surface": float(np.sqrt(np.mean(e_net[surface] ** 2))),
        "surface_fraction": float(surface.mean()),
        "max": float(e_net.max()),
        "rms_lamps": float(np.sqrt(np.mean(e_lamp**2))),
        "max_lamps": float(e_lamp.max()),
    }


# --- cost counters ------------------------------------------------------------------------------------------


def criterion1_visits(c, r, grid):
    """Sphere-cell pairs whose cell-centre ray meets the sphere, summed over the three grids."""
    q, r32, axes = _frame(c, r, grid, np.ones(len(r), dtype=bool))
    total = 0
    for a, (cu, cv, hu, hv, nu, nv) in enumerate(axes):
        u, v = (a + 1) % 3, (a + 2) % 3
        pu = q[:, u] - cu - hu * np.float32(0.5)
        pv = q[:, v] - cv - hv * np.float32(0.5)
        total += len(_sample_hits(pu, pv, r32, hu, hv, nu - 1, nv - 1)[0])
    return total


def subpoint_tests(est, c, r, grid, s):
    """Disk tests the sub-point resolver makes: a point stops at its first holder; a last seed that holds all
    four corners is never tested (it takes what is left)."""
    q, r32, axes = _frame(c, r, grid, np.ones(len(r), dtype=bool))
    total = 0
    for name, d in est.cells.items():
        a = LAMPS.index(name) // 2
        cu, cv, hu, hv, nu, _ = axes[a]
        u, v = (a + 1) % 3, (a + 2) % 3
        seeds = d["seeds"]
        o = np.where(seeds >= 0, seeds, 0)
        ox = (q[o, u] - cu) - ((d["cell"] % nu).astype(np.float32) * hu)[:, None]
        oy = (q[o, v] - cv) - ((d["cell"] // nu).astype(np.float32) * hv)[:, None]
        rr = np.where(seeds >= 0, r32[o], np.float32(0))
        k = (seeds >= 0).sum(axis=1)
        last = np.maximum(k - 1, 0)
        rows = np.arange(len(k))
        corner = k > 0
        for x, y in ((0, 0), (hu, 0), (0, hv), (hu, hv)):
            dx = np.float32(x) - ox[rows, last]
            dy = np.float32(y) - oy[rows, last]
            corner &= dx * dx + dy * dy <= rr[rows, last] ** 2
        tested = k - corner
        rr = np.where(np.arange(seeds.shape[1])[None, :] < tested[:, None], rr, np.float32(0))
        t = np.arange(s, dtype=np.float32) + np.float32(0.5)
        tx = np.repeat(t * (hu / np.float32(s)), s)
        ty = np.tile(t * (hv / np.float32(s)), s)
        for b0 in range(0, len(seeds), 4096):
            sl = slice(b0, b0 + 4096)
            dx = tx[None, :, None] - ox[sl][:, None, :]
            dy = ty[None, :, None] - oy[sl][:, None, :]
            held = (dx * dx + dy * dy <= rr[sl][:, None, :] ** 2) & (rr[sl][:, None, :] > 0)
            first = np.where(held.any(axis=2), held.argmax(axis=2) + 1, tested[sl][:, None])
            total += int(first.sum())
    return total


def kernel_cpu_ms(c, r, grid, d, resolver, s=8, reps=5):
    """Fastest of a few runs of the per-cell Warp kernel on the CPU (one thread), on the reference's D-slot keys."""
    import warp as wp

    from warp_lamp.kernels import area as KA

    keys, _ = area_depth_slots(c, r, grid, depth_slots=d)
    f = grid.frame()
    nu, nv = grid.counts[:, 0], grid.counts[:, 1]
    so = np.concatenate([[0], np.cumsum((nu + 1) * (nv + 1))[:2]])
    counts = wp.zeros(3 * len(c), dtype=wp.int64, device="cpu")
    diag = wp.zeros(2, dtype=wp.int32, device="cpu")
    inputs = [
        wp.array(keys, dtype=wp.uint64, device="cpu"),
        d,
        wp.array((c - grid.origin).astype(np.float32), dtype=wp.vec3, device="cpu"),
        wp.array(r.astype(np.float32), dtype=wp.float32, device="cpu"),
        wp.vec3(0.0, 0.0, 0.0),
        wp.vec3(*f["corner_u"]),
        wp.vec3(*f["corner_v"]),
        wp.vec3(*f["h_u"]),
        wp.vec3(*f["h_v"]),
        wp.vec3i(*(int(x) for x in nu)),
        wp.vec3i(*(int(x) for x in nv)),
        wp.vec3i(*(int(x) for x in f["offset"])),
        wp.vec3i(*(int(x) for x in so)),
        63,
        KA.RESOLVER_EXACT if resolver == "exact" else KA.RESOLVER_SUBPOINTS,
        s,
        4096 if resolver == "exact" else s * s,
    ]
    times = []
    for _ in range(reps + 1):
        counts.zero_()
        t0 = time.perf_counter()
        wp.launch(KA.area_cells, dim=grid.n_cells, inputs=inputs, outputs=[counts, diag], device="cpu")
        wp.synchronize_device("cpu")
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.min(times[1:]))


def criterion1_cpu_ms(c, r, grid, reps=5):
    """Fastest of a few cold criterion-1 updates (seed, depth pass, scatter) on the CPU (one thread)."""
    import warp as wp

    lamp = wl.ShiningLamp(grid, criterion=1, device="cpu")
    pos = wp.array((c - grid.origin).astype(np.float32), dtype=wp.vec3, device="cpu")
    rad = wp.array(r.astype(np.float32), dtype=wp.float32, device="cpu")
    lamp.update(pos, rad)
    times = []
    for _ in range(reps):
        lamp.forget()
        t0 = time.perf_counter()
        lamp.update(pos, rad)
        wp.synchronize_device("cpu")
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.min(times))


def all_candidates(c, r, grid):
    """Study hook: every sphere whose disk meets the cell, as extra candidates (the complete seed set)."""
    q, r32, axes = _frame(c, r, grid, np.ones(len(r), dtype=bool))

    def extra(a, nu, nv):
        cu, cv, hu, hv, _, _ = axes[a]
        u, v = (a + 1) % 3, (a + 2) % 3
        pu, pv = q[:, u] - cu, q[:, v] - cv
        # Cells [i h, (i+1) h] the bounding box reaches; the estimator's own test then drops the misses.
        i0 = np.clip(np.floor((pu - r32) / hu) - 1, 0, nu - 1).astype(np.int64)
        i1 = np.clip(np.floor((pu + r32) / hu) + 1, 0, nu - 1).astype(np.int64)
        j0 = np.clip(np.floor((pv - r32) / hv) - 1, 0, nv - 1).astype(np.int64)
        j1 = np.clip(np.floor((pv + r32) / hv) + 1, 0, nv - 1).astype(np.int64)
        ni, nj = i1 - i0 + 1, j1 - j0 + 1
        cnt = ni * nj
        pid = np.repeat(np.arange(len(r)), cnt)
        local = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        cell = (j0[pid] + local // ni[pid]) * nu + i0[pid] + local % ni[pid]
        order = np.lexsort((pid, cell))
        cell, pid = cell[order], pid[order]
        start = np.flatnonzero(np.r_[True, cell[1:] != cell[:-1]])
        rank = np.arange(len(cell)) - np.repeat(start, np.diff(np.r_[start, len(cell)]))
        out = np.full((nu * nv, int(rank.max()) + 1), _EMPTY, dtype=np.uint64)
        out[cell, rank] = ordered_key(np.zeros(len(pid), dtype=np.float32), pid)
        return out

    return extra


# --- runs ---------------------------------------------------------------------------------------------------


def run_estimator(c, r, grid, exact, rbar, *, resolver, d, s=8, **kw):
    t0 = time.perf_counter()
    est = area_estimate_reference(c, r, grid, depth_slots=d, resolver=resolver, subpoints=s, details=True, **kw)
    dt = time.perf_counter() - t0
    lamp = per_lamp_from_details(est, len(r)) * (grid.cell_area[0] / est.unit)
    out = errors(lamp, exact, rbar)
    st = est.stats
    out.update(
        resolver=resolver,
        D=d,
        S=s if resolver == "subpoints" else None,
        numpy_s=dt,
        sample_hits=st["sample_hits"],
        cells=st["cells"],
        seeds_per_cell=st["seeds"] / max(st["cells"], 1),
        gathered_per_cell=st["seeds_gathered"] / max(st["cells"], 1),
        max_seeds=st["max_seeds"],
        overflow=st["overflow"],
        one_sided=st["one_sided"],
        candidates_per_cell=st["candidates"] / max(st["cells"], 1),
    )
    if resolver == "subpoints":
        out["subpoint_tests_per_cell"] = subpoint_tests(est, c, r, grid, s) / max(st["cells"], 1)
    else:
        k = np.concatenate([(v["seeds"] >= 0).sum(axis=1) for v in est.cells.values()])
        out["seeds_sq_per_cell"] = float(np.mean(k.astype(np.float64) ** 2))
    out["balance"] = [int(x) for x in est.units.sum(axis=0)]
    assert out["balance"] == [0, 0, 0], out["balance"]
    return out, est


def study_body(scene, cpds_c1, cpds_area, ds, *, variants=False, quick=False, timings=False):
    c, r = scene.centers, scene.radii
    rbar = float(r.mean())
    t0 = time.perf_counter()
    exact = visible_area_reference(c, r)
    res = {"scene": scene.name, "n": len(r), "reference_s": time.perf_counter() - t0, "criterion1": [], "area": []}
    for cpd in cpds_c1:
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=cpd)
        lamp = per_lamp_criterion1(c, r, grid) * grid.cell_area[0]
        row = errors(lamp, exact, rbar)
        row.update(cpd=cpd, visits=criterion1_visits(c, r, grid), cells=int(grid.n_cells))
        if timings and cpd <= 8:
            row["cpu_update_ms"] = criterion1_cpu_ms(c, r, grid)
        res["criterion1"].append(row)
        print(
            f"  c1 {cpd:>3} cells/d: surface rms {row['rms_surface']:.3%} (all {row['rms']:.3%}) max {row['max']:.3%}"
        )
    for cpd in cpds_area:
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=cpd)
        for d in ds:
            for resolver in ("exact", "subpoints"):
                row, _ = run_estimator(c, r, grid, exact, rbar, resolver=resolver, d=d)
                row["cpd"] = cpd
                row["grid_cells"] = int(grid.n_cells)
                if timings:
                    row["cpu_cell_kernel_ms"] = kernel_cpu_ms(c, r, grid, d, resolver)
                res["area"].append(row)
                print(
                    f"  {resolver:>9} D={d} {cpd} cells/d: surface rms {row['rms_surface']:.3%} (all {row['rms']:.4%}) "
                    f"max {row['max']:.3%} "
                    f"seeds/cell {row['seeds_per_cell']:.2f} one-sided {row['one_sided']} overflow {row['overflow']}"
                )
    if variants:
        res["variants"] = []
        runs = [
            (3, "D=1", dict(resolver="exact", d=1)),
            (3, "D=2", dict(resolver="exact", d=2)),
            (3, "D=3, ring keeps D slots", dict(resolver="exact", d=3, _ring_slots=3)),
            (3, "D=3, no ring", dict(resolver="exact", d=3, _ring_slots=0)),
            (3, "D=3, seeds of both lamps", dict(resolver="exact", d=3, _cell_seeds="both")),
            (3, "D=2, seeds of both lamps", dict(resolver="exact", d=2, _cell_seeds="both")),
            (2, "D=3, seeds of both lamps", dict(resolver="exact", d=3, _cell_seeds="both")),
            (3, "complete seeds (every disk meeting the cell)", dict(resolver="exact", d=1, max_seeds=256)),
            (2, "complete seeds (every disk meeting the cell)", dict(resolver="exact", d=1, max_seeds=256)),
            (3, "S=4", dict(resolver="subpoints", d=3, s=4)),
            (3, "S=6", dict(resolver="subpoints", d=3, s=6)),
            (3, "S=16", dict(resolver="subpoints", d=3, s=16)),
            (2, "S=16", dict(resolver="subpoints", d=3, s=16)),
            (2, "S=12", dict(resolver="subpoints", d=3, s=12)),
            (3, "S=16, seeds of both lamps", dict(resolver="subpoints", d=3, s=16, _cell_seeds="both")),
        ]
        if quick:
            runs = [runs[2], runs[4], runs[7], runs[11]]
        grids = {}
        for cpd, label, kw in runs:
            grid = grids.setdefault(cpd, wl.LampGrid.enclosing(c, r, cells_per_diameter=cpd))
            if label.startswith("complete"):
                kw = dict(kw, _extra=all_candidates(c, r, grid))
            row, _ = run_estimator(c, r, grid, exact, rbar, **kw)
            row.update(cpd=cpd, variant=label)
            res["variants"].append(row)
            print(
                f"  variant {label} @{cpd}: surface rms {row['rms_surface']:.3%} max {row['max']:.3%} "
                f"seeds/cell {row['seeds_per_cell']:.2f}"
            )
    return res


def study_lone_sphere(samples, cpds):
    rng = np.random.default_rng(7)
    r = 0.5
    out = []
    for cpd in cpds:
        h = 2 * r / cpd
        grid = wl.LampGrid([-1.0] * 3, [1.0] * 3, h)
        offs = rng.uniform(0.0, h, (samples, 3))
        errs = {"exact": [], "subpoints": [], "criterion1": []}
        worst_units = 0.0
        for off in offs:
            c = off[None, :]
            for resolver in ("exact", "subpoints"):
                est = area_estimate_reference(c, [r], grid, resolver=resolver, details=True)
                lamp_units = per_lamp_from_details(est, 1)[0]
                target = np.pi * r * r / (h * h) * est.unit
                errs[resolver].extend(lamp_units / target - 1.0)
                if resolver == "exact":
                    worst_units = max(worst_units, float(np.abs(lamp_units - target).max()))
            lit = per_lamp_criterion1(c, [r], grid)[0]
            errs["criterion1"].extend(lit * h * h / (np.pi * r * r) - 1.0)
        row = {"cpd": cpd, "samples": samples, "exact_worst_units": worst_units, "unit": 4096}
        for k, v in errs.items():
            v = np.asarray(v)
            row[k] = {"rms": float(np.sqrt(np.mean(v**2))), "max": float(np.abs(v).max())}
        out.append(row)
        print(
            f"  lone sphere {cpd} cells/d: exact rms {row['exact']['rms']:.2e} (worst {worst_units:.2f} units of "
            f"4096/cell), subpoints rms {row['subpoints']['rms']:.3%}, criterion 1 rms {row['criterion1']['rms']:.3%}"
        )
    return out


def study_lattice(n, cpds, ds):
    scene = scene_touching_lattice(n)
    c, r = scene.centers, scene.radii
    out = []
    for cpd in cpds:
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=cpd)
        for d in ds:
            for resolver in ("exact", "subpoints"):
                est = area_estimate_reference(c, r, grid, depth_slots=d, resolver=resolver, details=True)
                per = per_lamp_from_details(est, len(r)).sum(axis=0) * grid.cell_area[0] / est.unit
                ratio = per / (n * n * np.pi * 0.25)
                out.append({"cpd": cpd, "D": d, "resolver": resolver, "load_ratio": ratio.tolist()})
                print(
                    f"  lattice {n}^3 {resolver} D={d} {cpd} cells/d: "
                    f"load / n^2 pi r^2 = {ratio.min():.6f}..{ratio.max():.6f}"
                )
    return out


def study_fcc_commensurate(fcc):
    """The aligned FCC ball on grids whose cell divides the cube edge a (sample rays on lattice features)."""
    c, r = fcc.centers, fcc.radii
    a = 2 * np.sqrt(2) * r[0]
    exact = visible_area_reference(c, r)
    out = []
    for k, shift in ((2, 0.0), (3, 0.0), (4, 0.0), (4, 0.5), (6, 0.0)):
        h = a / k
        lo = np.floor((c.min(0) - r[0]) / a - 1) * a + shift * h
        grid = wl.LampGrid(lo, lo + (np.ceil((c.max(0) + r[0] - lo) / h) + 2) * h, h)
        for resolver in ("exact", "subpoints"):
            row, _ = run_estimator(c, r, grid, exact, r.mean(), resolver=resolver, d=3)
            row.update(cpd=2 * r[0] / h, cell=f"a/{k}", shift=shift)
            out.append(row)
            print(
                f"  FCC, cell a/{k} ({row['cpd']:.2f} cells/d), shift {shift} h: {resolver} "
                f"surface rms {row['rms_surface']:.3%} max {row['max']:.2%}"
            )
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer resolutions and samples (a few minutes)")
    ap.add_argument("--json", default=None, help="write every number to this file")
    args = ap.parse_args(argv)
    q = args.quick
    t0 = time.perf_counter()
    result = {"machine": platform.platform(), "processor": platform.processor(), "quick": q}
    print("lone sphere (per-lamp error against pi r^2, random sub-cell offsets)")
    result["lone"] = study_lone_sphere(16 if q else 64, (2, 3, 4))
    print("touching cubic lattice")
    result["lattice"] = study_lattice(4 if q else 8, (2, 3, 4), (3,) if q else (3, 4))
    c1 = (2, 4, 8, 16, 32) if q else (2, 3, 4, 6, 8, 12, 16, 24, 32)
    ds = (3,) if q else (3, 4)
    specimen = scene_sphere_specimen()
    print(f"SphereTest specimen ({specimen.n} spheres)")
    result["specimen"] = study_body(specimen, c1, (2, 3, 4), ds, variants=True, quick=q, timings=True)
    overl = Scene("specimen, radii +2%", specimen.centers, specimen.radii * 1.02, specimen.center, specimen.radius)
    print("specimen with radii +2% (DEM-like overlaps)")
    result["overlap"] = study_body(overl, (4,) if q else (2, 4, 8, 16), (3,) if q else (2, 3, 4), ds)
    fcc = scene_fcc_ball()
    print(f"aligned FCC ball ({fcc.n} spheres)")
    result["fcc"] = study_body(fcc, (4,) if q else (2, 4, 8, 16, 32), (3,) if q else (2, 3, 4), (3, 4))
    if not q:
        print("aligned FCC ball on commensurate grids")
        result["fcc_commensurate"] = study_fcc_commensurate(fcc)
        loose = scene_fcc_ball(r=0.0025 * 0.97)
        loose.name = "aligned FCC ball, radii 0.97 of touching"
        print(f"{loose.name} ({loose.n} spheres)")
        result["fcc_loose"] = study_body(loose, (4,), (2, 3, 4), (3, 4))
    result["seconds"] = time.perf_counter() - t0
    print(f"total {result['seconds']:.0f} s")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
