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
        if stats.shape[0] > 0:
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
        if stats.shape[0] > 0:
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
    if stats.shape[0] > 0:
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


# --- bonded particles (PFC's parallel bonds), a rigid tool, fixed particles, fragments --------------------------


@wp.struct
class BondMaterial:
    """Parallel-bond stiffness, as the bond kernel takes it (float64): PFC's k_n = E_b / (R_a + R_b) per area."""

    e_c: wp.float64  # bond modulus [Pa]
    kn_ks: wp.float64  # normal over shear stiffness per area
    tan_phi: wp.float64  # tangent of the bond's friction angle: shear strength c - (F_n / A) tan(phi)


@wp.func
def carry_tangent(u: wp.vec3d, n: wp.vec3d, spin: wp.float64):
    """A vector of the bond's tangent plane carried with the bond: into the plane normal to ``n`` with its length
    kept, then turned by ``spin`` [rad] about ``n`` (the pair's mean spin over the step)."""
    p = u - wp.dot(u, n) * n
    lp = wp.length(p)
    if lp > wp.float64(0.0):
        p = p * (wp.length(u) / lp)
    return p * wp.cos(spin) + wp.cross(n, p) * wp.sin(spin)


@wp.kernel(enable_backward=False)
def dem_bonds(
    x: wp.array[wp.vec3d],
    v: wp.array[wp.vec3d],
    w: wp.array[wp.vec3d],
    radius: wp.array[wp.float64],
    end_a: wp.array[wp.int32],
    end_b: wp.array[wp.int32],
    bond_radius: wp.array[wp.float64],
    tensile: wp.array[wp.float64],
    shear: wp.array[wp.float64],
    mat: BondMaterial,
    dt: wp.float64,
    # outputs
    state: wp.array[wp.int32],
    fn: wp.array[wp.float64],
    fs: wp.array[wp.vec3d],
    mt: wp.array[wp.float64],
    mb: wp.array[wp.vec3d],
    force_a: wp.array[wp.vec3d],
    moment_a: wp.array[wp.vec3d],
    moment_b: wp.array[wp.vec3d],
    broken: wp.array[wp.int32],
):
    """One thread per bond: PFC's parallel bond (Potyondy and Cundall 2004), incremental, between particles a and b.

    A disk of radius R = ``bond_radius`` at the middle of the gap (or overlap) between the two surfaces, area
    A = pi R^2, I = pi R^4 / 4, J = 2 I, stiffness per area k_n = E_b / (R_a + R_b), k_s = k_n / (k_n/k_s). Each
    step: the normal force (tension positive) grows by k_n A times the opening, the shear force on b by -k_s A times
    the sliding, the twisting and bending moments on b by -k_s J and -k_n I times the relative turn; shear force and
    bending moment are first carried with the bond (:func:`carry_tangent`). The bond breaks for good, in tension
    (state 1) when sigma = F_n / A + |M_b| R / I reaches ``tensile``, else in shear (state 2) when
    tau = |F_s| / A + |M_t| R / J reaches ``shear`` - (F_n / A) tan(phi) (PFC5's linear parallel bond: the
    cohesion ``shear`` and a friction angle, ``mat.tan_phi``; 0 for PFC4's parallel bond); ``broken[0]`` and
    ``broken[1]`` count those. Writes the force
    on a and the moments on a and b (b's force is minus a's), zero for a broken bond."""
    k = wp.tid()
    zero = wp.vec3d()
    if state[k] != 0:
        force_a[k] = zero
        moment_a[k] = zero
        moment_b[k] = zero
        return
    i = end_a[k]
    j = end_b[k]
    d = x[j] - x[i]
    dist = wp.length(d)
    if dist == wp.float64(0.0):
        force_a[k] = zero
        moment_a[k] = zero
        moment_b[k] = zero
        return
    n = d / dist
    ri = radius[i]
    rj = radius[j]
    arm_i = ri + wp.float64(0.5) * (dist - ri - rj)  # from i's centre to the bond's plane
    arm_j = dist - arm_i
    # Velocity of b's material point at the bond relative to a's.
    vc = (v[j] + wp.cross(w[j], -arm_j * n)) - (v[i] + wp.cross(w[i], arm_i * n))
    vn = wp.dot(vc, n)
    vt = vc - vn * n
    rb = bond_radius[k]
    area = wp.float64(wp.pi) * rb * rb
    inertia = wp.float64(0.25) * area * rb * rb
    polar = wp.float64(2.0) * inertia
    kn = mat.e_c / (ri + rj)
    ks = kn / mat.kn_ks
    spin = wp.float64(0.5) * wp.dot(w[i] + w[j], n) * dt
    f_n = fn[k] + kn * area * vn * dt
    f_s = carry_tangent(fs[k], n, spin) - ks * area * vt * dt
    dw = w[j] - w[i]
    dwn = wp.dot(dw, n)
    m_t = mt[k] - ks * polar * dwn * dt
    m_b = carry_tangent(mb[k], n, spin) - kn * inertia * (dw - dwn * n) * dt
    sigma = f_n / area + wp.length(m_b) * rb / inertia
    tau = wp.length(f_s) / area + wp.abs(m_t) * rb / polar
    mode = int(0)
    if sigma >= tensile[k]:
        mode = 1
    elif tau >= shear[k] - f_n / area * mat.tan_phi:
        mode = 2
    if mode != 0:
        state[k] = mode
        wp.atomic_add(broken, mode - 1, 1)
        fn[k] = wp.float64(0.0)
        fs[k] = zero
        mt[k] = wp.float64(0.0)
        mb[k] = zero
        force_a[k] = zero
        moment_a[k] = zero
        moment_b[k] = zero
        return
    fn[k] = f_n
    fs[k] = f_s
    mt[k] = m_t
    mb[k] = m_b
    fb = f_s - f_n * n  # on b: pulled toward a in tension, dragged by the shear spring
    mbond = m_t * n + m_b
    force_a[k] = -fb
    moment_a[k] = wp.cross(arm_i * n, -fb) - mbond
    moment_b[k] = wp.cross(-arm_j * n, fb) + mbond


@wp.kernel(enable_backward=False)
def dem_bond_gather(
    offsets: wp.array[wp.int32],
    entries: wp.array[wp.int32],
    force_a: wp.array[wp.vec3d],
    moment_a: wp.array[wp.vec3d],
    moment_b: wp.array[wp.vec3d],
    # outputs
    force: wp.array[wp.vec3d],
    moment: wp.array[wp.vec3d],
):
    """One thread per particle adds its bonds' forces and moments, in the fixed order of its bond list (entry
    2 k + side: bond k, side 0 for end a, 1 for end b), so the sums do not depend on thread order."""
    i = wp.tid()
    f = force[i]
    m = moment[i]
    for e in range(offsets[i], offsets[i + 1]):
        code = entries[e]
        k = code >> 1
        if (code & 1) == 0:
            f = f + force_a[k]
            m = m + moment_a[k]
        else:
            f = f - force_a[k]
            m = m + moment_b[k]
    force[i] = f
    moment[i] = m


@wp.kernel(enable_backward=False)
def dem_tool(
    x: wp.array[wp.vec3d],
    v: wp.array[wp.vec3d],
    w: wp.array[wp.vec3d],
    radius: wp.array[wp.float64],
    external: wp.array[wp.vec3],
    tip: wp.array[wp.vec3d],
    velocity: wp.array[wp.vec3d],
    face: wp.vec3d,
    side: wp.vec3d,
    up: wp.vec3d,
    extent: wp.vec3d,
    mat: Material,
    dt: wp.float64,
    # outputs
    shear: wp.array[wp.vec3d],
    force: wp.array[wp.vec3d],
    moment: wp.array[wp.vec3d],
    reaction: wp.array[wp.int64],
    stats: wp.array[wp.float64],
):
    """A rigid tool, a box moving at ``velocity``, against the particles: the box is {tip + u face + s side + h up :
    -extent[0] <= u <= 0, |s| <= extent[1] / 2, 0 <= h <= extent[2]}, its working face the u = 0 side (``face`` its
    unit outward normal), ``tip`` the middle of the face's bottom edge. Each ball meets the box's closest point
    (exact for a box: clamped local coordinates) with the law of :func:`dem_planes` (kn = 2 E_c R, incremental shear,
    Coulomb). Adds to force and moment; sums the force on the particles (units of 2^-24 N) into reaction[0:3], the
    contacts into reaction[3], and the ``external`` forces (the lamp's) on the particles it touches into
    reaction[4:7], as integers, so the sums do not depend on thread order."""
    i = wp.tid()
    xi = x[i]
    ri = radius[i]
    rel = xi - tip[0]
    u = wp.dot(rel, face)
    s = wp.dot(rel, side)
    h = wp.dot(rel, up)
    cu = wp.clamp(u, -extent[0], wp.float64(0.0))
    cs = wp.clamp(s, wp.float64(-0.5) * extent[1], wp.float64(0.5) * extent[1])
    ch = wp.clamp(h, wp.float64(0.0), extent[2])
    gap = (u - cu) * face + (s - cs) * side + (h - ch) * up  # from the box's closest point to the centre
    dist = wp.length(gap)
    n = wp.vec3d()
    overlap = wp.float64(0.0)
    if dist > wp.float64(0.0):
        n = gap / dist
        overlap = ri - dist
    else:
        # The centre inside the box (never in a sound run): out through the nearest face.
        depth = -u
        n = face
        if u + extent[0] < depth:
            depth = u + extent[0]
            n = -face
        if wp.float64(0.5) * extent[1] - wp.abs(s) < depth:
            depth = wp.float64(0.5) * extent[1] - wp.abs(s)
            n = side * wp.where(s < wp.float64(0.0), wp.float64(-1.0), wp.float64(1.0))
        if h < depth:
            depth = h
            n = -up
        if extent[2] - h < depth:
            depth = extent[2] - h
            n = up
        overlap = ri + depth
    if overlap <= wp.float64(0.0):
        shear[i] = wp.vec3d()
        return
    kn = wp.float64(2.0) * mat.e_c * ri
    ks = kn / mat.kn_ks
    fn = kn * overlap
    vc = velocity[0] - (v[i] + wp.cross(w[i], -ri * n))
    vt = vc - wp.dot(vc, n) * n
    fs = shear[i]
    fs = fs - wp.dot(fs, n) * n
    fs = fs + ks * vt * dt
    fs, fnd, fd = contact_law(fs, vt, wp.dot(vc, n), fn, kn, ks, wp.float64(0.0), mat.mu)
    shear[i] = fs
    fi = fnd * n + fd
    force[i] = force[i] + fi
    moment[i] = moment[i] + wp.cross(-ri * n, fd)
    for a in range(3):
        wp.atomic_add(reaction, a, wp.int64(wp.round(fi[a] * _FORCE_SCALE_64)))
        wp.atomic_add(reaction, 4 + a, wp.int64(wp.round(wp.float64(external[i][a]) * _FORCE_SCALE_64)))
    wp.atomic_add(reaction, 3, wp.int64(1))
    if stats.shape[0] > 0:
        wp.atomic_add(stats, 1, wp.float64(2.0) * fn)
        wp.atomic_add(stats, 2, wp.float64(1.0))


@wp.kernel(enable_backward=False)
def dem_tool_advance(
    reaction: wp.array[wp.int64],
    velocity: wp.array[wp.vec3d],
    dt: wp.float64,
    # outputs
    tip: wp.array[wp.vec3d],
    total: wp.array[wp.float64],
):
    """One thread: the tool moves by velocity dt; ``total`` sums, over the cycles, the force on the particles [N]
    (0:3), the contacts (3), the lamp's force on the particles it touched [N] (4:7) and the cycles (7)."""
    for a in range(3):
        total[a] = total[a] + wp.float64(reaction[a]) / _FORCE_SCALE_64
        total[4 + a] = total[4 + a] + wp.float64(reaction[4 + a]) / _FORCE_SCALE_64
    total[3] = total[3] + wp.float64(reaction[3])
    total[7] = total[7] + wp.float64(1.0)
    tip[0] = tip[0] + velocity[0] * dt


@wp.kernel(enable_backward=False)
def dem_hold(
    ids: wp.array[wp.int32],
    held: wp.array[wp.vec3d],
    velocity: wp.vec3d,
    # outputs
    x: wp.array[wp.vec3d],
    v: wp.array[wp.vec3d],
    w: wp.array[wp.vec3d],
):
    """Held particles: back to their held positions (after the integration moved them), moving at ``velocity``
    without turning; the bonds and contact dashpots see that velocity (a grip pulled at constant speed moves its
    held positions by velocity dt each cycle)."""
    k = wp.tid()
    i = ids[k]
    x[i] = held[k]
    v[i] = velocity
    w[i] = wp.vec3d()


@wp.kernel(enable_backward=False)
def dem_in_box(
    x: wp.array[wp.vec3d],
    lower: wp.vec3d,
    upper: wp.vec3d,
    # outputs
    inside: wp.array[wp.int32],
):
    """1 for a particle whose centre lies in the box [lower, upper], 0 elsewhere (an ``active`` mask)."""
    i = wp.tid()
    p = x[i]
    ok = int(1)
    for a in range(3):
        if p[a] < lower[a] or p[a] > upper[a]:
            ok = 0
    inside[i] = ok


@wp.kernel(enable_backward=False)
def dem_held_force(
    ids: wp.array[wp.int32],
    force: wp.array[wp.vec3d],
    # outputs
    total: wp.array[wp.int64],
):
    """Sums the force the other particles put on the held particles ``ids`` (before the integration), in units of
    2^-24 N as integers, so the sum does not depend on thread order."""
    k = wp.tid()
    f = force[ids[k]]
    for a in range(3):
        wp.atomic_add(total, a, wp.int64(wp.round(f[a] * _FORCE_SCALE_64)))


@wp.kernel(enable_backward=False)
def dem_held_advance(
    step: wp.vec3d,
    # outputs
    held: wp.array[wp.vec3d],
):
    """Moves held positions by ``step`` [m] (a grip pulled at constant speed)."""
    k = wp.tid()
    held[k] = held[k] + step


@wp.kernel(enable_backward=False)
def dem_plane_advance(
    speed: wp.array[wp.float64],
    normal: wp.array[wp.vec3d],
    dt: wp.float64,
    # outputs
    offset: wp.array[wp.float64],
    velocity: wp.array[wp.vec3d],
    total: wp.array[wp.float64],
    reaction: wp.array2d[wp.int64],
):
    """One thread per plane: it moves toward the particles at ``speed`` [m/s]; ``total`` sums its normal spring
    force over the cycles [N] (for means between samples)."""
    p = wp.tid()
    total[p] = total[p] + wp.float64(reaction[p, 0]) / _FORCE_SCALE_64
    offset[p] = offset[p] + speed[p] * dt
    velocity[p] = normal[p] * speed[p]


@wp.kernel(enable_backward=False)
def dem_label_init(
    # outputs
    label: wp.array[wp.int32],
):
    i = wp.tid()
    label[i] = i


@wp.kernel(enable_backward=False)
def dem_label_hook(
    end_a: wp.array[wp.int32],
    end_b: wp.array[wp.int32],
    state: wp.array[wp.int32],
    # outputs
    label: wp.array[wp.int32],
    changed: wp.array[wp.int32],
):
    """One thread per intact bond: the larger of its ends' labels (roots after a jump) is hooked under the smaller
    (an atomic minimum), so labels only fall and stay inside their component."""
    k = wp.tid()
    if state[k] != 0:
        return
    li = label[end_a[k]]
    lj = label[end_b[k]]
    if li != lj:
        wp.atomic_min(label, wp.max(li, lj), wp.min(li, lj))
        changed[0] = 1


@wp.kernel(enable_backward=False)
def dem_label_jump(
    # outputs
    label: wp.array[wp.int32],
):
    """Pointer jumping: each particle's label becomes the root of its chain (labels point to smaller indices, so
    the chain ends)."""
    i = wp.tid()
    lab = label[i]
    up = label[lab]
    while up != lab:
        lab = up
        up = label[lab]
    label[i] = lab


@wp.kernel(enable_backward=False)
def dem_label_round(
    max_rounds: wp.int32,
    # outputs
    rounds: wp.array[wp.int32],
    changed: wp.array[wp.int32],
):
    """Counts a round; stops the loop at ``max_rounds`` (rounds[1] = 1 marks a cut-short solve)."""
    r = rounds[0] + 1
    rounds[0] = r
    if r >= max_rounds and changed[0] != 0:
        changed[0] = 0
        rounds[1] = 1


@wp.kernel(enable_backward=False)
def dem_label_sizes(
    label: wp.array[wp.int32],
    # outputs
    size: wp.array[wp.int32],
):
    i = wp.tid()
    wp.atomic_add(size, label[i], 1)


@dataclass
class Bonds:
    """Parallel bonds on the device: ends, radii, strengths, state (0 intact, 1 broken in tension, 2 in shear),
    the incremental forces and moments, and each particle's bond list (CSR) for the gather.

    ``broken`` counts the bonds broken in tension and in shear on the device; :meth:`components` labels the
    fragments (connected components of the intact bonds) on the device.
    """

    end_a: wp.array
    end_b: wp.array
    radius: wp.array
    tensile: wp.array
    shear_strength: wp.array
    mat: BondMaterial
    state: wp.array
    fn: wp.array
    fs: wp.array
    mt: wp.array
    mb: wp.array
    force_a: wp.array
    moment_a: wp.array
    moment_b: wp.array
    broken: wp.array
    offsets: wp.array
    entries: wp.array
    label: wp.array
    changed: wp.array
    rounds: wp.array
    size: wp.array

    @classmethod
    def create(
        cls, pairs, bond_radius, tensile, shear, n: int, *, e_c: float, kn_ks: float, friction_deg=0.0, device
    ) -> Bonds:
        """Bonds between ``pairs`` (shape (B, 2), particle indices, each pair once) for ``n`` particles.

        Args:
            pairs: Bonded particle pairs, shape (B, 2), int.
            bond_radius: Bond disk radius [m] per bond (PFC: lambda min(R_a, R_b)), shape (B,).
            tensile: Tensile strength [Pa] per bond, shape (B,).
            shear: Shear strength [Pa] per bond, shape (B,): the cohesion when ``friction_deg`` > 0.
            n: Particle count.
            e_c: Bond modulus [Pa]: normal stiffness per area E_b / (R_a + R_b).
            kn_ks: Normal over shear stiffness per area.
            friction_deg: Friction angle of the bond's shear strength [degrees]: it rises by tan(phi) times the
                bond's mean compressive stress (PFC5's linear parallel bond); 0, PFC4's constant shear strength.
            device: Warp device.
        """
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        b = len(pairs)
        for name, arr in (("bond_radius", bond_radius), ("tensile", tensile), ("shear", shear)):
            arr = np.asarray(arr, dtype=np.float64)
            if arr.shape != (b,):
                raise ValueError(f"{name}: expected shape ({b},), got {arr.shape}")
            bad = np.flatnonzero(~(np.isfinite(arr) & (arr > 0)))
            if len(bad):
                raise ValueError(f"{name}: must be finite and > 0; index {bad[0]} is {arr[bad[0]]!r}")
        bad = np.flatnonzero((pairs[:, 0] == pairs[:, 1]) | (pairs.min(axis=1) < 0) | (pairs.max(axis=1) >= n))
        if len(bad):
            raise ValueError(f"pairs: need two different particles in [0, {n}); index {bad[0]} is {pairs[bad[0]]}")
        # Each particle's bonds in increasing bond order: entry 2 k + side.
        ends = pairs.ravel()
        codes = 2 * np.repeat(np.arange(b), 2) + np.tile([0, 1], b)
        order = np.lexsort((codes, ends))
        offsets = np.zeros(n + 1, dtype=np.int64)
        np.add.at(offsets, ends + 1, 1)
        offsets = np.cumsum(offsets)
        d = device
        m = BondMaterial()
        m.e_c = wp.float64(e_c)
        m.kn_ks = wp.float64(kn_ks)
        m.tan_phi = wp.float64(np.tan(np.radians(friction_deg)))

        def f64(a):
            return wp.array(np.asarray(a, dtype=np.float64), dtype=wp.float64, device=d)

        return cls(
            wp.array(pairs[:, 0].astype(np.int32), dtype=wp.int32, device=d),
            wp.array(pairs[:, 1].astype(np.int32), dtype=wp.int32, device=d),
            f64(bond_radius),
            f64(tensile),
            f64(shear),
            m,
            wp.zeros(b, dtype=wp.int32, device=d),
            wp.zeros(b, dtype=wp.float64, device=d),
            wp.zeros(b, dtype=wp.vec3d, device=d),
            wp.zeros(b, dtype=wp.float64, device=d),
            wp.zeros(b, dtype=wp.vec3d, device=d),
            wp.zeros(b, dtype=wp.vec3d, device=d),
            wp.zeros(b, dtype=wp.vec3d, device=d),
            wp.zeros(b, dtype=wp.vec3d, device=d),
            wp.zeros(2, dtype=wp.int32, device=d),
            wp.array(offsets.astype(np.int32), dtype=wp.int32, device=d),
            wp.array(codes[order].astype(np.int32), dtype=wp.int32, device=d),
            wp.zeros(n, dtype=wp.int32, device=d),
            wp.zeros(1, dtype=wp.int32, device=d),
            wp.zeros(2, dtype=wp.int32, device=d),
            wp.zeros(n, dtype=wp.int32, device=d),
        )

    @property
    def count(self) -> int:
        return self.end_a.shape[0]

    def broken_counts(self) -> tuple[int, int]:
        """Bonds broken so far in tension and in shear (a host copy)."""
        t, s = self.broken.numpy()
        return int(t), int(s)

    def components(self, max_rounds: int = 64) -> None:
        """Label the fragments on the device: ``label[i]`` becomes the smallest particle index of i's connected
        component of intact bonds (hooking and pointer jumping, in a ``wp.capture_while`` loop of at most
        ``max_rounds`` rounds; ``rounds`` holds the count and a cut-short flag), ``size[l]`` the particles labelled
        l. Capture-safe: nothing allocates or reads the device on the host."""
        d = self.label.device
        n = self.label.shape[0]
        wp.launch(dem_label_init, dim=n, outputs=[self.label], device=d)
        self.rounds.zero_()
        self.changed.fill_(1)

        def round_body():
            self.changed.zero_()
            wp.launch(
                dem_label_hook,
                dim=self.count,
                inputs=[self.end_a, self.end_b, self.state],
                outputs=[self.label, self.changed],
                device=d,
            )
            wp.launch(dem_label_jump, dim=n, outputs=[self.label], device=d)
            wp.launch(dem_label_round, dim=1, inputs=[max_rounds], outputs=[self.rounds, self.changed], device=d)

        wp.capture_while(self.changed, round_body)
        self.size.zero_()
        wp.launch(dem_label_sizes, dim=n, inputs=[self.label], outputs=[self.size], device=d)


@dataclass
class Tool:
    """A rigid box tool on the device (:func:`dem_tool`): its tip and velocity (device arrays, so a captured graph
    sees them move and change), axes and extents, contact law, each particle's shear spring, the last cycle's
    reaction and the sums since :meth:`reset_totals`."""

    tip: wp.array
    velocity: wp.array
    face: tuple
    side: tuple
    up: tuple
    extent: tuple
    mat: Material
    shear: wp.array
    reaction: wp.array
    total: wp.array

    @classmethod
    def create(cls, tip, face, side, extent, n: int, mat: Material, device) -> Tool:
        """A box tool with its working face's bottom edge centred at ``tip`` [m], outward face normal ``face`` and
        edge direction ``side`` (unit vectors, orthogonal), ``extent`` = (thickness behind the face, width along
        ``side``, height along the face) [m], for ``n`` particles."""
        face = np.asarray(face, dtype=np.float64)
        side = np.asarray(side, dtype=np.float64)
        if abs(np.linalg.norm(face) - 1) > 1e-12 or abs(np.linalg.norm(side) - 1) > 1e-12 or abs(face @ side) > 1e-12:
            raise ValueError("face, side: need orthogonal unit vectors")
        up = np.cross(face, side)  # along the face, away from the tip
        return cls(
            wp.array([np.asarray(tip, dtype=np.float64)], dtype=wp.vec3d, device=device),
            wp.zeros(1, dtype=wp.vec3d, device=device),
            wp.vec3d(*face),
            wp.vec3d(*side),
            wp.vec3d(*up),
            wp.vec3d(*np.asarray(extent, dtype=np.float64)),
            mat,
            wp.zeros(n, dtype=wp.vec3d, device=device),
            wp.zeros(7, dtype=wp.int64, device=device),
            wp.zeros(8, dtype=wp.float64, device=device),
        )

    def reset_totals(self) -> None:
        self.total.zero_()

    def totals(self) -> dict:
        """Means since :meth:`reset_totals` (a host copy): force on the particles [N], contacts, the lamp's force
        on the particles touched [N], cycles."""
        t = self.total.numpy()
        c = max(t[7], 1.0)
        return {"force": t[0:3] / c, "contacts": t[3] / c, "lamp": t[4:7] / c, "cycles": int(t[7])}


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


class BlockRunner:
    """Runs a simulation in whole blocks of ``block`` cycles: eagerly on the CPU, as replays of one captured graph
    on CUDA (the examples' triaxial test and rock cutting). A subclass sets ``dem``, ``device``, ``block``,
    ``_graph = None`` and ``_loaded = False``, and defines ``_block()`` (one block, eagerly) and ``capture()`` (one
    block recorded into a graph)."""

    def advance(self, cycles: int) -> None:
        """Run whole blocks (replays of the captured block on CUDA) for at least ``cycles`` cycles."""
        blocks = -(-cycles // self.block)
        if not self.device.is_cuda:
            for _ in range(blocks):
                self._block()
            return
        if not self._loaded:
            self._block()  # load the modules and fill the lamp before recording
            blocks -= 1
            self._loaded = True
        if self._graph is None:
            self._graph = self.capture()
        for _ in range(blocks):
            wp.capture_launch(self._graph)
        self.dem.cycle += blocks * self.block


class Dem:
    """Particles, their float64 state and the pieces of one cycle; the examples put the lamp in between.

    A cycle is ``begin()``, ``contacts()``, optionally ``planes()``, then ``integrate(external)``. Contact
    histories live in two slot buffers that swap by cycle parity, so an even number of cycles replays from a
    CUDA graph (see :meth:`capture`).
    """

    def __init__(
        self, centers, radii, mass, inertia, mat: Material, dt: float, *, frame_center=None, stats=True, device=None
    ):
        """Args:
        centers: Particle centres [m], shape (N, 3).
        radii: Particle radii [m], shape (N,).
        mass: Particle masses [kg], shape (N,).
        inertia: Moments of inertia [kg m^2], shape (N,).
        mat: Contact law and damping.
        dt: Time step [s].
        frame_center: Centre of the float32 frame the lamp and the hash grid see [m]; the mean centre by default.
        stats: Sum the unbalanced-force statistics (:meth:`unbalanced_ratio`) every cycle.
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
        # Unbalanced-force statistics cost two float64 atomics per contact on one address; stats=False skips them.
        self.stats = wp.zeros(3 if stats else 0, dtype=wp.float64, device=d)
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
        if self.stats.shape[0]:
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

    def bonds(self, bonds: Bonds) -> None:
        """Parallel bonds: their forces and moments, added to the particles' (after :meth:`contacts`)."""
        d = self.device
        wp.launch(
            dem_bonds,
            dim=bonds.count,
            inputs=[
                self.x,
                self.v,
                self.w,
                self.radius,
                bonds.end_a,
                bonds.end_b,
                bonds.radius,
                bonds.tensile,
                bonds.shear_strength,
                bonds.mat,
                self.dt,
            ],
            outputs=[
                bonds.state,
                bonds.fn,
                bonds.fs,
                bonds.mt,
                bonds.mb,
                bonds.force_a,
                bonds.moment_a,
                bonds.moment_b,
                bonds.broken,
            ],
            device=d,
        )
        wp.launch(
            dem_bond_gather,
            dim=self.n,
            inputs=[bonds.offsets, bonds.entries, bonds.force_a, bonds.moment_a, bonds.moment_b],
            outputs=[self.force, self.moment],
            device=d,
        )

    def tool(self, tool: Tool, external: wp.array) -> None:
        """Ball-tool contacts, added to the forces and moments; the tool's reaction is cleared first. ``external``:
        the forces the lamp puts on the particles (float32 vec3), whose sum over those the tool touches it
        records."""
        tool.reaction.zero_()
        wp.launch(
            dem_tool,
            dim=self.n,
            inputs=[
                self.x,
                self.v,
                self.w,
                self.radius,
                external,
                tool.tip,
                tool.velocity,
                tool.face,
                tool.side,
                tool.up,
                tool.extent,
                tool.mat,
                self.dt,
            ],
            outputs=[tool.shear, self.force, self.moment, tool.reaction, self.stats],
            device=self.device,
        )

    def advance_tool(self, tool: Tool) -> None:
        """The tool's step after the integration: sums its reaction, moves it by velocity dt."""
        wp.launch(
            dem_tool_advance,
            dim=1,
            inputs=[tool.reaction, tool.velocity, self.dt],
            outputs=[tool.tip, tool.total],
            device=self.device,
        )

    def hold(self, ids: wp.array, held: wp.array, velocity=(0.0, 0.0, 0.0)) -> None:
        """Held particles ``ids`` (int32) back at ``held`` (vec3d), moving at ``velocity`` [m/s] (at rest by
        default); call after :meth:`integrate`."""
        if ids.shape[0]:
            wp.launch(
                dem_hold,
                dim=ids.shape[0],
                inputs=[ids, held, wp.vec3d(*velocity)],
                outputs=[self.x, self.v, self.w],
                device=self.device,
            )

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
        if self.stats.shape[0] == 0:
            raise RuntimeError("unbalanced_ratio: this Dem was made with stats=False")
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
