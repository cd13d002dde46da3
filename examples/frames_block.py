"""Why the lamp frame matters: the README's turned block (``warp-lamp bench``'s frames section), a jittered
20 x 20 x 20 block turned by 10, 20 and 30 degrees about x, y and z, loaded by an axis-aligned lamp and by a lamp
turned with it. Prints the mean and 90th percentile, over the interiors of all six faces, of the angle between
each face particle's force and the face's inward normal (the README's table), and draws it on the +z face.

    python examples/frames_block.py                     # the two rows, at 4 cells per diameter
    pip install ".[plot]" && python examples/frames_block.py --out docs/frames_block.png

The experiment is :func:`warp_lamp.bench.modes.frames_block_case`, the benchmark's own, so that the picture and
the table are one experiment with one number.
"""

import argparse
import sys

import numpy as np
import warp as wp

from warp_lamp.bench.modes import BLOCK_ROTATION_DEG, frames_block_case

N = 20  # spheres per block edge
CASES = {"axis-aligned lamp": False, "lamp turned with the block": True}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default=None, help="PNG of the +z face (needs the plot extra)")
    parser.add_argument("--cells-per-diameter", type=float, default=4)
    parser.add_argument("--device", default=None)
    args = parser.parse_args(argv)
    if args.out:
        try:
            import matplotlib
        except ImportError:
            sys.exit("--out needs matplotlib: pip install '.[plot]' in a clone, or pip install 'warp-lamp[plot]'")
    wp.config.log_level = wp.LOG_WARNING
    results = {}
    for name, turned in CASES.items():
        case = frames_block_case(lamp_turned=turned, cells_per_diameter=args.cells_per_diameter, device=args.device)
        results[name] = case
        print(
            f"{name:<28} mean {case['mean_deg']:5.2f} deg, p90 {case['p90_deg']:5.2f} deg ({case['loaded']} particles)"
        )
    if args.out:
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(10, 4.6), sharey=True, constrained_layout=True)
        for ax, (name, case) in zip(axes, results.items(), strict=True):
            index, f, rot = case["index"], case["forces"], case["rotation"]
            face = case["select"] & (index[:, 2] == N - 1) & (np.linalg.norm(f, axis=1) > 0)
            normal = -rot[:, 2]
            cosine = f[face] @ normal / np.linalg.norm(f[face], axis=1)
            angle = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
            sc = ax.scatter(index[face, 0], index[face, 1], c=angle, s=60, cmap="viridis", vmin=0, vmax=25)
            ax.set_title(f"{name}\nall faces: mean {case['mean_deg']:.2f}\u00b0, p90 {case['p90_deg']:.2f}\u00b0")
            ax.set_xlabel("lattice index along the block's x")
            ax.set_aspect("equal")
        axes[0].set_ylabel("lattice index along the block's y")
        fig.colorbar(sc, ax=axes, label="angle between force and inward face normal [\u00b0]")
        turn = "/".join(f"{d:g}" for d in BLOCK_ROTATION_DEG)
        fig.suptitle(
            f"Block {N}\u00b3 turned {turn}\u00b0 about x/y/z: its +z face, {args.cells_per_diameter:g} cells/d"
        )
        fig.savefig(args.out, dpi=110)
        print(f"wrote {args.out}")
    return results


if __name__ == "__main__":
    main()
