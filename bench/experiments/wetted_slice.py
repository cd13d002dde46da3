"""A picture of what each mode loads: one x-slice of the slot block, "first" beside "all" (the wetted surface).
The slot block is a lattice of spacing 1 with radii in [0.4, 0.5], without a physical unit: lengths are labelled
in lattice spacings.

Left: the first-surface lamp. Each dot is where a +-y or +-z lamp ray first meets a sphere in the slice's plane
(the memo's Figures 10-14, as a slice). Right: the wetted-surface mode with rho = one mean radius: blue voxels are
fluid, each dot a loaded crossing on a y or z ray. Grey circles: the spheres cut by the plane.

    PYTHONPATH=$PWD python bench/experiments/wetted_slice.py --out docs/wetted_slice.png
"""

import argparse

import numpy as np
import warp as wp
from wetted_checks import wetted_solve

import warp_lamp as wl
from warp_lamp.scenes import scene_slot_block


def figure(scene, cells: float = 4.0, *, unit: str = "lattice spacings", window=((6, 24), (6, 21))):
    """The two panels for a cut block ``scene`` at ``cells`` per mean diameter, lengths labelled in ``unit`` (the
    scene's own: the slot block is a lattice of spacing 1, no physical unit); ``window`` the (y, z) ranges shown,
    or None for all. Returns the figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    wp.config.log_level = wp.LOG_WARNING
    rho = float(scene.radii.mean())
    grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cells, margin=2.0 * rho + rho)
    surf = wetted_solve(scene.centers, scene.radii, probe_radius=rho, grid=grid, keep_owners=True, device="cpu")
    d = surf.diagnostics()
    lamp = wl.lamp_update(scene.centers, scene.radii, grid=grid, device="cpu").diagnostics()
    n, h, o = np.array(surf.shape), surf.h, grid.origin
    ix = int(n[0] // 2)
    x0 = o[0] + (ix + 0.5) * h[0]
    ys = o[1] + (np.arange(n[1]) + 0.5) * h[1]
    zs = o[2] + (np.arange(n[2]) + 0.5) * h[2]
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2), sharey=True)
    for ax in axes:
        for c, r in zip(scene.centers, scene.radii, strict=True):
            if abs(c[0] - x0) < r:
                ax.add_patch(Circle((c[1], c[2]), np.sqrt(r * r - (c[0] - x0) ** 2), color="0.75", lw=0))
        ax.set_aspect("equal")
        ax.set_xlabel(f"y [{unit}]")
    axes[0].set_ylabel(f"z [{unit}]")
    # "first": where each y ray (grid 1 spans (z, x)) and z ray (grid 2 spans (x, y)) meets its owner.
    for name, color in (("-y", "tab:red"), ("+y", "tab:orange")):
        dep = lamp.depths[name][:, ix]
        axes[0].plot(dep, zs, ".", ms=2.5, color=color, label=f"{name} lamp")
    for name, color in (("-z", "tab:green"), ("+z", "tab:blue")):
        dep = lamp.depths[name][ix, :]
        axes[0].plot(ys, dep, ".", ms=2.5, color=color, label=f"{name} lamp")
    axes[0].set_title('"first": what each lamp sees first')
    fl = d.fluid[ix].T  # (z, y)
    ext = (o[1], o[1] + n[1] * h[1], o[2], o[2] + n[2] * h[2])
    axes[1].imshow(fl, origin="lower", extent=ext, cmap="Blues", vmin=0, vmax=2.5, interpolation="nearest")
    own_y = d.owners[1][:, ix, :]  # (z, face along y)
    kz, fy = np.nonzero(own_y >= 0)
    axes[1].plot(o[1] + fy * h[1], zs[kz], ".", ms=2.5, color="tab:red", label="y crossings")
    own_z = d.owners[2][ix, :, :]  # (y, face along z)
    jy, fz = np.nonzero(own_z >= 0)
    axes[1].plot(ys[jy], o[2] + fz * h[2], ".", ms=2.5, color="tab:green", label="z crossings")
    axes[1].set_title(f'"all", \u03c1 = {rho:.3f} (one mean radius): fluid voxels and every crossing')
    for ax in axes:
        if window is not None:
            ax.set_xlim(*window[0])
            ax.set_ylim(*window[1])
        ax.legend(loc="lower left", fontsize=8, markerscale=3)
    fig.suptitle(f"{scene.name}: slice x = {x0:.2f}, {cells:g} cells per diameter; lengths in {unit}")
    fig.tight_layout()
    return fig


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="wetted_slice.png")
    ap.add_argument("--cells", type=float, default=4.0)
    args = ap.parse_args()
    fig = figure(scene_slot_block(), args.cells)
    fig.savefig(args.out, dpi=110)
    print(args.out)


if __name__ == "__main__":
    main()
