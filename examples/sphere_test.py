"""The memo's SphereTest in a minimal Warp DEM: a 100 mm ball of 5 mm particles held by a 10 MPa shining lamp.

    python examples/sphere_test.py                      # the four resolutions to 40,000 cycles, on a GPU
    python examples/sphere_test.py --cells 4 --steps 3000 --device cpu

On a CPU, with neither --cells nor --steps given, it runs the CI's CPU size instead (2 cells per diameter, 2,500
cycles: minutes) and says so: the full study is about 160,000 cycles, days on a CPU.

The DEM is ``examples/dem.py`` (shared with ``triaxial.py``): spheres with linear normal and shear springs,
Coulomb friction, PFC local damping and rotations; no bonds (the pressure holds the body together). Contact
stiffness from the memo's Table 1 (E_c = 100 GPa, kn/ks = 3.7, mu = 0.5): each ball has kn = 4 E_c R and a
contact the series combination of its balls'. Density scaling (mass from stiffness, unit time step) reaches
static equilibrium in a few thousand cycles; statics do not depend on mass.

The state is float64: at 10 MPa the contacts overlap by about 3e-7 m, below float32's resolution at 5 cm, and the
equilibrium test (mean unbalanced force under 1e-5 of the mean contact force) needs the digits. The lamp takes a
float32 copy of the positions relative to the specimen's centre, as a simulator hands it Warp arrays.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.scenes import scene_sphere_specimen


def _sibling(name: str):
    """Import a sibling example by path: examples/ is no package, and the tests load examples by file."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


dem = _sibling("dem")

MASS_SCALE = 4.0  # mass / ball stiffness at dt = 1: critical step ~1.6
E_C = 100e9  # contact modulus [Pa]
KN_KS = 3.7
MU = 0.5
DAMPING = 0.7


class SphereTest:
    """The DEM, the lamp inside it, and the measurement sphere."""

    def __init__(
        self, cells_per_diameter: float = 4, *, pressure: float = 10e6, update_every: int = 1, device=None, scene=None
    ):
        self.device = wp.get_device(device)
        d = self.device
        self.scene = scene or scene_sphere_specimen()
        s = self.scene
        self.n = s.n
        self.update_every = update_every
        self.pressure = pressure
        # Density scaling: masses from stiffness at a unit time step, so that every particle's critical step
        # (2 / sqrt(sum k / m) with ~12 contacts of stiffness 2 E_c R) stays above 1 with a margin; rotational
        # inertia likewise. Statics do not depend on mass, and equal critical steps make equilibrium come fast.
        kn_ball = 4.0 * E_C * s.radii
        m = MASS_SCALE * kn_ball
        mat = dem.material(E_C, kn_ks=KN_KS, mu=MU, damping=DAMPING)
        self.dem = dem.Dem(s.centers, s.radii, m, 0.4 * m * s.radii**2 * 2.0, mat, 1.0, frame_center=s.center, device=d)
        self.lamp_force = wp.zeros(self.n, dtype=wp.vec3, device=d)
        grid = wl.LampGrid.enclosing(s.centers - s.center, s.radii, cells_per_diameter=cells_per_diameter)
        self.lamp = wl.ShiningLamp(grid, device=d)
        self.lamp.reserve(self.n)

    @property
    def cycle(self) -> int:
        return self.dem.cycle

    @property
    def x(self) -> wp.array:
        """Particle centres [m], float64, on the device."""
        return self.dem.x

    def step(self, *, lamp_update: bool = True, lamp: bool = True) -> None:
        """One DEM cycle; swaps the contact slot buffers by parity, so two cycles form a capturable pair.
        ``lamp=False`` leaves the lamp out altogether (to time its share)."""
        sim = self.dem
        sim.begin()
        if lamp:
            self.lamp_force.zero_()
            if lamp_update:
                self.lamp.update(sim.pos32, sim.radius32)
            self.lamp.add_forces(self.lamp_force, self.pressure)
        sim.contacts()
        sim.integrate(self.lamp_force)

    def time_cycle(self, repeats: int = 20) -> dict:
        """Seconds per cycle from graph replays (CUDA), with and without the lamp."""
        out = {}
        for name, with_lamp in (("cycle_s", True), ("cycle_without_lamp_s", False)):
            graph = self.capture(with_lamp=with_lamp)
            out[name] = dem.median_gpu_time(lambda g=graph: wp.capture_launch(g), self.device, repeats) / 2
        out["lamp_share"] = 1.0 - out["cycle_without_lamp_s"] / out["cycle_s"]
        return out

    def capture(self, *, with_lamp: bool = True):
        """Record two cycles (the slot buffers swap by parity) in one CUDA graph: neighbour build, contacts,
        the lamp's update and forces, integration. ``with_lamp=False`` leaves the lamp out, to time its share."""
        return self.dem.capture(lambda: self.step(lamp=with_lamp), 2)

    def run(self, max_cycles: int, *, tol: float = 1e-5, check_every: int = 100, verbose: bool = False) -> dict:
        """Cycle until the mean unbalanced force ratio is below ``tol`` (checked every ``check_every``). On CUDA
        with the lamp updated every cycle, the cycles replay a captured graph."""
        ratio = np.inf
        t0 = time.perf_counter()
        graph = None
        if self.device.is_cuda and self.update_every == 1:
            self.step()
            self.step()  # load the kernels and fill the lamp before recording
            graph = self.capture()
        while self.cycle < max_cycles:
            if graph is not None:
                for _ in range(check_every // 2):
                    wp.capture_launch(graph)
                self.dem.cycle += 2 * (check_every // 2)
            else:
                for _ in range(check_every):
                    self.step(lamp_update=self.cycle % self.update_every == 0)
            ratio = self.unbalanced_ratio()
            if verbose:
                print(f"  cycle {self.cycle:6d}  unbalanced ratio {ratio:.3e}", flush=True)
            if ratio < tol:
                break
        return {"cycles": self.cycle, "ratio": ratio, "seconds": time.perf_counter() - t0}

    def unbalanced_ratio(self) -> float:
        """Mean resultant force on the particles over mean contact normal force (PFC's ratio)."""
        return self.dem.unbalanced_ratio()

    def measure(self, diameter: float = 0.09) -> np.ndarray:
        """Stress [Pa] in a measurement sphere at the centre, PFC's formula, compression positive:
        sigma = -(1 - n) / sum V_p * sum_p sum_c (x_c - x_p) (x) F_c,p over particles whose centres lie inside,
        n the porosity of the measurement sphere (particle volume inside it, lens-exact)."""
        return self.dem.sphere_stress(self.scene.center, diameter)


#: The full study: four resolutions, to 40,000 cycles each (a GPU run).
FULL_CELLS, FULL_STEPS = [2.0, 4.0, 8.0, 16.0], 40000
#: What a CPU runs when not told otherwise: the CI's size.
CPU_CELLS, CPU_STEPS = [2.0], 2500


def run_size(device, cells, steps) -> tuple[list, int, str | None]:
    """The resolutions and cycles to run: those given, else the full study on a GPU and the CI's size on a CPU,
    with a note saying so (None when nothing was chosen for the user)."""
    if cells is not None or steps is not None or wp.get_device(device).is_cuda:
        return cells or FULL_CELLS, steps or FULL_STEPS, None
    note = (
        f"sphere_test: on a CPU, {CPU_CELLS[0]:g} cells per diameter and {CPU_STEPS:,} cycles (minutes); the full "
        f"study (--cells 2 4 8 16 --steps {FULL_STEPS}) takes days on a CPU and minutes on a GPU"
    )
    return CPU_CELLS, CPU_STEPS, note


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cells", type=float, nargs="*", default=None, help="cells per mean diameter (2 4 8 16)")
    parser.add_argument("--steps", type=int, default=None, help="most cycles per run (40,000)")
    parser.add_argument("--update-every", type=int, default=1, help="lamp update every n cycles (ct_pressrate)")
    parser.add_argument("--device", default=None)
    parser.add_argument("--json", default=None, help="write the table as JSON")
    args = parser.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    args.cells, args.steps, note = run_size(args.device, args.cells, args.steps)
    if note:
        print(note, file=sys.stderr, flush=True)
    rows = []
    for k in args.cells:
        test = SphereTest(k, update_every=args.update_every, device=args.device)
        info = test.run(args.steps, verbose=True, check_every=500 if test.device.is_cuda else 100)
        if test.device.is_cuda:
            info.update(test.time_cycle())
            print(f"  {info['cycle_s'] * 1e6:.1f} us per cycle, lamp {info['lamp_share']:.0%} of it", flush=True)
        sigma = test.measure() / 1e6
        off = max(abs(sigma[0, 1]), abs(sigma[0, 2]), abs(sigma[1, 2]))
        mean = np.trace(sigma) / 3
        rows.append((k, sigma[0, 0], sigma[1, 1], sigma[2, 2], off, mean, info))
        print(f"d/{k:g}: {info['cycles']} cycles, ratio {info['ratio']:.1e}, {info['seconds']:.1f} s", flush=True)
    print("\n| cells per diameter | sxx MPa | syy MPa | szz MPa | max off-diagonal MPa | mean MPa | cycles | ratio |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for k, sxx, syy, szz, off, mean, info in rows:
        print(
            f"| {k:g} | {sxx:.2f} | {syy:.2f} | {szz:.2f} | {off:.3f} | {mean:.2f} | {info['cycles']} | "
            f"{info['ratio']:.1e} |"
        )
    if args.json:
        import json

        with open(args.json, "w") as f:
            json.dump(
                [
                    {
                        "cells_per_diameter": k,
                        "sxx": a,
                        "syy": b,
                        "szz": c,
                        "max_offdiag": o,
                        "mean": mm,
                        **{key: val for key, val in info.items()},
                    }
                    for k, a, b, c, o, mm, info in rows
                ],
                f,
                indent=1,
            )


if __name__ == "__main__":
    main()
