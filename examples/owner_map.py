"""Draw the memo's Figures 10-14: where the +x, +y and +z lamps' rays meet the SphereTest specimen.

pip install ".[plot]" && python examples/owner_map.py --out docs/owner_map.png
"""

import argparse
import sys

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.scenes import scene_sphere_specimen

#: Each lamp drawn, and its colour.
LAMP_COLOURS = (("+x", "tab:red"), ("+y", "tab:green"), ("+z", "tab:blue"))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default="owner_map.png")
    parser.add_argument("--ratios", default="2,4,8,16", help="cells per mean diameter, one panel each")
    parser.add_argument("--device", default=None)
    args = parser.parse_args(argv)
    try:
        import matplotlib
    except ImportError:
        sys.exit("owner_map.py needs matplotlib: pip install '.[plot]' in a clone, or pip install 'warp-lamp[plot]'")

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    wp.config.log_level = wp.LOG_WARNING
    scene = scene_sphere_specimen()
    ratios = [float(k) for k in args.ratios.split(",")]
    fig = plt.figure(figsize=(4 * len(ratios), 4.6))
    for p, k in enumerate(ratios):
        lamp = wl.lamp_update(scene.centers, scene.radii, cells_per_diameter=k, device=args.device)
        d = lamp.diagnostics()
        ax = fig.add_subplot(1, len(ratios), p + 1, projection="3d")
        for name, color in LAMP_COLOURS:
            a = "xyz".index(name[1])
            u, v = lamp.grid.cell_centers(a)
            uu, vv = np.meshgrid(u, v, indexing="ij")
            depth = d.depths[name]
            pts = np.zeros((*depth.shape, 3))
            pts[..., a] = depth
            pts[..., (a + 1) % 3] = uu
            pts[..., (a + 2) % 3] = vv
            pts = pts[np.isfinite(depth)]
            pts = pts[np.all(pts >= 0, axis=1)] * 1e3
            ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=12.0 / k, c=color, depthshade=False, linewidths=0)
        ax.set_title(f"cell = d/{k:g}: {int(d.surface.sum())} lit particles", fontsize=9)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_zlabel("z [mm]")
        ax.view_init(elev=25, azim=45)
        ax.set_box_aspect((1, 1, 1))
    handles = [
        Line2D([], [], ls="", marker="o", color=color, label=f"where the {name} lamp's rays meet a sphere")
        for name, color in LAMP_COLOURS
    ]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=9, frameon=False)
    fig.suptitle("Shining lamp on the SphereTest specimen: the first sphere each lamp cell lights, positive octant")
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return fig


if __name__ == "__main__":
    main()
