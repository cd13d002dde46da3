"""Why the lamp frame matters: a jittered block turned by 10, 20 and 30 degrees about x, y and z, loaded by an
axis-aligned lamp and by a lamp turned with it. Draws the angle between each face particle's force and the face's
inward normal, on the block's +z face, and prints the mean and 90th percentile over the interiors of all six faces.

    pip install ".[plot]" && python examples/frames_block.py --out docs/frames_block.png
"""

import argparse

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.scenes import scene_lattice_box

N = 20  # spheres per block edge


def rotation_xyz(degrees) -> np.ndarray:
    """R = Rz Ry Rx for angles about x, y, z in degrees."""
    ax, ay, az = np.radians(degrees)
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def face_angles(index, forces, rot):
    """Per face (axis a, side s), the angle [deg] between the force of each loaded particle in the face's outer
    layer and interior (lattice index 2 .. N-3 on the other axes) and the face's inward normal (-s R e_a)."""
    out = {}
    for a in range(3):
        for side in (-1, 1):
            layer = index[:, a] == (0 if side < 0 else N - 1)
            others = [b for b in range(3) if b != a]
            interior = np.all((index[:, others] >= 2) & (index[:, others] <= N - 3), axis=1)
            pick = layer & interior & (np.linalg.norm(forces, axis=1) > 0)
            normal = -side * rot[:, a]
            f = forces[pick]
            cosine = f @ normal / np.linalg.norm(f, axis=1)
            out[(a, side)] = (np.flatnonzero(pick), np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default=None, help="PNG of the +z face (needs the plot extra)")
    parser.add_argument("--cells-per-diameter", type=float, default=4)
    parser.add_argument("--device", default=None)
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    scene = scene_lattice_box(N, seed=1)
    index = np.round(scene.centers).astype(int)
    rot = rotation_xyz((10, 20, 30))
    centers = (scene.centers - scene.center) @ rot.T
    cases = {
        "axis-aligned lamp": wl.LampGrid.enclosing(centers, scene.radii, cells_per_diameter=args.cells_per_diameter),
        "lamp turned with the block": wl.LampGrid.enclosing(
            centers, scene.radii, cells_per_diameter=args.cells_per_diameter, rotation=rot
        ),
    }
    results = {}
    for name, grid in cases.items():
        f = wl.lamp_forces(centers, scene.radii, 1.0, grid=grid, device=args.device)
        angles = face_angles(index, f, rot)
        every = np.concatenate([v[1] for v in angles.values()])
        results[name] = angles
        print(
            f"{name:<28} mean {every.mean():5.2f} deg, p90 {np.percentile(every, 90):5.2f} deg ({len(every)} particles)"
        )
    if args.out:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(10, 4.6), sharey=True, constrained_layout=True)
        for ax, (name, angles) in zip(axes, results.items(), strict=True):
            ids, ang = angles[(2, 1)]
            sc = ax.scatter(index[ids, 0], index[ids, 1], c=ang, s=60, cmap="viridis", vmin=0, vmax=25)
            every = np.concatenate([v[1] for v in angles.values()])
            ax.set_title(f"{name}\nall faces: mean {every.mean():.1f} deg, p90 {np.percentile(every, 90):.1f} deg")
            ax.set_xlabel("lattice index along the block's x")
            ax.set_aspect("equal")
        axes[0].set_ylabel("lattice index along the block's y")
        fig.colorbar(sc, ax=axes, label="angle between force and inward face normal [deg]")
        fig.suptitle(f"Block {N}^3 turned 10/20/30 deg about x/y/z: its +z face, {args.cells_per_diameter:g} cells/d")
        fig.savefig(args.out, dpi=110)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
