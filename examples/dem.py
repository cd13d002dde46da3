"""The small Warp DEM that the examples share (``sphere_test.py``, ``triaxial.py``); not part of warp_lamp's API.

Only what the examples need: spheres with linear normal and shear springs, Coulomb friction, PFC local damping
and rotations; neighbours from ``wp.HashGrid``; plane contacts for rigid platens; no bonds. Contact stiffness
follows the memo's Table 1 convention: a ball has kn = 4 E_c R, a contact the series combination of its two
balls' (2 E_c R for equal balls), ks = kn / (kn/ks). The state is float64 (overlaps at working stress are far
below float32's resolution at the specimen's size); the lamp gets a float32 copy of the positions relative to
a frame centre, as a simulator hands it Warp arrays. Contact forces are gathered per particle (no atomics), and
the platen reactions are summed in 64-bit fixed point, so a run replays bitwise on the same device.

Stress: PFC's formula, sigma = -(1 - n) / sum V_p * sum_p sum_c (x_c - x_p) (x) F_c,p over the particles whose
centres lie in a measurement sphere, n its porosity (lens-exact particle volume inside it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

SLOTS = 24  # contacts remembered per particle (a dense packing has about 6-12)
#: Platen reactions are summed as integers: force in units of 2^-24 N, stiffness in units of 2^-8 N/m.
FORCE_SCALE = 2.0**24
STIFFNESS_SCALE = 2.0**8
_FORCE_SCALE_64 = wp.constant(wp.float64(FORCE_SCALE))
_STIFFNESS_SCALE_64 = wp.constant(wp.float64(STIFFNESS_SCALE))


@wp.struct
class Material:
    """Linear contact law and damping, as the kernels take them (float64)."""

    e_c: wp.float64  # contact modulus [Pa]: a ball's normal stiffness is 4 e_c R
    kn_ks: wp.float64  # normal over shear stiffness
    mu: wp.float64  # Coulomb friction coefficient, balls and platens alike
    damping: wp.float64  # PFC local damping coefficient
    viscous: wp.float64  # critical damping ratio of the contact dashpots (normal; shear while sticking)


def material(
    e_c: float, *, kn_ks: float = 3.7, mu: float = 0.5, damping: float = 0.7, viscous: float = 0.0
) -> Material:
    """A :class:`Material` from plain numbers: contact modulus [Pa], kn/ks, friction, local damping coefficient,
    contact dashpots' critical damping ratio.

    Local damping (PFC's) takes alpha |F| from each component of a particle's force against its velocity: it
    settles a body at rest fast, but it acts on absolute velocities, so a body that deforms steadily feels it as
    a drag of alpha sum |F_i| (the particles' fluctuating forces) against its motion. Contact dashpots act on
    relative velocities only: c = 2 zeta sqrt(m k), m the contact's reduced mass.
    """
    m = Material()
    m.e_c = wp.float64(e_c)
    m.kn_ks = wp.float64(kn_ks)
    m.mu = wp.float64(mu)
    m.damping = wp.float64(damping)
    m.viscous = wp.float64(viscous)
    return m


@wp.func
def find_slot(ids: wp.array2d[wp.int32], i: int, j: int) -> int:
    for s in range(SLOTS):
        if ids[i, s] == j:
            return s
    return -1


@wp.func
def contact_law(
    fs: wp.vec3d,
    vt: wp.vec3d,
    closing: wp.float64,
    fn: wp.float64,
    kn: wp.float64,
    ks: wp.float64,
    cd: wp.float64,
    mu: wp.float64,
):
    """Coulomb's limit on the shear spring ``fs`` and the dashpots (coefficient ``cd``, 0 for none) of one contact
    closing at ``closing`` [m/s] with tangential velocity ``vt``: returns the spring kept as the contact's state, the
    normal force with its dashpot (it never pulls), and the shear force with its dashpot (only while the spring
    sticks)."""
    limit = mu * fn
    mag = wp.length(fs)
    fnd = fn
    if cd > wp.float64(0.0):
        fnd = wp.max(fn + cd * wp.sqrt(kn) * closing, wp.float64(0.0))
    fd = fs
    if mag > limit:
        fs = fs * (limit / mag)
        fd = fs
    elif cd > wp.float64(0.0):
        fd = fs + cd * wp.sqrt(ks) * vt
    return fs, fnd, fd


@wp.kernel(enable_backward=False)
def dem_contacts(
    grid: wp.uint64,
    x: wp.array[wp.vec3d],
    v: wp.array[wp.vec3d],
    w: wp.array[wp.vec3d],
    radius: wp.array[wp.float64],
    mass: wp.array[wp.float64],
    query: wp.float32,
    old_ids: wp.array2d[wp.int32],
    old_shear: wp.array2d[wp.vec3d],
    mat: Material,
    dt: wp.float64,
    # outputs
    new_ids: wp.array2d[wp.int32],
    new_shear: wp.array2d[wp.vec3d],
    force: wp.array[wp.vec3d],
    moment: wp.array[wp.vec3d],
    stats: wp.array[wp.float64],
):
    """One thread per particle gathers its contacts: linear springs, incremental shear with Coulomb's limit,
    dashpots when ``mat.viscous`` > 0 (the normal one never pulls; the shear one only while the spring sticks)."""
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
        kn = wp.float64(4.0) * mat.e_c * ri * rj / (ri + rj)  # series of 4 E_c R_i and 4 E_c R_j
        ks = kn / mat.kn_ks
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
        # Dashpots: c = 2 zeta sqrt(m k), m the reduced mass; the springs' fn and fs stay the contact's state.
        cd = wp.float64(0.0)
        if mat.viscous > wp.float64(0.0):
            cd = wp.float64(2.0) * mat.viscous * wp.sqrt(mass[i] * mass[j] / (mass[i] + mass[j]))
        # n points from i to j, so the balls close in while vc . n < 0.
        fs, fnd, fd = contact_law(fs, vt, -wp.dot(vc, n), fn, kn, ks, cd, mat.mu)
        f = f - fnd * n + fd
        m = m + wp.cross(ri * n, fd)
        if slot < SLOTS:
            new_ids[i, slot] = j
            new_shear[i, slot] = fs
            slot += 1
        wp.atomic_add(stats, 1, fn)
        wp.atomic_add(stats, 2, wp.float64(0.5))  # each contact is seen from both sides
    force[i] = f
    moment[i] = m


@wp.kernel(enable_backward=False)
def dem_planes(
    x: wp.array[wp.vec3d],
    v: wp.array[wp.vec3d],
    w: wp.array[wp.vec3d],
    radius: wp.array[wp.float64],
    mass: wp.array[wp.float64],
    normal: wp.array[wp.vec3d],
    offset: wp.array[wp.float64],
    velocity: wp.array[wp.vec3d],
    mat: Material,
    dt: wp.float64,
    # outputs
    shear: wp.array2d[wp.vec3d],
    force: wp.array[wp.vec3d],
    moment: wp.array[wp.vec3d],
    reaction: wp.array2d[wp.int64],
    stats: wp.array[wp.float64],
):
    """Rigid planes {y : n.y = offset}, particles on the side n points to: the contact of a ball with an equal
    ball (kn = 2 E_c R), incremental shear with Coulomb's limit, dashpots as in :func:`dem_contacts`. Adds to
    force and moment; each plane's normal spring force and contact stiffness are summed as integers (fixed
    point), so the sums do not depend on thread order."""
    i = wp.tid()
    xi = x[i]
    ri = radius[i]
    f = force[i]
    m = moment[i]
    for p in range(normal.shape[0]):
        n = normal[p]
        overlap = ri - (wp.dot(n, xi) - offset[p])
        if overlap <= wp.float64(0.0):
            shear[i, p] = wp.vec3d()
            continue
        kn = wp.float64(2.0) * mat.e_c * ri
        ks = kn / mat.kn_ks
        fn = kn * overlap
        # Velocity of the plane relative to the ball's surface at the contact point, which lies at -r n.
        vc = velocity[p] - (v[i] + wp.cross(w[i], -ri * n))
        vt = vc - wp.dot(vc, n) * n
        fs = shear[i, p]
        fs = fs - wp.dot(fs, n) * n
        fs = fs + ks * vt * dt
        cd = wp.float64(0.0)
        if mat.viscous > wp.float64(0.0):
            cd = wp.float64(2.0) * mat.viscous * wp.sqrt(mass[i])
        # vc . n > 0 while the plane and the ball close in (n points from the plane to the ball).
        fs, fnd, fd = contact_law(fs, vt, wp.dot(vc, n), fn, kn, ks, cd, mat.mu)
        shear[i, p] = fs
        f = f + fnd * n + fd
        m = m + wp.cross(-ri * n, fd)
        # The springs' force only: a servo that fed back its own dashpot (c / dt ~ kn here) would ring.
        wp.atomic_add(reaction, p, 0, wp.int64(wp.round(fn * _FORCE_SCALE_64)))
        wp.atomic_add(reaction, p, 1, wp.int64(wp.round(kn * _STIFFNESS_SCALE_64)))
        wp.atomic_add(reaction, p, 2, wp.int64(1))
        wp.atomic_add(stats, 1, wp.float64(2.0) * fn)  # counted like a ball contact seen from both sides
        wp.atomic_add(stats, 2, wp.float64(1.0))
    force[i] = f
    moment[i] = m


@wp.kernel(enable_backward=False)
def dem_integrate(
    external: wp.array[wp.vec3],
    mass: wp.array[wp.float64],
    inertia: wp.array[wp.float64],
    mat: Material,
    dt: wp.float64,
    force: wp.array[wp.vec3d],
    moment: wp.array[wp.vec3d],
    # outputs
    x: wp.array[wp.vec3d],
    v: wp.array[wp.vec3d],
    w: wp.array[wp.vec3d],
    stats: wp.array[wp.float64],
):
    """Local non-viscous damping (PFC): each component loses alpha |F| against its velocity; then Euler steps.
    ``external`` (the lamp's float32 forces) joins the contact forces first."""
    i = wp.tid()
    fe = external[i]
    f = force[i] + wp.vec3d(wp.float64(fe[0]), wp.float64(fe[1]), wp.float64(fe[2]))
    wp.atomic_add(stats, 0, wp.length(f))
    m = moment[i]
    vi = v[i]
    wi = w[i]
    for a in range(3):
        f[a] = f[a] - mat.damping * wp.abs(f[a]) * wp.sign(vi[a])
        m[a] = m[a] - mat.damping * wp.abs(m[a]) * wp.sign(wi[a])
    vi = vi + f / mass[i] * dt
    wi = wi + m / inertia[i] * dt
    v[i] = vi
    w[i] = wi
    x[i] = x[i] + vi * dt


@wp.kernel(enable_backward=False)
def dem_to_frame(
    x: wp.array[wp.vec3d],
    center: wp.vec3d,
    # outputs
    out: wp.array[wp.vec3],
):
    """float32 positions relative to ``center``: what the lamp and the hash grid take."""
    i = wp.tid()
    p = x[i] - center
    out[i] = wp.vec3(wp.float32(p[0]), wp.float32(p[1]), wp.float32(p[2]))


@dataclass
class Planes:
    """Rigid planes on the device: unit normals toward the particles, offsets and velocities (all float64).

    A plane is ``{y : normal . y = offset}``; moving it toward the particles raises its offset. ``reaction`` holds,
    per plane, the summed normal force (units of 1/FORCE_SCALE N), contact stiffness (1/STIFFNESS_SCALE N/m) and
    contact count of the last cycle; :meth:`reactions` converts them.
    """

    normal: wp.array
    offset: wp.array
    velocity: wp.array
    shear: wp.array
    reaction: wp.array
    mat: Material | None = None  # the planes' contact law; the particles' when None

    @classmethod
    def create(cls, normals, offsets, n: int, device, *, mat: Material | None = None) -> Planes:
        """Planes with the given unit normals, shape (P, 3), and offsets [m], shape (P,), for ``n`` particles;
        ``mat`` for a contact law of their own (friction, dashpots)."""
        normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        k = len(normals)
        return cls(
            wp.array(normals, dtype=wp.vec3d, device=device),
            wp.array(np.asarray(offsets, dtype=np.float64), dtype=wp.float64, device=device),
            wp.zeros(k, dtype=wp.vec3d, device=device),
            wp.zeros((n, k), dtype=wp.vec3d, device=device),
            wp.zeros((k, 3), dtype=wp.int64, device=device),
            mat,
        )

    def reactions(self) -> dict:
        """Last cycle's per-plane normal force [N], contact stiffness [N/m] and contact count (host copies)."""
        r = self.reaction.numpy()
        return {"force": r[:, 0] / FORCE_SCALE, "stiffness": r[:, 1] / STIFFNESS_SCALE, "contacts": r[:, 2]}


class Dem:
    """Particles, their float64 state and the pieces of one cycle; the examples put the lamp in between.

    A cycle is ``begin()``, ``contacts()``, optionally ``planes()``, then ``integrate(external)``. Contact
    histories live in two slot buffers that swap by cycle parity, so an even number of cycles replays from a
    CUDA graph (see :meth:`capture`).
    """

    def __init__(self, centers, radii, mass, inertia, mat: Material, dt: float, *, frame_center=None, device=None):
        """Args:
        centers: Particle centres [m], shape (N, 3).
        radii: Particle radii [m], shape (N,).
        mass: Particle masses [kg], shape (N,).
        inertia: Moments of inertia [kg m^2], shape (N,).
        mat: Contact law and damping.
        dt: Time step [s].
        frame_center: Centre of the float32 frame the lamp and the hash grid see [m]; the mean centre by default.
        device: Warp device.
        """
        self.device = wp.get_device(device)
        d = self.device
        centers = np.asarray(centers, dtype=np.float64)
        radii = np.asarray(radii, dtype=np.float64)
        self.n = len(radii)
        self.mat = mat
        self.dt = float(dt)
        self.x = wp.array(centers, dtype=wp.vec3d, device=d)
        self.v = wp.zeros(self.n, dtype=wp.vec3d, device=d)
        self.w = wp.zeros(self.n, dtype=wp.vec3d, device=d)
        self.radius = wp.array(radii, dtype=wp.float64, device=d)
        self.radius32 = wp.array(radii.astype(np.float32), dtype=wp.float32, device=d)
        self.mass = wp.array(np.asarray(mass, dtype=np.float64), dtype=wp.float64, device=d)
        self.inertia = wp.array(np.asarray(inertia, dtype=np.float64), dtype=wp.float64, device=d)
        self.ids = [wp.full((self.n, SLOTS), -1, dtype=wp.int32, device=d) for _ in range(2)]
        self.shear = [wp.zeros((self.n, SLOTS), dtype=wp.vec3d, device=d) for _ in range(2)]
        self.force = wp.zeros(self.n, dtype=wp.vec3d, device=d)
        self.moment = wp.zeros(self.n, dtype=wp.vec3d, device=d)
        self.stats = wp.zeros(3, dtype=wp.float64, device=d)
        self.grid = wp.HashGrid(32, 32, 32, device=d)
        self.grid.reserve(self.n)
        self.query = float(2.0 * radii.max())
        center = centers.mean(axis=0) if frame_center is None else np.asarray(frame_center, dtype=np.float64)
        self.frame_center = center
        self._center = wp.vec3d(*center)
        self.pos32 = wp.zeros(self.n, dtype=wp.vec3, device=d)
        self.cycle = 0

    def begin(self) -> None:
        """Clear the cycle's statistics and refresh the float32 frame positions (lamp and hash grid)."""
        self.stats.zero_()
        wp.launch(dem_to_frame, dim=self.n, inputs=[self.x, self._center], outputs=[self.pos32], device=self.device)

    def contacts(self) -> None:
        """Ball-ball contacts: neighbours, then the forces and moments (overwritten), new slot buffers."""
        d = self.device
        k = self.cycle % 2
        # The hash grid bins only, so the float32 frame copy (the positions shifted by a constant) serves.
        self.grid.build(self.pos32, self.query)
        wp.launch(
            dem_contacts,
            dim=self.n,
            inputs=[
                self.grid.id,
                self.x,
                self.v,
                self.w,
                self.radius,
                self.mass,
                self.query,
                self.ids[k],
                self.shear[k],
                self.mat,
                self.dt,
            ],
            outputs=[self.ids[1 - k], self.shear[1 - k], self.force, self.moment, self.stats],
            device=d,
        )

    def planes(self, planes: Planes) -> None:
        """Ball-plane contacts, added to the forces and moments; the planes' reactions are cleared first."""
        planes.reaction.zero_()
        wp.launch(
            dem_planes,
            dim=self.n,
            inputs=[
                self.x,
                self.v,
                self.w,
                self.radius,
                self.mass,
                planes.normal,
                planes.offset,
                planes.velocity,
                self.mat if planes.mat is None else planes.mat,
                self.dt,
            ],
            outputs=[planes.shear, self.force, self.moment, planes.reaction, self.stats],
            device=self.device,
        )

    def integrate(self, external: wp.array) -> None:
        """Damping and the Euler step, with ``external`` forces [N] (vec3 float32, shape (N,)); ends the cycle."""
        wp.launch(
            dem_integrate,
            dim=self.n,
            inputs=[external, self.mass, self.inertia, self.mat, self.dt, self.force, self.moment],
            outputs=[self.x, self.v, self.w, self.stats],
            device=self.device,
        )
        self.cycle += 1

    def capture(self, cycle_fn, cycles: int = 2):
        """Record ``cycles`` calls of ``cycle_fn`` (an even number: the slot buffers swap by parity) in one CUDA
        graph; the cycle counter is left as it was (recording runs nothing)."""
        if cycles % 2 or self.cycle % 2:
            raise ValueError(f"cycles: need an even count from an even cycle, got {cycles} from {self.cycle}")
        start = self.cycle
        with wp.ScopedCapture(device=self.device) as cap:
            for _ in range(cycles):
                cycle_fn()
        self.cycle = start
        return cap.graph

    def unbalanced_ratio(self) -> float:
        """Mean resultant force on the particles over mean contact normal force (PFC's ratio), last cycle."""
        sum_unbalanced, sum_contact, contacts = self.stats.numpy()
        return float((sum_unbalanced / self.n) / (sum_contact / (2 * contacts))) if contacts else np.inf

    def sphere_stress(self, center, diameter: float) -> np.ndarray:
        """Stress [Pa] in a measurement sphere, PFC's formula, compression positive (the module docstring);
        ball-ball contacts of the last cycle, symmetric part. Shape (3, 3)."""
        center = np.asarray(center, dtype=np.float64)
        x = self.x.numpy() - center
        r = self.radius.numpy()
        R = diameter / 2.0
        dist = np.linalg.norm(x, axis=1)
        inside = dist < R
        ids = self.ids[self.cycle % 2].numpy()
        shear = self.shear[self.cycle % 2].numpy()
        p, s = np.nonzero((ids >= 0) & inside[:, None])
        q = ids[p, s]
        d = x[q] - x[p]
        length = np.linalg.norm(d, axis=1)
        nrm = d / length[:, None]
        overlap = r[p] + r[q] - length
        kn = 4.0 * float(self.mat.e_c) * r[p] * r[q] / (r[p] + r[q])
        f = -(kn * overlap)[:, None] * nrm + shear[p, s]
        branch = (r[p] - 0.5 * overlap)[:, None] * nrm
        total = branch.T @ f
        vol = 4.0 / 3.0 * np.pi * r**3
        # Particle volume inside the measurement sphere: whole balls, and lenses for those crossing its surface.
        whole = dist + r <= R
        lens = ~whole & (dist < R + r)
        solid = vol[whole].sum() + sum(_lens(R, ri, di) for ri, di in zip(r[lens], dist[lens], strict=True))
        porosity = 1.0 - solid / (4.0 / 3.0 * np.pi * R**3)
        # Compression positive: forces on p push from the contact toward p.
        sigma = -(1.0 - porosity) / vol[inside].sum() * total
        return 0.5 * (sigma + sigma.T)


def _lens(R: float, r: float, d: float) -> float:
    """Volume of the intersection of balls of radii R and r with centres d apart (they overlap, neither inside)."""
    return np.pi * (R + r - d) ** 2 * (d * d + 2 * d * r - 3 * r * r + 2 * d * R + 6 * r * R - 3 * R * R) / (12 * d)


def median_gpu_time(fn, device, repeats: int = 20) -> float:
    """Median seconds of ``fn()`` between CUDA events after a warm-up (host clock, synchronised, on the CPU)."""
    from warp_lamp.timing import time_median_events

    return time_median_events(fn, device, repeats=repeats)
