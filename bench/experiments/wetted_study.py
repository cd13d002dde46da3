"""Shared by the studies of the exact test's work on the float64 reference (``wetted_work_count.py``,
``wetted_reach_first.py``, ``wetted_reach_masks.py``): the reference run on a named scene, with a hook that sees
every tested voxel, and the candidates' spheres of a test as the reference chooses them."""

import argparse
import time

import numpy as np

import warp_lamp as wl
from warp_lamp.reference import wetted as R
from warp_lamp.scenes import scene_lattice_box, scene_slot_block, scene_sphere_specimen

SCENES = {"specimen": scene_sphere_specimen, "slot": scene_slot_block, "small": lambda: scene_lattice_box(12)}


def near_exposed(exact, x):
    """(near, ids): the spheres within r_max + 2 rho + diagonal of x (the searches' list), and the exposed ones
    among them within r + 2 rho (with slack) that can carry a candidate within rho of x, in increasing index."""
    rho = exact.rho
    near = exact._near(x, exact.rmax + 2.0 * rho + exact.diag)
    v = x - exact.c[near]
    d2 = R._dot(v, v)
    g = (exact.r[near] + 2.0 * rho) * (1.0 + R.SLACK)
    return near, near[exact.exposed[near] & (d2 <= g * g)]


def run_reference(scene: str, rho_diameters: float, hook) -> tuple:
    """Run the reference on ``scene`` at 4 cells per diameter with rho = ``rho_diameters`` mean diameters, calling
    ``hook(exact, x)`` for every voxel it tests exactly; (the scene, rho, seconds)."""
    sc = SCENES[scene]()
    rho = rho_diameters * 2.0 * float(sc.radii.mean())
    grid = wl.LampGrid.enclosing(sc.centers, sc.radii, cells_per_diameter=4, margin=2.0 * float(sc.radii.mean()) + rho)
    original = R._Exact.fluid

    def fluid(self, x, lattice):
        hook(self, x)
        return original(self, x, lattice)

    R._Exact.fluid = fluid
    try:
        t = time.perf_counter()
        R.wetted_reference(sc.centers, sc.radii, grid, probe_radius=rho)
        return sc, rho, time.perf_counter() - t
    finally:
        R._Exact.fluid = original


def percentiles(values) -> np.ndarray:
    """Median, p90, p99, p99.9 and max."""
    return np.percentile(np.asarray(values), [50, 90, 99, 99.9, 100])


def study_main(hook) -> tuple:
    """A study's command line (``--scene``, ``--rho-diameters``), then :func:`run_reference` with ``hook``;
    (the arguments, the scene, rho, seconds)."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="specimen", choices=sorted(SCENES))
    ap.add_argument("--rho-diameters", type=float, default=0.5)
    args = ap.parse_args()
    return (args, *run_reference(args.scene, args.rho_diameters, hook))
