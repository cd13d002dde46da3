"""A drained triaxial test in a Warp DEM, the confining pressure applied by the shining lamp as a membrane.

    python examples/triaxial.py --plot triaxial.png --json triaxial.json      # 10,000 particles, GPU
    python examples/triaxial.py --quick --device cpu                          # 2,000 particles, minutes on a CPU

Specimen: a cylinder 50 mm across and 100 mm high (height = 2 x diameter) of N polydisperse spheres
(``scene_cylinder_specimen``: generated in Warp, cached), between two rigid platens (plane contacts). The DEM is
``examples/dem.py``: linear contacts, kn = 2 E_c R for equal balls, kn/ks = 3.7, mu = 0.5 (balls and platens),
real density 2650 kg/m^3, no mass scaling. E_c = 1 GPa gives a stiffness number kappa = kn / (sigma_3 d) =
E_c / sigma_3 = 1e4 at sigma_3 = 100 kPa: overlaps about 1e-4 d, the rigid-grain limit of the literature. Time
step: 0.29 sqrt(m / k) of the smallest ball (k = 2 E_c R), half the critical step of a ball with 12 contacts.
Damping: contact dashpots at 0.15 of critical throughout, PFC local damping 0.7 while consolidating only (see
LOCAL_DAMPING for why not in the compression).

Confinement: the lamp on the lateral surface, lamps -x +x -y +y on, -z +z off, at P = sigma_3, updated every
``update_every`` cycles (10 by default: at I = 5e-4 the bulging surface moves about 2e-4 of a cell between), on a
grid that follows the body inside the captured graph (:class:`FollowLamp`, ``ShiningLamp(follow=True)``): its
cell counts are a capacity fixed at the start, the specimen's box plus room to bulge (BULGE of the diameter
across, and one mean diameter on every side), and each update moves it by whole cells to keep the body centred.

Procedure: (1) isotropic consolidation: lamp at sigma_3, both platens servo-controlled to sigma_3, until both
platen stresses are within 1% of sigma_3 and the unbalanced-force ratio is below 1e-3; (2) drained axial
compression: bottom platen fixed, top platen at constant speed (constant engineering strain rate, reached by a
linear ramp over the first 0.25% of strain's worth of cycles) to 15% axial strain, the lamp holding sigma_3
throughout. The rate is set by the inertial number I = rate d sqrt(rho / sigma_3) (d the mean particle diameter,
rho the solid density): default 5e-4, quasi-static below 1e-3. A run takes about 0.15 / (rate dt) = 92 / I
compression cycles whatever N (dt and d scale together): 184,000 at I = 5e-4.

Measurements (every ``check_every`` cycles, on the host):

* Axial strain: eps_a = (H0 - H) / H0, H the platen gap, H0 at the end of consolidation.
* Volume, from the particles' lateral envelope: the platen gap is cut into slabs about two mean diameters high;
  in each, about the centroid of the particles whose centres lie in it, into sectors about two diameters wide at
  the perimeter; a sector's envelope radius is the largest rho_i + r_i of its particles (rho_i the centre's
  distance from the slab's axis); a slab's area is sum R_k^2 dtheta / 2, and V = sum area x slab height.
  eps_v = (V0 - V) / V0, compression positive. Mean area A = V / H.
* sigma_1 = mean of the two platen forces (each averaged over the cycles since the last sample) / A; deviator
  q = sigma_1 - sigma_3; peak friction angle sin phi = q / (q + 2 sigma_3) at the peak of q.
* The membrane's check, the lateral stress the lamp applies: sigma_lat = P (L_x + L_y) / (2 S_x + 2 S_y), where
  L_x is the area the two x lamps light (their lit cells times the cell area: P L_x is the force they push with,
  P A_cell per lit cell) and S_x the area of the specimen's silhouette seen along x (the union of all particles'
  projected disks on the y-z plane: exact interval unions on rows d/16 apart, float64). A uniform pressure pushes
  along x with P times the area projected normal to x, on each side, whatever the shape, so sigma_lat = P for an
  ideal membrane; the lamp departs from it by its cells (at a flat end, up to half a cell row) and by any part of
  the body outside its grid. Also reported, sigma_lat_net: the same with the net forces the particles receive,
  sum |f_x| + |f_y|; it is lower because a particle at the silhouette's rim takes both ends of some rays, whose
  pushes cancel (as a true pressure's would on that particle).
* Cross-check inside the specimen: the stress in a measurement sphere of 0.8 D at the centre (PFC's formula). It
  is not the platens' average: the outer layer of particles carries less axial stress than the core.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.scenes import scene_cylinder_specimen


def _sibling(name: str):
    """Import a sibling example by path: examples/ is no package, and the tests load examples by file."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


dem = _sibling("dem")

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

SIGMA_3 = 100e3  # confining pressure [Pa]
E_C = 1e9  # contact modulus [Pa]: kappa = E_c / sigma_3 = 1e4
DENSITY = 2650.0  # solid density [kg/m^3]
MU = 0.5  # friction coefficient, between balls and between balls and platens
DIAMETER = 0.05  # specimen diameter [m]; height twice that
LATERAL = ("-x", "+x", "-y", "+y")
#: Time step over sqrt(m / k) of the smallest ball against an equal ball (k = 2 E_c R): the critical step of a
#: ball with 12 such contacts is 2 / sqrt(12) = 0.58 of it, so this keeps a factor of two.
DT_FACTOR = 0.29
#: Damping. Local damping (PFC's, 0.7) settles the consolidation fast, but it acts on absolute velocities: in the
#: compression, where every particle moves, it becomes a drag of 0.7 sum |F_i| against the motion, which the top
#: platen must overcome (2,000 particles at I = 5e-3: top platen 2.6 times the bottom's stress). So it is on only
#: while consolidating; contact dashpots (frame-invariant) damp both phases.
LOCAL_DAMPING = 0.7
VISCOUS = 0.15
SERVO_GAIN = 0.5  # fraction of the platen's force error closed per cycle through its contacts' stiffness
SERVO_SPEED = 10.0  # the servo's fastest platen speed, in units of the compression speed
CONSOLIDATION_TOL = 0.01  # platen stresses within 1% of sigma_3 ...
RATIO_TOL = 1e-3  # ... and the unbalanced-force ratio below this, to end consolidation
#: The top platen's speed rises linearly over the cycles this axial strain takes at full speed, and over no fewer
#: than RAMP_CYCLES (about five crossings of the 10,000-particle specimen by the loading wave, which takes some 400
#: cycles): a sudden start sends a stress wave of rho c v through the specimen (measured at I = 5e-3 with a
#: 320-cycle ramp: the top platen at 2.8 times the bottom's stress at 0.05% strain). Peaks are taken after it.
RAMP_STRAIN = 0.0025
RAMP_CYCLES = 2000

_FORCE_SCALE_64 = wp.constant(wp.float64(dem.FORCE_SCALE))
_STIFFNESS_SCALE_64 = wp.constant(wp.float64(dem.STIFFNESS_SCALE))


def default_porosity(particles: int) -> float:
    """Porosity the cylinder specimen is packed at: near the densest that the overlap relaxation reaches below
    1% overlap, which rises as the walls take a larger share (0.40 at 10,000 particles, 0.44 at 300)."""
    return 0.38 + 0.35 * (1.8 / particles) ** (1.0 / 3.0)


@wp.kernel(enable_backward=False)
def platen_control(
    reaction: wp.array2d[wp.int64],
    target: wp.array[wp.float64],
    normal: wp.array[wp.vec3d],
    servo: wp.int32,
    speed: wp.float64,
    ramp: wp.int64,
    gain: wp.float64,
    max_step: wp.float64,
    dt: wp.float64,
    # outputs
    clock: wp.array[wp.int64],
    offset: wp.array[wp.float64],
    velocity: wp.array[wp.vec3d],
    total: wp.array[wp.float64],
):
    """One thread per platen moves it toward the specimen by a step [m]: with ``servo``, a Newton step through
    its contacts' stiffness toward the target force (``gain`` of it, at most ``max_step``; ``max_step`` when it
    touches nothing); without, the top platen (1) by ``speed`` (times clock / ``ramp`` over the first ``ramp``
    cycles that ``clock`` counts) and the bottom (0) not at all. ``total`` sums each platen's force [N] over the
    cycles, for means between samples."""
    p = wp.tid()
    f = wp.float64(reaction[p, 0]) / _FORCE_SCALE_64
    total[p] = total[p] + f
    step = wp.float64(0.0)
    if servo != 0:
        k = wp.float64(reaction[p, 1]) / _STIFFNESS_SCALE_64
        step = max_step
        if k > wp.float64(0.0):
            step = wp.clamp(gain * (target[p] - f) / k, -max_step, max_step)
    elif p == 1:
        tick = clock[0] + wp.int64(1)
        clock[0] = tick
        step = speed
        if tick < ramp:
            step = speed * wp.float64(tick) / wp.float64(ramp)
    offset[p] = offset[p] + step
    velocity[p] = normal[p] * (step / dt)


#: Room the following grid leaves for the specimen to widen, as a fraction of its diameter (it bulges about 17%
#: by 15% axial strain).
BULGE = 0.4


class FollowLamp:
    """The lateral lamp on a grid that follows the body inside the captured graph (``ShiningLamp(follow=True)``).

    The grid's cells are fixed once, from the specimen at the start: mean diameter / ``cells_per_diameter``, a
    capacity of the specimen's box widened by ``BULGE`` of its width across and one mean diameter on every side.
    Each update finds the body's box on the device and moves the grid by whole cells so that the body stays
    centred; a particle that still pokes out is counted in ``diagnostics().outside`` (checked by the tests).
    """

    def __init__(
        self,
        positions,
        radii,
        *,
        cells_per_diameter: float,
        lamps=LATERAL,
        surfaces: str = "first",
        probe_radius: float | None = None,
        device=None,
    ):
        """Args:
        positions: Particle centres in the lamp's frame [m], shape (N, 3).
        radii: Particle radii [m], shape (N,).
        cells_per_diameter: Cells per mean particle diameter.
        lamps: Lamps that are on.
        surfaces: ``"first"`` (the memo's lamp) or ``"all"`` (every wetted surface, ``probe_radius`` [m]).
        probe_radius: The wetted mode's probe radius [m].
        device: Warp device.
        """
        d = 2.0 * float(np.mean(radii))
        lo = np.min(positions - radii[:, None], axis=0)
        hi = np.max(positions + radii[:, None], axis=0)
        cell = d / float(cells_per_diameter)
        # The wetted mode needs the probe radius plus a cell of fluid around the body on every side.
        pad = np.full(3, d + (probe_radius + cell if surfaces == "all" else 0.0))
        pad[:2] += 0.5 * BULGE * (hi[:2] - lo[:2])
        self.grid = wl.LampGrid(lo - pad, hi + pad, cell)
        self.surfaces = surfaces
        self.lamps = set(lamps)
        options = {"surfaces": "all", "probe_radius": probe_radius} if surfaces == "all" else {}
        self.lamp = wl.ShiningLamp(self.grid, lamps=lamps, follow=True, device=device, **options)
        self.lamp.reserve(len(radii))
        self.max_outside = 0

    def update(self, positions: wp.array, radii: wp.array) -> None:
        """Who is lit, after the grid's move (capturable); positions float32 in the lamp's frame."""
        self.lamp.update(positions, radii)

    def add_forces(self, forces: wp.array, pressure) -> None:
        """forces += the lamp's forces (capturable)."""
        self.lamp.add_forces(forces, pressure)

    def check(self) -> dict:
        """Outside the graph (syncs): the area each lamp lights [m^2] by name, from the diagnostics of the lamp
        whose forces are in place; records the largest count of particles outside the grid."""
        diag = self.lamp.diagnostics()
        self.max_outside = max(self.max_outside, diag.outside)
        if self.surfaces == "all":
            # Each lit ray meets the wetted boundary first where the memo's lamp meets the body: the rays with a
            # crossing are the lit area of both lamps of their axis (the inner crossings cancel along the ray).
            return {
                name: int(np.count_nonzero(diag.crossings[k // 2])) * float(self.grid.cell_area[k // 2])
                if name in self.lamps
                else 0.0
                for k, name in enumerate(wl.LAMPS)
            }
        return {name: diag.lit[name] * float(self.grid.cell_area[k // 2]) for k, name in enumerate(wl.LAMPS)}


def silhouette_area(u: np.ndarray, v: np.ndarray, r: np.ndarray, pixel: float) -> float:
    """Area [m^2] of the union of disks (u_i, v_i, r_i): exact union lengths along u on rows ``pixel`` apart in v
    (the midpoint rule across rows)."""
    v0 = float(np.min(v - r))
    j0 = np.ceil((v - r - v0) / pixel - 0.5).astype(np.int64)
    j1 = np.floor((v + r - v0) / pixel - 0.5).astype(np.int64)
    count = np.maximum(j1 - j0 + 1, 0)
    idx = np.repeat(np.arange(len(r)), count)
    row = j0[idx] + np.arange(len(idx)) - np.repeat(np.cumsum(count) - count, count)
    w2 = r[idx] ** 2 - (v0 + (row + 0.5) * pixel - v[idx]) ** 2
    keep = w2 >= 0.0
    idx, row, w = idx[keep], row[keep], np.sqrt(w2[keep])
    # Rows shifted apart by more than the body's width: one running maximum then merges every row on its own.
    shift = row * 2.0 * (float(np.max(u + r) - np.min(u - r)) + 1.0)
    a = u[idx] - w + shift
    order = np.argsort(a, kind="stable")
    a, b, row = a[order], (u[idx] + w + shift)[order], row[order]
    reach = np.maximum.accumulate(b)
    first = np.r_[True, row[1:] != row[:-1]]
    last = np.r_[row[1:] != row[:-1], True]
    gaps = np.maximum(a[1:] - reach[:-1], 0.0)[~first[1:]]
    return float((np.sum(reach[last]) - np.sum(a[first]) - np.sum(gaps)) * pixel)


def lateral_envelope(x, r, z_bottom: float, z_top: float, slabs: int, sectors: int) -> dict:
    """The specimen's lateral envelope (module docstring): volume [m^3] and each slab's mean radius [m]."""
    dz = (z_top - z_bottom) / slabs
    slab = np.clip(np.floor((x[:, 2] - z_bottom) / dz).astype(np.int64), 0, slabs - 1)
    dtheta = 2.0 * np.pi / sectors
    volume = 0.0
    radius = np.zeros(slabs)
    for s in range(slabs):
        sel = slab == s
        xs = x[sel]
        axis = xs[:, :2].mean(axis=0)
        d = xs[:, :2] - axis
        reach = np.hypot(d[:, 0], d[:, 1]) + r[sel]
        sector = np.floor((np.arctan2(d[:, 1], d[:, 0]) + np.pi) / dtheta).astype(np.int64) % sectors
        env = np.full(sectors, -np.inf)
        np.maximum.at(env, sector, reach)
        filled = np.isfinite(env)
        env[~filled] = env[filled].mean()  # a sector no particle falls in takes the slab's mean
        volume += 0.5 * dtheta * np.sum(env**2) * dz
        radius[s] = env.mean()
    return {"volume": volume, "radius": radius}


class TriaxialTest(dem.BlockRunner):
    """The specimen, the DEM with its platens, the lateral lamp, the two phases and the measurements."""

    def __init__(
        self,
        particles: int = 10000,
        *,
        cells_per_diameter: float = 4,
        sigma3: float = SIGMA_3,
        inertial_number: float = 5e-4,
        update_every: int = 10,
        check_every: int | None = None,
        porosity: float | None = None,
        e_c: float = E_C,
        damping: float = LOCAL_DAMPING,
        viscous: float = VISCOUS,
        platen_friction: float = MU,
        surfaces: str = "first",
        probe_radius: float = 0.5,
        seed: int = 0,
        device=None,
        scene=None,
    ):
        """Args:
        particles: Number of particles of the specimen.
        cells_per_diameter: Lamp cells per mean particle diameter.
        sigma3: Confining pressure [Pa].
        inertial_number: I = rate d sqrt(rho / sigma_3) of the axial compression; sets the strain rate.
        update_every: Cycles between the lamp's updates (n_u, the memo's ct_pressrate); forces every cycle.
        check_every: Cycles between host samples; a multiple of the captured block.
        porosity: Porosity of the packing; :func:`default_porosity` by default.
        e_c: Contact modulus [Pa].
        damping: Local damping coefficient while consolidating (0 in the compression).
        viscous: Critical damping ratio of the contact dashpots, both phases.
        platen_friction: Friction coefficient between the balls and the platens.
        surfaces: The lamp's mode: ``"first"`` (the memo's) or ``"all"`` (every wetted surface).
        probe_radius: ``surfaces="all"``: the probe radius, in mean particle radii.
        seed: Packing seed.
        device: Warp device.
        scene: A ready specimen (a cylinder about the z axis, centred at the origin) instead of generating one.
        """
        self.device = wp.get_device(device)
        d = self.device
        if porosity is None:
            porosity = default_porosity(particles)
        # Packed on the CPU (seconds, cached), so that every machine tests the same specimen.
        self.scene = scene or scene_cylinder_specimen(DIAMETER, particles=particles, porosity=porosity, seed=seed)
        s = self.scene
        self.n = s.n
        self.sigma3 = float(sigma3)
        self.update_every = int(update_every)
        if self.update_every < 1:
            raise ValueError(f"update_every: must be >= 1, got {update_every!r}")
        self.block = self.update_every if self.update_every % 2 == 0 else 2 * self.update_every
        r = s.radii
        self.d_mean = 2.0 * float(r.mean())
        mass = DENSITY * 4.0 / 3.0 * np.pi * r**3
        self.dt = DT_FACTOR * float(np.min(np.sqrt(mass / (2.0 * e_c * r))))
        mat = dem.material(e_c, mu=MU, damping=damping, viscous=viscous)
        self.dem = dem.Dem(s.centers, r, mass, 0.4 * mass * r**2, mat, self.dt, frame_center=s.center, device=d)
        self.inertial_number = float(inertial_number)
        self.strain_rate = self.inertial_number / (self.d_mean * np.sqrt(DENSITY / self.sigma3))
        # The platens start touching the lowest and the highest particle.
        z_lo = float(np.min(s.centers[:, 2] - r))
        z_hi = float(np.max(s.centers[:, 2] + r))
        h = z_hi - z_lo
        self.platen_mat = dem.material(e_c, mu=platen_friction, damping=damping, viscous=viscous)
        self.planes = dem.Planes.create([[0, 0, 1], [0, 0, -1]], [z_lo, -z_hi], self.n, d, mat=self.platen_mat)
        self.target = wp.zeros(2, dtype=wp.float64, device=d)
        self.pressure = wp.array([self.sigma3], dtype=wp.float32, device=d)
        self.lamp_force = wp.zeros(self.n, dtype=wp.vec3, device=d)
        self.surfaces = surfaces
        self.probe_radius = float(probe_radius) * 0.5 * self.d_mean if surfaces == "all" else None
        self.lamp = FollowLamp(
            s.centers - s.center,
            r,
            cells_per_diameter=cells_per_diameter,
            surfaces=surfaces,
            probe_radius=self.probe_radius,
            device=d,
        )
        self.cells_per_diameter = float(cells_per_diameter)
        self.slabs = max(1, round(h / (2.0 * self.d_mean)))
        self.sectors = max(8, round(np.pi * DIAMETER / (2.0 * self.d_mean)))
        if check_every is None:
            check_every = 2000 if d.is_cuda else 200
        self.check_every = max(self.block, int(np.ceil(check_every / self.block)) * self.block)
        self.servo = True
        self.speed = 0.0  # top platen step per cycle in compression [m]
        self.ramp = 1  # cycles of the speed ramp
        self._compression_start = 0
        self.clock = wp.zeros(1, dtype=wp.int64, device=d)  # compression cycles so far, on the device
        self.total = wp.zeros(2, dtype=wp.float64, device=d)  # platen forces summed since the last sample [N]
        self._total_since = 0
        self._platen_force = np.zeros(2)
        self.max_step = SERVO_SPEED * self.strain_rate * h * self.dt
        self._graph = None
        self._loaded = False
        self.h0 = h
        self.v0 = None
        self.history = {"consolidation": [], "compression": []}

    @property
    def cycle(self) -> int:
        return self.dem.cycle

    def platens(self) -> tuple[float, float]:
        """Bottom and top platen heights [m] (host copy)."""
        off = self.planes.offset.numpy()
        return float(off[0]), float(-off[1])

    # --- one cycle ----------------------------------------------------------------------------------------------

    def step(self, *, lamp_update: bool = True, lamp: bool = True) -> None:
        """One cycle: frame copy, the lamp (``lamp_update``: who is lit, then its forces), ball and platen contacts,
        integration, platen control. ``lamp=False`` leaves the lamp out (to time its share)."""
        sim = self.dem
        sim.begin()
        if lamp and lamp_update:
            self.lamp.update(sim.pos32, sim.radius32)
            self.lamp_force.zero_()
            self.lamp.add_forces(self.lamp_force, self.pressure)
        sim.contacts()
        sim.planes(self.planes)
        sim.integrate(self.lamp_force)
        wp.launch(
            platen_control,
            dim=2,
            inputs=[
                self.planes.reaction,
                self.target,
                self.planes.normal,
                int(self.servo),
                self.speed,
                self.ramp,
                SERVO_GAIN,
                self.max_step,
                self.dt,
            ],
            outputs=[self.clock, self.planes.offset, self.planes.velocity, self.total],
            device=self.device,
        )

    def _block(self, *, lamp: bool = True) -> None:
        for k in range(self.block):
            self.step(lamp_update=k % self.update_every == 0, lamp=lamp)

    def capture(self, *, lamp: bool = True):
        """One block of cycles (n_u cycles, or 2 n_u when n_u is odd: the slot buffers swap by parity) in one CUDA
        graph: frame copy, the lamp's update on its cycle, contacts, platens, integration, platen control."""
        ticks = iter(range(self.block))
        # dem.capture records its function once per cycle, so the graph holds one step per call, not a block.
        return self.dem.capture(
            lambda: self.step(lamp_update=next(ticks) % self.update_every == 0, lamp=lamp), self.block
        )

    def time_cycle(self, repeats: int = 20) -> dict:
        """Seconds per cycle from graph replays (CUDA; wall time on the CPU), with and without the lamp, at this
        test's n_u; and the lamp's share. The timed cycles run (uncounted), so call it at the end."""
        if not self._loaded:
            self.advance(self.block)
        out = {"update_every": self.update_every}
        for name, with_lamp in (("cycle_s", True), ("cycle_without_lamp_s", False)):
            if self.device.is_cuda:
                graph = self.capture(lamp=with_lamp)
                t = dem.median_gpu_time(lambda g=graph: wp.capture_launch(g), self.device, repeats)
            else:
                t = dem.median_gpu_time(lambda w=with_lamp: self._block(lamp=w), self.device, repeats)
            out[name] = t / self.block
        out["lamp_share"] = 1.0 - out["cycle_without_lamp_s"] / out["cycle_s"]
        return out

    # --- measurements -------------------------------------------------------------------------------------------

    def sample(self) -> dict:
        """Host measurements now (module docstring)."""
        x = self.dem.x.numpy()
        r = self.scene.radii
        lit = self.lamp.check()
        z_b, z_t = self.platens()
        h = z_t - z_b
        env = lateral_envelope(x, r, z_b, z_t, self.slabs, self.sectors)
        area = env["volume"] / h
        # Platen forces: the mean over the cycles since the last sample (the instantaneous ones rattle).
        if self.cycle > self._total_since:
            self._platen_force = self.total.numpy() / (self.cycle - self._total_since)
            self.total.zero_()
            self._total_since = self.cycle
        f_bottom, f_top = (float(f) for f in self._platen_force)
        pixel = self.d_mean / 16.0
        s_x = silhouette_area(x[:, 1], x[:, 2], r, pixel)
        s_y = silhouette_area(x[:, 0], x[:, 2], r, pixel)
        # Each lamp pushes with P times the area it lights; both x lamps light the silhouette seen along x.
        lit_x = lit["-x"] + lit["+x"]
        lit_y = lit["-y"] + lit["+y"]
        # The net forces particles receive: where one particle takes both ends of a ray, its pushes cancel.
        lf = self.lamp_force.numpy().astype(np.float64)
        sigma1 = 0.5 * (f_bottom + f_top) / area
        sphere = self.dem.sphere_stress(np.array([0.0, 0.0, 0.5 * (z_b + z_t)]), 0.8 * DIAMETER)
        return {
            "cycle": self.cycle,
            "height": h,
            "volume": env["volume"],
            "area": area,
            "sigma1": sigma1,
            "sigma_bottom": f_bottom / area,
            "sigma_top": f_top / area,
            "q": sigma1 - self.sigma3,
            "sigma_lat": self.sigma3 * (lit_x + lit_y) / (2.0 * s_x + 2.0 * s_y),
            "sigma_lat_x": self.sigma3 * lit_x / (2.0 * s_x),
            "sigma_lat_y": self.sigma3 * lit_y / (2.0 * s_y),
            "sigma_lat_net": float(np.abs(lf[:, 0]).sum() + np.abs(lf[:, 1]).sum()) / (2.0 * s_x + 2.0 * s_y),
            "loaded": int(np.count_nonzero(np.abs(lf).sum(axis=1))),
            "silhouette_x": s_x,
            "silhouette_y": s_y,
            "sphere_stress": sphere.tolist(),
            "ratio": self.dem.unbalanced_ratio(),
            "outside": self.lamp.max_outside,
            "radius_profile": env["radius"].tolist(),
            "max_radial": float(np.max(np.hypot(x[:, 0], x[:, 1]) + r)),
        }

    # --- the two phases -----------------------------------------------------------------------------------------

    def consolidate(self, max_cycles: int = 60000, *, verbose: bool = False) -> dict:
        """Phase 1: lamp at sigma_3, both platens servo-controlled to sigma_3 (target force sigma_3 times the
        envelope's mean area, refreshed at every check) until both platen stresses are within 1% of sigma_3 and
        the unbalanced ratio is below 1e-3, or ``max_cycles``."""
        self.servo = True
        self._graph = None
        area = np.pi * (DIAMETER / 2) ** 2
        start = self.cycle
        while True:
            self.target.assign(np.full(2, self.sigma3 * area))
            self.advance(self.check_every)
            smp = self.sample()
            area = smp["area"]
            self.history["consolidation"].append(smp)
            if verbose:
                print(
                    f"  consolidation cycle {self.cycle:7d}: platens {smp['sigma_bottom'] / 1e3:7.2f} "
                    f"{smp['sigma_top'] / 1e3:7.2f} kPa, lamp {smp['sigma_lat'] / 1e3:7.2f} kPa, "
                    f"ratio {smp['ratio']:.2e}",
                    flush=True,
                )
            done = (
                abs(smp["sigma_bottom"] / self.sigma3 - 1) < CONSOLIDATION_TOL
                and abs(smp["sigma_top"] / self.sigma3 - 1) < CONSOLIDATION_TOL
                and smp["ratio"] < RATIO_TOL
            )
            if done or self.cycle - start >= max_cycles:
                break
        self.h0 = smp["height"]
        self.v0 = smp["volume"]
        return {"cycles": self.cycle - start, "converged": bool(done), **smp}

    def compress(self, strain: float = 0.15, *, verbose: bool = False) -> list:
        """Phase 2: bottom platen fixed, top platen at constant speed (strain rate from the inertial number, after
        a linear ramp over the cycles that RAMP_STRAIN takes at full speed, RAMP_CYCLES at least) until ``strain``
        axial strain; the lamp
        keeps sigma_3 on the lateral surface. Returns the samples."""
        if self.v0 is None:
            raise RuntimeError("consolidate first: the axial and volumetric strains start from its end")
        self.servo = False
        self.dem.mat.damping = wp.float64(0.0)
        self.speed = self.strain_rate * self.h0 * self.dt
        self.ramp = max(RAMP_CYCLES, round(RAMP_STRAIN / (self.strain_rate * self.dt)))
        self._compression_start = self.cycle
        self.clock.zero_()
        self._graph = None
        samples = self.history["compression"]
        samples.append(self._strains(self.sample()))
        while samples[-1]["eps_a"] < strain:
            # Sample more often near the end, so that the last one lands close to the target strain.
            left = (strain - samples[-1]["eps_a"]) / (self.strain_rate * self.dt)
            self.advance(int(min(self.check_every, max(self.block, left))))
            smp = self._strains(self.sample())
            samples.append(smp)
            if verbose:
                print(
                    f"  compression cycle {self.cycle:7d}: eps_a {smp['eps_a']:6.2%}  q {smp['q'] / 1e3:7.2f} kPa  "
                    f"eps_v {smp['eps_v']:+.3%}  lamp {smp['sigma_lat'] / self.sigma3 - 1:+.2%}  "
                    f"outside {smp['outside']}",
                    flush=True,
                )
        return samples

    def _strains(self, smp: dict) -> dict:
        smp["eps_a"] = (self.h0 - smp["height"]) / self.h0
        smp["eps_v"] = (self.v0 - smp["volume"]) / self.v0
        smp["ramp"] = self.cycle - self._compression_start < self.ramp
        return smp

    def summary(self) -> dict:
        """Peak q, friction angles, dilatancy, the lamp's lateral-stress error, from the compression samples."""
        c = self.history["compression"]
        eps_a = np.array([s["eps_a"] for s in c])
        q = np.array([s["q"] for s in c])
        eps_v = np.array([s["eps_v"] for s in c])
        lat = np.array([s["sigma_lat"] for s in c]) / self.sigma3 - 1.0
        steady = ~np.array([s["ramp"] for s in c])
        k = int(np.flatnonzero(steady)[np.argmax(q[steady])]) if steady.any() else int(np.argmax(q))
        # Dilatancy: slope of eps_v against eps_a by least squares over a window of about 1% axial strain.
        half = max(1, int(np.ceil(0.005 / max(np.median(np.diff(eps_a)), 1e-12))))
        rates = [
            np.polyfit(eps_a[max(0, i - half) : i + half + 1], eps_v[max(0, i - half) : i + half + 1], 1)[0]
            for i in range(len(c))
        ]
        j = int(np.argmin(rates))
        rate = float(rates[j])
        sig = np.array(self.history["consolidation"][-1]["sphere_stress"])
        inner = np.array([_principal(s["sphere_stress"]) for s in c])  # (sigma_1, sigma_3) in the sphere
        phi_in = np.degrees(np.arcsin((inner[:, 0] - inner[:, 1]) / (inner[:, 0] + inner[:, 1])))
        ends = np.array([[s["sigma_bottom"], s["sigma_top"]] for s in c])
        mismatch = np.abs(ends[:, 1] - ends[:, 0]) / ends.mean(axis=1)
        all_lat = np.array([s["sigma_lat"] for s in self.history["consolidation"] + c]) / self.sigma3 - 1.0
        return {
            "particles": self.n,
            "mean_diameter_m": self.d_mean,
            "cells_per_diameter": self.cells_per_diameter,
            "update_every": self.update_every,
            "sigma3_Pa": self.sigma3,
            "inertial_number": self.inertial_number,
            "strain_rate_per_s": self.strain_rate,
            "dt_s": self.dt,
            "peak_q_Pa": float(q[k]),
            "peak_q_over_sigma3": float(q[k] / self.sigma3),
            "eps_a_at_peak": float(eps_a[k]),
            "peak_friction_angle_deg": float(np.degrees(np.arcsin(q[k] / (q[k] + 2 * self.sigma3)))),
            "final_q_Pa": float(q[-1]),
            "final_friction_angle_deg": float(np.degrees(np.arcsin(q[-1] / (q[-1] + 2 * self.sigma3)))),
            "eps_v_min": float(eps_v.min()),
            "eps_v_final": float(eps_v[-1]),
            "max_dilatancy_rate": -rate,
            "dilatancy_angle_deg": float(np.degrees(np.arcsin(-rate / (2.0 - rate)))),
            "sphere_friction_angle_at_peak_deg": float(phi_in[k]),
            "sphere_friction_angle_max_deg": float(phi_in[steady].max() if steady.any() else phi_in.max()),
            "platen_mismatch_mean": float(mismatch[steady].mean() if steady.any() else mismatch.mean()),
            "unbalanced_ratio_mean": float(np.mean([s["ratio"] for s in c[1:]])),
            "lamp_lateral_error_max": float(np.abs(lat).max()),
            "lamp_lateral_error_mean": float(lat.mean()),
            "lamp_lateral_error_max_all_phases": float(np.abs(all_lat).max()),
            "lamp_lateral_net_mean": float(np.mean([s["sigma_lat_net"] for s in c]) / self.sigma3),
            "consolidation_sphere_stress_Pa": sig.tolist(),
            "max_outside": self.lamp.max_outside,
            "compression_cycles": int(c[-1]["cycle"] - c[0]["cycle"]),
            "max_bulge": float(max(np.max(s["radius_profile"]) for s in c) / np.mean(c[0]["radius_profile"]) - 1),
            "surfaces": self.surfaces,
            "probe_radius_m": self.probe_radius,
            "loaded_mean": float(np.mean([s["loaded"] for s in c])),
        }


def _principal(stress) -> tuple[float, float]:
    """(sigma_zz, mean of sigma_xx and sigma_yy) of a stress tensor given as nested lists [Pa]."""
    s = np.asarray(stress)
    return float(s[2, 2]), float(0.5 * (s[0, 0] + s[1, 1]))


def plot(test: TriaxialTest, path: str):
    """The curves of a run to a PNG (:func:`plot_history`); returns the figure."""
    return plot_history(test.summary(), test.history, path)


def plot_history(summary: dict, history: dict, path: str):
    """The curves to a PNG: q, the volumetric strain (dilation shaded) and the lamp's lateral stress against the
    axial strain, and the radius profiles; from a run's ``summary()`` and ``history``, or from the JSON that
    ``--json`` writes. Returns the figure (still open, for the caller to inspect or close)."""
    try:
        import matplotlib
    except ImportError:
        sys.exit("--plot needs matplotlib: pip install '.[plot]' in a clone, or pip install 'warp-lamp[plot]'")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sigma3 = summary["sigma3_Pa"]
    c = history["compression"]
    eps_a = np.array([s["eps_a"] for s in c]) * 100
    q = np.array([s["q"] for s in c]) / 1e3
    eps_v = np.array([s["eps_v"] for s in c]) * 100
    lat = np.array([s["sigma_lat"] for s in c]) / sigma3
    fig, ax = plt.subplots(2, 2, figsize=(10, 7.5))
    inner = np.array([_principal(s["sphere_stress"]) for s in c]) / 1e3
    strain = r"axial strain $\varepsilon_a$ [%]"
    ax[0, 0].plot(eps_a, q, label=r"platens: mean platen force / envelope area $-\ \sigma_3$")
    ax[0, 0].plot(
        eps_a,
        inner[:, 0] - inner[:, 1],
        "--",
        lw=0.8,
        label=r"measurement sphere (core): $\sigma_{zz} - (\sigma_{xx} + \sigma_{yy})/2$",
    )
    ax[0, 0].set(xlabel=strain, ylabel=r"$q = \sigma_1 - \sigma_3$ [kPa]", title="deviator stress")
    ax[0, 0].legend(fontsize=8)
    ax[0, 1].plot(eps_a, eps_v)
    ax[0, 1].axhline(0.0, color="0.5", lw=0.6)
    if (eps_v < 0).any():
        ax[0, 1].fill_between(
            eps_a, eps_v, 0.0, where=eps_v < 0, color="tab:orange", alpha=0.25, label=r"dilation ($\varepsilon_v < 0$)"
        )
        ax[0, 1].legend(fontsize=8)
    ax[0, 1].set(
        xlabel=strain,
        ylabel=r"volumetric strain $\varepsilon_v$ [%]",
        title=r"volume change: $\varepsilon_v > 0$ compaction, $< 0$ dilation",
    )
    ax[1, 0].plot(eps_a, lat, label=r"lamp: lit area $\times P$ / silhouette area")
    net = np.array([s["sigma_lat_net"] for s in c]) / sigma3
    ax[1, 0].plot(eps_a, net, "--", lw=0.8, label="net forces on the particles / silhouette area")
    ax[1, 0].axhspan(0.97, 1.03, color="0.9", label=r"$\pm$3%")
    ax[1, 0].set(xlabel=strain, ylabel=r"$\sigma_\mathrm{lat} / \sigma_3$", title="the membrane's check")
    ax[1, 0].set_ylim(min(0.94, float(net.min()) - 0.01), 1.06)
    ax[1, 0].legend(fontsize=8)
    for frac in (0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0):
        i = int(np.argmin(np.abs(eps_a - frac * eps_a[-1])))
        prof = np.array(c[i]["radius_profile"]) * 1e3
        zs = (np.arange(len(prof)) + 0.5) / len(prof) * c[i]["height"] * 1e3
        ax[1, 1].plot(prof, zs, label=rf"$\varepsilon_a$ = {eps_a[i]:.1f}%")
    ax[1, 1].set(xlabel="envelope radius [mm]", ylabel="height above bottom platen [mm]", title="bulging")
    ax[1, 1].legend()
    s = summary
    fig.suptitle(
        rf"Drained triaxial, {s['particles']:,} particles, $\sigma_3$ = {sigma3 / 1e3:g} kPa, lamp "
        rf"{s['cells_per_diameter']:g} cells/d, $I$ = {s['inertial_number']:g}"
        "\n"
        rf"peak $q/\sigma_3$ = {s['peak_q_over_sigma3']:.2f} (platens), "
        rf"$\varphi_\mathrm{{peak}}$ = {s['peak_friction_angle_deg']:.1f}° (platens), "
        rf"{s['sphere_friction_angle_at_peak_deg']:.1f}° (core)",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return fig


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--particles", type=int, default=None, help="particles (10,000; --quick: 2,000)")
    parser.add_argument("--cells-per-diameter", type=float, default=4, help="lamp cells per mean diameter")
    parser.add_argument("--inertial-number", type=float, default=None, help="I of the compression (5e-4; quick 5e-3)")
    parser.add_argument("--update-every", type=int, default=10, help="lamp update every n_u cycles")
    parser.add_argument("--strain", type=float, default=0.15, help="final axial strain")
    parser.add_argument("--device", default=None)
    parser.add_argument("--quick", action="store_true", help="2,000 particles, I = 5e-3: minutes on a CPU")
    parser.add_argument("--surfaces", choices=("first", "all"), default="first", help="the lamp's mode")
    parser.add_argument(
        "--probe-radius", type=float, default=0.5, help="--surfaces all: probe radius in mean particle radii"
    )
    parser.add_argument("--time", action="store_true", help="time a cycle with and without the lamp at the end")
    parser.add_argument("--json", default=None, help="write the summary and the samples as JSON")
    parser.add_argument("--plot", default=None, help="draw the curves to this PNG (needs the plot extra)")
    parser.add_argument("--from-json", default=None, help="--plot: redraw a saved run (--json) instead of running")
    args = parser.parse_args(argv)
    if args.plot and importlib.util.find_spec("matplotlib") is None:
        sys.exit("--plot needs matplotlib: pip install '.[plot]' in a clone, or pip install 'warp-lamp[plot]'")
    if args.from_json:
        if not args.plot:
            sys.exit("--from-json redraws a saved run: add --plot PATH")
        with open(args.from_json) as f:
            saved = json.load(f)
        plot_history(saved["summary"], saved, args.plot)
        print(f"wrote {args.plot}")
        return
    wp.config.log_level = wp.LOG_WARNING
    particles = args.particles or (2000 if args.quick else 10000)
    inertial = args.inertial_number or (5e-3 if args.quick else 5e-4)
    t0 = time.perf_counter()
    test = TriaxialTest(
        particles,
        cells_per_diameter=args.cells_per_diameter,
        inertial_number=inertial,
        update_every=args.update_every,
        surfaces=args.surfaces,
        probe_radius=args.probe_radius,
        device=args.device,
    )
    est = int(np.ceil(args.strain / (test.strain_rate * test.dt)))
    print(
        f"{test.n} particles, d = {test.d_mean * 1e3:.2f} mm, dt = {test.dt:.3e} s, strain rate "
        f"{test.strain_rate:.3g}/s (I = {inertial:g}): {est} compression cycles; specimen ready in "
        f"{time.perf_counter() - t0:.1f} s",
        flush=True,
    )
    t1 = time.perf_counter()
    cons = test.consolidate(verbose=True)
    t2 = time.perf_counter()
    print(f"consolidated in {cons['cycles']} cycles, {t2 - t1:.1f} s (converged: {cons['converged']})", flush=True)
    test.compress(args.strain, verbose=True)
    t3 = time.perf_counter()
    summary = test.summary()
    summary.update(
        {"consolidation_cycles": cons["cycles"], "consolidation_s": t2 - t1, "compression_s": t3 - t2},
        device=str(test.device),
    )
    if args.time:
        summary.update(test.time_cycle())
    for key, val in summary.items():
        print(f"  {key}: {val}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"summary": summary, **test.history}, f, indent=1)
    if args.plot:
        plot(test, args.plot)
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
