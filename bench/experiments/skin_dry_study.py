"""Why the skin leaves dry voxels uncertified (the specimen's floor at rest): CPU, reference geometry.

For the SphereTest specimen at 4 cells per diameter, rho = r-bar, one skinned update on the CPU; every dry-tested
voxel without a certificate is sampled and sorted by the float64 reference (``reference.wetted.dry_certificate``):
- *thin*: its rho-ball is covered by the inflated balls (certificate with no shrink) but not by the balls shrunk by
  the skin: a smaller skin would certify it;
- *unreachable*: some point within rho of it is free of every inflated ball, so it is dry only because no reached
  probe position comes near: no coverage certificate can hold it, whatever the skin.
Also the certified counts at smaller skins. Prints a table; ``--out`` writes JSON.

    PYTHONPATH=$PWD python bench/experiments/skin_dry_study.py --sample 300
"""

import argparse
import json

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.reference.wetted import dry_certificate
from warp_lamp.scenes import scene_sphere_specimen
from warp_lamp.wetted import WettedSurface, unpack_bits


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sample", type=int, default=300)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.config.quiet = True
    wp.init()
    scene = scene_sphere_specimen()
    rbar = float(scene.radii.mean())
    rho = rbar
    grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=4, margin=2.0 * rbar + rho)
    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device="cpu")
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device="cpu")
    h = float(grid.cell[0, 0])
    rows = {}
    for frac in (0.1, 0.05, 0.02):
        s = WettedSurface(grid, probe_radius=rho, device="cpu", skin=frac * h)
        s.update(pos, rad)
        d = s.diagnostics()
        rows[frac] = {"skin_m": s.skin, "dry_tested": int(d.uncertain - d.rescued), "certified": int(d.skin_certified)}
        if frac == 0.1:
            solid = unpack_bits(s.solid.numpy(), s.shape)
            kept = unpack_bits(s.kept.numpy(), s.shape)
            dry = d.band & ~d.fluid & ~solid & ~kept
            ijk = np.argwhere(dry)
            rng = np.random.default_rng(1)
            pick = ijk[rng.choice(len(ijk), min(args.sample, len(ijk)), replace=False)]
            c = pos.numpy().astype(np.float64)
            r = rad.numpy().astype(np.float64)
            thin = sum(dry_certificate((p + 0.5) * s.h, c, r, rho, 0.0) for p in pick)
            rows["uncertified"] = {"count": len(ijk), "sampled": len(pick), "thin": int(thin)}
    u = rows["uncertified"]
    print(f"specimen, rho = rbar, h = {h:.4g} m: {u['count']} dry-tested voxels uncertified at skin 0.1 h")
    print(
        f"  sampled {u['sampled']}: thin (covered, not by the shrunk balls) {u['thin']}, "
        f"unreachable (a free point within rho) {u['sampled'] - u['thin']}"
    )
    print("| skin [h] | dry tested | certified |")
    print("| --- | --- | --- |")
    for frac in (0.1, 0.05, 0.02):
        print(f"| {frac} | {rows[frac]['dry_tested']} | {rows[frac]['certified']} |")
    if args.out:
        with open(args.out, "w") as f:
            json.dump({str(k): v for k, v in rows.items()}, f, indent=1)


if __name__ == "__main__":
    main()
