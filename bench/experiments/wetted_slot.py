"""Issue 10's slot block: wall and floor load ratios of the wetted-surface mode (float64 reference and kernels)
against today's first-surface lamp. CPU only; prints a Markdown table for bench/experiments/WETTED.md.

Wall load: the lateral force on the lattice column next to the slot over the slot's depth (iy = j0 - 1 or j1,
iz >= k0), pushing into the wall, over P L D. Floor load: the downward force on the layer under the slot
(iz = k0 - 1, j0 <= iy < j1) over P L w. "floor+" also counts the two corner columns (iy = j0 - 1, j1).

    PYTHONPATH=$PWD python bench/experiments/wetted_slot.py [--no-reference]
"""

import argparse
import time

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.lamp import pressure_area
from warp_lamp.reference.wetted import wetted_reference
from warp_lamp.scenes import scene_slot_block
from warp_lamp.wetted import WettedSurface

P = 1.0


def wetted_solve(centers, radii, *, probe_radius, grid, device="cpu", **kw):
    """The wetted-surface engine on host positions (frame coordinates in float64, then float32)."""
    surface = WettedSurface(grid, probe_radius=probe_radius, device=device, **kw)
    pos = wp.array(grid.to_frame(centers).astype(np.float32), dtype=wp.vec3, device=device)
    surface.update(pos, wp.array(np.asarray(radii, dtype=np.float32), device=device))
    return surface


def ratios(scene, forces):
    cut, idx = scene.cut, scene.index
    top = idx[:, 2] >= cut["k0"]
    lo = (idx[:, 1] == cut["wall_lo"]) & top
    hi = (idx[:, 1] == cut["wall_hi"]) & top
    layer = idx[:, 2] == cut["floor"]
    floor = layer & (idx[:, 1] >= cut["j0"]) & (idx[:, 1] < cut["j1"])
    floor_plus = layer & (idx[:, 1] >= cut["wall_lo"]) & (idx[:, 1] <= cut["wall_hi"])
    side = P * cut["length"] * cut["depth"]
    bottom = P * cut["length"] * cut["width"]
    return dict(
        wall_lo=-forces[lo, 1].sum() / side,
        wall_hi=forces[hi, 1].sum() / side,
        floor=-forces[floor, 2].sum() / bottom,
        floor_plus=-forces[floor_plus, 2].sum() / bottom,
    )


def row(label, r, loaded, extra=""):
    return (
        f"| {label} | {r['wall_lo']:.3f} / {r['wall_hi']:.3f} | {r['floor']:.3f} | {r['floor_plus']:.3f} | "
        f"{loaded:,} | {extra} |"
    )


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--no-reference", action="store_true", help="kernels only (fast)")
    ap.add_argument("--cells", type=float, default=4.0)
    args = ap.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    scene = scene_slot_block()
    rmean = float(scene.radii.mean())
    print(f"# {scene.name}: {scene.n:,} particles, mean radius {rmean:.4f}, {args.cells:g} cells per diameter\n")
    print("| mode | walls (-y / +y side) | floor | floor+ | loaded particles | notes |")
    print("| --- | --- | --- | --- | --- | --- |")
    for cpd in (2, 4, 8):
        f = wl.lamp_forces(scene.centers, scene.radii, P, cells_per_diameter=cpd, device="cpu")
        loaded = int(np.any(f != 0, axis=1).sum())
        lamp = wl.lamp_update(scene.centers, scene.radii, cells_per_diameter=cpd, device="cpu")
        print(
            row(
                f'"first", {cpd} cells/d',
                ratios(scene, f),
                int(lamp.diagnostics().surface.sum()),
                f"{loaded:,} with F != 0",
            )
        )
    rhos = [(f"{x:g}", x) for x in (0.1, 0.225, 0.45, 0.9)]
    rhos += [(f"{k:g} r_mean = {k * rmean:.4f}", k * rmean) for k in (0.25, 0.5, 1.0, 2.0)]
    for label, rho in rhos:
        grid = wl.LampGrid.enclosing(
            scene.centers, scene.radii, cells_per_diameter=args.cells, margin=2.0 * rmean + rho
        )
        t0 = time.perf_counter()
        surf = wetted_solve(scene.centers, scene.radii, probe_radius=rho, grid=grid, device="cpu")
        d = surf.diagnostics(P)
        t1 = time.perf_counter()
        fk = d.counts * pressure_area(P, grid)
        assert np.all(d.force == 0) and d.unattributed == 0
        note = f"kernels {t1 - t0:.2f} s CPU, {surf.shape[0]}x{surf.shape[1]}x{surf.shape[2]} voxels, {d.rounds} rounds"
        if not args.no_reference:
            ref = wetted_reference(scene.centers, scene.radii, grid, probe_radius=rho)
            t2 = time.perf_counter()
            fr = ref.counts * pressure_area(P, grid)
            same = np.array_equal(ref.counts, d.counts) and np.array_equal(ref.fluid, d.fluid)
            amb = int(ref.allowed_ambiguous.sum())
            ties = int(sum(ref.crossings[a]["near_tie"].sum() for a in range(3)))
            worst = max(float(ref.crossings[a]["distance"].max() / ref.bound[a]) for a in range(3))
            print(
                row(
                    f"all, rho {label} (reference)",
                    ratios(scene, fr),
                    int((ref.hits > 0).sum()),
                    f"reference {t2 - t1:.1f} s; kernels equal: {same}; ambiguous voxels {amb}, near ties {ties}; "
                    f"max nearest distance / bound {worst:.2f}",
                )
            )
        print(row(f"all, rho {label} (kernels)", ratios(scene, fk), int(d.surface.sum()), note))


if __name__ == "__main__":
    main()
