"""The memo's SphereTest in a minimal Warp DEM: a 100 mm ball of 5 mm particles held by a 10 MPa shining lamp.

    python examples/sphere_test.py                      # the four resolutions, on the default device
    python examples/sphere_test.py --cells 4 --steps 3000 --device cpu

Model only what the scene needs: spheres with linear normal and shear springs, Coulomb friction, PFC local
damping and rotations; neighbours from ``wp.HashGrid``; no bonds (the pressure holds the body together).
Contact stiffness from the memo's Table 1 (E_c = 100 GPa, kn/ks = 3.7, mu = 0.5): each ball has kn = 4 E_c R
and a contact the series combination of its balls'. Density scaling (mass from stiffness, unit time step)
reaches static equilibrium in a few thousand cycles; statics do not depend on mass.

The state is float64: at 10 MPa the contacts overlap by about 3e-7 m, below float32's resolution at 5 cm, and the
equilibrium test (mean unbalanced force under 1e-5 of the mean contact force) needs the digits. The lamp takes a
float32 copy of the positions relative to the specimen's centre, as a simulator hands it Warp arrays.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.scenes import scene_sphere_specimen

wp.set_module_options({"enable_backward": False})

MASS_SCALE = 4.0  # mass / ball stiffness at dt = 1: critical step ~1.6
SLOTS = 24  # contacts remembered per particle (a dense packing has about 6-12)
E_C = 100e9  # contact modulus [Pa]
KN_KS = 3.7
MU = 0.5
DAMPING = 0.7
DENSITY = 2620.0
# The same, as float64 constants for the kernels (a bare Python float is float32 there).
E_C_64 = wp.constant(wp.float64(E_C))
KN_KS_64 = wp.constant(wp.float64(KN_KS))
MU_64 = wp.constant(wp.float64(MU))
DAMPING_64 = wp.constant(wp.float64(DAMPING))


@wp.func
def find_slot(ids: wp.array2d[wp.int32], i: int, j: int) -> int:
    for s in range(SLOTS):
        if ids[i, s] == j:
            return s
    return -1


@wp.kernel(enable_backward=False)
def dem_contacts(
    grid: wp.uint64,
    x: wp.array[wp.vec3d],
    v: wp.array[wp.vec3d],
    w: wp.array[wp.vec3d],
    radius: wp.array[wp.float64],
    query: wp.float32,
    old_ids: wp.array2d[wp.int32],
    old_shear: wp.array2d[wp.vec3d],
    dt: wp.float64,
    # outputs
    new_ids: wp.array2d[wp.int32],
    new_shear: wp.array2d[wp.vec3d],
    force: wp.array[wp.vec3d],
    moment: wp.array[wp.vec3d],
    stats: wp.array[wp.float64],
):
    """One thread per particle gathers its contacts: linear springs, incremental shear with Coulomb's limit."""
    i = wp.tid()
    xi = x[i]
    ri = radius[i]
    f = wp.vec3d()
    m = wp.vec3d()
    slot = int(0)
    for s in range(SLOTS):
        new_ids[i, s] = -1
    q = wp.hash_grid_query(grid, wp.vec3(wp.float32(xi[0]), wp.float32(xi[1]), wp.float32(xi[2])), query)
    j = int(0)
    while wp.hash_grid_query_next(q, j):
        if j == i:
            continue
        d = x[j] - xi
        dist = wp.length(d)
        rj = radius[j]
        overlap = ri + rj - dist
        if overlap <= wp.float64(0.0) or dist == wp.float64(0.0):
            continue
        n = d / dist
        kn = wp.float64(4.0) * E_C_64 * ri * rj / (ri + rj)  # series of 4 E_c R_i and 4 E_c R_j
        ks = kn / KN_KS_64
        fn = kn * overlap
        # Velocity of j's surface relative to i's at the contact point.
        vc = (v[j] + wp.cross(w[j], -rj * n)) - (v[i] + wp.cross(w[i], ri * n))
        vt = vc - wp.dot(vc, n) * n
        fs = wp.vec3d()
        k = find_slot(old_ids, i, j)
        if k >= 0:
            fs = old_shear[i, k]
            fs = fs - wp.dot(fs, n) * n  # back into the current tangent plane
        fs = fs + ks * vt * dt
        limit = MU_64 * fn
        mag = wp.length(fs)
        if mag > limit:
            fs = fs * (limit / mag)
        f = f - fn * n + fs
        m = m + wp.cross(ri * n, fs)
        if slot < SLOTS:
            new_ids[i, slot] = j
            new_shear[i, slot] = fs
            slot += 1
        wp.atomic_add(stats, 1, fn)
        wp.atomic_add(stats, 2, wp.float64(0.5))  # each contact is seen from both sides
    force[i] = f
    moment[i] = m


@wp.kernel(enable_backward=False)
def dem_integrate(
    lamp_force: wp.array[wp.vec3],
    mass: wp.array[wp.float64],
    inertia: wp.array[wp.float64],
    dt: wp.float64,
    force: wp.array[wp.vec3d],
    moment: wp.array[wp.vec3d],
    # outputs
    x: wp.array[wp.vec3d],
    v: wp.array[wp.vec3d],
    w: wp.array[wp.vec3d],
    stats: wp.array[wp.float64],
):
    """Local non-viscous damping (PFC): each component loses alpha |F| against its velocity; then Euler steps."""
    i = wp.tid()
    fl = lamp_force[i]
    f = force[i] + wp.vec3d(wp.float64(fl[0]), wp.float64(fl[1]), wp.float64(fl[2]))
    wp.atomic_add(stats, 0, wp.length(f))
    m = moment[i]
    vi = v[i]
    wi = w[i]
    for a in range(3):
        f[a] = f[a] - DAMPING_64 * wp.abs(f[a]) * wp.sign(vi[a])
        m[a] = m[a] - DAMPING_64 * wp.abs(m[a]) * wp.sign(wi[a])
    vi = vi + f / mass[i] * dt
    wi = wi + m / inertia[i] * dt
    v[i] = vi
    w[i] = wi
    x[i] = x[i] + vi * dt


@wp.kernel(enable_backward=False)
def to_lamp_frame(
    x: wp.array[wp.vec3d],
    center: wp.vec3d,
    # outputs
    out: wp.array[wp.vec3],
):
    i = wp.tid()
    p = x[i] - center
    out[i] = wp.vec3(wp.float32(p[0]), wp.float32(p[1]), wp.float32(p[2]))


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
        self.x = wp.array(s.centers, dtype=wp.vec3d, device=d)
        self.v = wp.zeros(self.n, dtype=wp.vec3d, device=d)
        self.w = wp.zeros(self.n, dtype=wp.vec3d, device=d)
        self.radius = wp.array(s.radii, dtype=wp.float64, device=d)
        self.radius32 = wp.array(s.radii.astype(np.float32), dtype=wp.float32, device=d)
        # Density scaling: masses from stiffness at a unit time step, so that every particle's critical step
        # (2 / sqrt(sum k / m) with ~12 contacts of stiffness 2 E_c R) stays above 1 with a margin; rotational
        # inertia likewise. Statics do not depend on mass, and equal critical steps make equilibrium come fast.
        kn_ball = 4.0 * E_C * s.radii
        m = MASS_SCALE * kn_ball
        self.mass = wp.array(m, dtype=wp.float64, device=d)
        self.inertia = wp.array(0.4 * m * s.radii**2 * 2.0, dtype=wp.float64, device=d)
        self.dt = 1.0
        self.ids = [wp.full((self.n, SLOTS), -1, dtype=wp.int32, device=d) for _ in range(2)]
        self.shear = [wp.zeros((self.n, SLOTS), dtype=wp.vec3d, device=d) for _ in range(2)]
        self.force = wp.zeros(self.n, dtype=wp.vec3d, device=d)
        self.moment = wp.zeros(self.n, dtype=wp.vec3d, device=d)
        self.stats = wp.zeros(3, dtype=wp.float64, device=d)
        self.grid = wp.HashGrid(32, 32, 32, device=d)
        self.grid.reserve(self.n)
        self.query = float(2.0 * s.radii.max())
        self.center = wp.vec3d(*s.center)
        self.pos32 = wp.zeros(self.n, dtype=wp.vec3, device=d)
        self.lamp_force = wp.zeros(self.n, dtype=wp.vec3, device=d)
        grid = wl.LampGrid.enclosing(s.centers - s.center, s.radii, cells_per_diameter=cells_per_diameter)
        self.lamp = wl.ShiningLamp(grid, device=d)
        self.lamp.reserve(self.n)
        self.cycle = 0

    def step(self, *, lamp_update: bool = True, lamp: bool = True) -> None:
        """One DEM cycle; swaps the contact slot buffers by parity, so two cycles form a capturable pair.
        ``lamp=False`` leaves the lamp out altogether (to time its share)."""
        d = self.device
        k = self.cycle % 2
        self.stats.zero_()
        wp.launch(to_lamp_frame, dim=self.n, inputs=[self.x, self.center], outputs=[self.pos32], device=d)
        if lamp:
            self.lamp_force.zero_()
            if lamp_update:
                self.lamp.update(self.pos32, self.radius32)
            self.lamp.add_forces(self.lamp_force, self.pressure)
        self.grid.build(self.x_f32(), self.query)
        wp.launch(
            dem_contacts,
            dim=self.n,
            inputs=[self.grid.id, self.x, self.v, self.w, self.radius, self.query, self.ids[k], self.shear[k], self.dt],
            outputs=[self.ids[1 - k], self.shear[1 - k], self.force, self.moment, self.stats],
            device=d,
        )
        wp.launch(
            dem_integrate,
            dim=self.n,
            inputs=[self.lamp_force, self.mass, self.inertia, self.dt, self.force, self.moment],
            outputs=[self.x, self.v, self.w, self.stats],
            device=d,
        )
        self.cycle += 1

    def time_cycle(self, repeats: int = 20) -> dict:
        """Seconds per cycle from graph replays (CUDA), with and without the lamp."""
        from warp_lamp.timing import time_median_events

        out = {}
        for name, with_lamp in (("cycle_s", True), ("cycle_without_lamp_s", False)):
            graph = self.capture(with_lamp=with_lamp)
            out[name] = time_median_events(lambda g=graph: wp.capture_launch(g), self.device, repeats=repeats) / 2
        out["lamp_share"] = 1.0 - out["cycle_without_lamp_s"] / out["cycle_s"]
        return out

    def x_f32(self) -> wp.array:
        # The hash grid takes float32 points: the lamp's frame copy plus the centre would do, but the grid only
        # bins, so the frame copy itself (shifted by a constant) is enough.
        return self.pos32

    def capture(self, *, with_lamp: bool = True):
        """Record two cycles (the slot buffers swap by parity) in one CUDA graph: neighbour build, contacts,
        the lamp's update and forces, integration. ``with_lamp=False`` leaves the lamp out, to time its share."""
        assert self.cycle % 2 == 0
        with wp.ScopedCapture(device=self.device) as cap:
            for _ in range(2):
                self.step(lamp=with_lamp)
        self.cycle -= 2  # recording ran no cycle
        return cap.graph

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
                self.cycle += 2 * (check_every // 2)
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
        sum_unbalanced, sum_contact, contacts = self.stats.numpy()
        return float((sum_unbalanced / self.n) / (sum_contact / (2 * contacts))) if contacts else np.inf

    def measure(self, diameter: float = 0.09) -> np.ndarray:
        """Stress [Pa] in a measurement sphere at the centre, PFC's formula, compression positive:
        sigma = -(1 - n) / sum V_p * sum_p sum_c (x_c - x_p) (x) F_c,p over particles whose centres lie inside,
        n the porosity of the measurement sphere (particle volume inside it, lens-exact)."""
        x = self.x.numpy() - self.scene.center
        r = self.radius.numpy()
        R = diameter / 2
        inside = np.linalg.norm(x, axis=1) < R
        ids = self.ids[self.cycle % 2].numpy()
        shear = self.shear[self.cycle % 2].numpy()
        total = np.zeros((3, 3))
        for p in np.flatnonzero(inside):
            for s in range(SLOTS):
                q = ids[p, s]
                if q < 0:
                    continue
                d = x[q] - x[p]
                dist = np.linalg.norm(d)
                nrm = d / dist
                kn = 4.0 * E_C * r[p] * r[q] / (r[p] + r[q])
                f = -kn * (r[p] + r[q] - dist) * nrm + shear[p, s]
                branch = (r[p] - 0.5 * (r[p] + r[q] - dist)) * nrm
                total += np.outer(branch, f)
        vol = 4.0 / 3.0 * np.pi * r**3
        # Particle volume inside the measurement sphere: whole balls, and lenses for those crossing its surface.
        dist = np.linalg.norm(x, axis=1)
        solid = 0.0
        for di, ri, vi in zip(dist, r, vol, strict=True):
            if di + ri <= R:
                solid += vi
            elif di < R + ri:
                solid += _lens(R, ri, di)
        porosity = 1.0 - solid / (4.0 / 3.0 * np.pi * R**3)
        # Compression positive, as the memo reports its 9.6 MPa: forces on p push from the contact toward p.
        sigma = -(1.0 - porosity) / vol[inside].sum() * total
        return 0.5 * (sigma + sigma.T)


def _lens(R: float, r: float, d: float) -> float:
    """Volume of the intersection of balls of radii R and r with centres d apart (they overlap, neither inside)."""
    return np.pi * (R + r - d) ** 2 * (d * d + 2 * d * r - 3 * r * r + 2 * d * R + 6 * r * R - 3 * R * R) / (12 * d)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cells", type=float, nargs="*", default=[2, 4, 8, 16], help="cells per mean diameter")
    parser.add_argument("--steps", type=int, default=40000, help="most cycles per run")
    parser.add_argument("--update-every", type=int, default=1, help="lamp update every n cycles (ct_pressrate)")
    parser.add_argument("--device", default=None)
    parser.add_argument("--json", default=None, help="write the table as JSON")
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_WARNING
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
