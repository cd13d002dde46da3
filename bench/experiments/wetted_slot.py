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
from wetted_checks import wetted_solve

import warp_lamp as wl
from warp_lamp.lamp import pressure_area
from warp_lamp.measures import slot_load_ratios
from warp_lamp.reference.wetted import wetted_reference
from warp_lamp.scenes import scene_slot_block

P = 1.0


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
                slot_load_ratios(scene, f, P),
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
                    slot_load_ratios(scene, fr, P),
                    int((ref.hits > 0).sum()),
                    f"reference {t2 - t1:.1f} s; kernels equal: {same}; ambiguous voxels {amb}, near ties {ties}; "
                    f"max nearest distance / bound {worst:.2f}",
                )
            )
        print(row(f"all, rho {label} (kernels)", slot_load_ratios(scene, fk, P), int(d.surface.sum()), note))


if __name__ == "__main__":
    main()
