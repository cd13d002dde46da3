"""Error and load measures that the benchmark, the CLI and the tests report, each defined once."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_lamp.grid import LampGrid
from warp_lamp.lamp import LAMPS, ShiningLamp
from warp_lamp.validate import check_particles, check_positive, check_vec3

__all__ = [
    "ball_outer_normals",
    "block_face_interior",
    "direction_error",
    "envelope_stress",
    "lone_sphere_area_error",
    "lone_sphere_error",
    "slot_load_ratios",
    "sphere_stress",
    "stress_summary",
    "visible_area_error",
]


def lone_sphere_error(criterion: int, cells_per_diameter: float, device, *, samples: int = 256, seed: int = 7) -> float:
    """E_area: RMS, over random sub-cell offsets of a lone sphere and over the six lamps, of F_lamp / (P pi r^2) - 1.

    Args:
        criterion: The lamp's criterion (0 or 1).
        cells_per_diameter: Cells per sphere diameter.
        device: Warp device.
        samples: Random offsets of the sphere within a cell.
        seed: Seed of the offsets.
    """
    r = 0.5
    h = 2 * r / cells_per_diameter
    grid = LampGrid([-1.0] * 3, [1.0] * 3, h)
    lamp = ShiningLamp(grid, criterion=criterion, device=device)
    offsets = np.random.default_rng(seed).uniform(0.0, h, (samples, 3))
    rad = wp.array([r], dtype=wp.float32, device=device)
    errs = []
    for off in offsets:
        lamp.update(wp.array([off], dtype=wp.vec3, device=device), rad)
        lit = lamp.diagnostics().lit
        errs.extend(lit[name] * h * h / (np.pi * r * r) - 1.0 for name in LAMPS)
    return float(np.sqrt(np.mean(np.square(errs))))


def lone_sphere_area_error(
    resolver: str, cells_per_diameter: float, device, *, samples: int = 64, seed: int = 7, subpoints: int = 8
) -> dict:
    """The area criterion's lone-sphere error: over random sub-cell offsets and the six lamps, each lamp's load
    over P pi r^2, minus 1.

    Args:
        resolver: ``"exact"`` or ``"subpoints"``.
        cells_per_diameter: Cells per sphere diameter.
        device: Warp device.
        samples: Random offsets of the sphere within a cell.
        seed: Seed of the offsets.
        subpoints: S of the sub-point resolver.

    Returns:
        ``rms`` and ``worst`` (the largest magnitude) of that relative error.
    """
    r = 0.5
    h = 2 * r / cells_per_diameter
    grid = LampGrid([-1.0] * 3, [1.0] * 3, h)
    offsets = np.random.default_rng(seed).uniform(0.0, h, (samples, 3))
    rad = wp.array([r], dtype=wp.float32, device=device)
    errs = []
    for lamps in (("-x", "-y", "-z"), ("+x", "+y", "+z")):
        lamp = ShiningLamp(grid, criterion="area", resolver=resolver, subpoints=subpoints, lamps=lamps, device=device)
        for off in offsets:
            lamp.update(wp.array([off], dtype=wp.vec3, device=device), rad)
            load = np.abs(lamp.counts_numpy()[0]) * grid.cell_area / lamp.unit
            errs.extend(load / (np.pi * r * r) - 1.0)
    errs = np.asarray(errs)
    return {"rms": float(np.sqrt(np.mean(errs**2))), "worst": float(np.abs(errs).max())}


def envelope_stress(centers, forces, center, volume: float) -> np.ndarray:
    """Average stress that external point loads imply on a body: sigma = (1/V) sum_i (x_i - x_c) (x) F_i.

    Tension positive: a body under fluid pressure P has sigma close to -P I, so its mean pressure is
    -trace(sigma)/3 (see :func:`stress_summary`).

    Args:
        centers: Load points (particle centres) [m], shape (N, 3).
        forces: Loads [N], shape (N, 3).
        center: Reference point [m], shape (3,) (the moment of balanced loads does not depend on it).
        volume: Volume to average over [m^3] (the body's envelope).

    Returns:
        sigma [Pa], shape (3, 3).
    """
    x = np.asarray(centers, dtype=np.float64) - np.asarray(center, dtype=np.float64)
    return np.einsum("ni,nj->ij", x, np.asarray(forces, dtype=np.float64)) / float(volume)


def stress_summary(sigma: np.ndarray, pressure: float) -> dict:
    """Mean pressure -tr(sigma)/3 and the deviatoric (Frobenius) norm of sigma, both over ``pressure``."""
    mean = -np.trace(sigma) / 3.0
    deviator = sigma + mean * np.eye(3)
    return {
        "mean_pressure_over_P": float(mean / pressure),
        "deviatoric_over_P": float(np.linalg.norm(deviator) / pressure),
    }


# --- direction error ----------------------------------------------------------------------------------------


def direction_error(forces, normals, select=None) -> dict:
    """Angle between each selected particle's force and its inward normal of the body's envelope.

    Particles with a zero force have no direction: they are left out of the angles and counted as ``unloaded``.

    Args:
        forces: Particle forces [N], shape (N, 3).
        normals: Inward normal of the envelope at each particle, shape (N, 3) (any length > 0 where selected).
        select: The surface particles to measure, bool, shape (N,); all by default.

    Returns:
        ``mean_deg`` and ``p90_deg`` (the 90th percentile, linear interpolation) of the angles [degrees],
        ``weighted_mean_deg`` (weighted by |F|), and the counts ``particles`` (selected), ``loaded`` (measured) and
        ``unloaded``; the angles are None where no selected particle is loaded.
    """
    f = np.asarray(forces, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"forces: expected shape (N, 3), got {f.shape}")
    if n.shape != f.shape:
        raise ValueError(f"normals: expected shape {f.shape}, got {n.shape}")
    sel = np.ones(len(f), dtype=bool) if select is None else np.asarray(select, dtype=bool)
    if sel.shape != (len(f),):
        raise ValueError(f"select: expected shape ({len(f)},), got {sel.shape}")
    mag = np.linalg.norm(f, axis=1)
    loaded = sel & (mag > 0)
    out = {"particles": int(sel.sum()), "loaded": int(loaded.sum()), "unloaded": int((sel & ~loaded).sum())}
    nl = np.linalg.norm(n[loaded], axis=1)
    if np.any(~(nl > 0)):
        k = int(np.flatnonzero(loaded)[np.flatnonzero(~(nl > 0))[0]])
        raise ValueError(f"normals: must be nonzero where a loaded particle is selected; index {k} is {n[k].tolist()}")
    if not loaded.any():
        return {**out, "mean_deg": None, "p90_deg": None, "weighted_mean_deg": None}
    cosine = np.sum(f[loaded] * n[loaded], axis=1) / (mag[loaded] * nl)
    angle = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    return {
        **out,
        "mean_deg": float(angle.mean()),
        "p90_deg": float(np.percentile(angle, 90)),
        "weighted_mean_deg": float(np.average(angle, weights=mag[loaded])),
    }


def block_face_interior(index, n_per_axis, *, rotation=None, edge: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The surface particles of a lattice block's face interiors, and each one's inward face normal.

    A particle is on face -a (+a) when its lattice index on axis a is 0 (n_a - 1): the block's outermost layer.
    It is in that face's interior when its other two lattice indices are at least ``edge`` from both ends
    (``edge <= i <= n - 1 - edge``), away from the edges, where two faces meet and the envelope has no single
    normal. With ``edge >= 1`` a particle is in at most one face interior.

    Args:
        index: Lattice index (ix, iy, iz) of each particle, shape (N, 3), integers.
        n_per_axis: Lattice sites along each axis, an int or three ints.
        rotation: How the body was turned (world = R body, about any point): the normals are R times the body's
            face normals; the identity by default.
        edge: Lattice sites left out next to each face edge, >= 1.

    Returns:
        ``(select, normals)``: bool, shape (N,), and the inward normals in world coordinates, shape (N, 3) (zero
        where not selected).
    """
    idx = np.asarray(index)
    if idx.ndim != 2 or idx.shape[1] != 3:
        raise ValueError(f"index: expected shape (N, 3), got {idx.shape}")
    n3 = np.broadcast_to(np.asarray(n_per_axis, dtype=np.int64), (3,))
    if isinstance(edge, bool) or not isinstance(edge, (int, np.integer)) or edge < 1:
        raise ValueError(f"edge: expected an integer >= 1, got {edge!r}")
    r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
    if r.shape != (3, 3):
        raise ValueError(f"rotation: expected a 3 x 3 matrix, got shape {r.shape}")
    select = np.zeros(len(idx), dtype=bool)
    normals = np.zeros((len(idx), 3))
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        inner = (idx[:, u] >= edge) & (idx[:, u] <= n3[u] - 1 - edge) & (idx[:, v] >= edge)
        inner &= idx[:, v] <= n3[v] - 1 - edge
        for at, sign in ((0, 1.0), (n3[a] - 1, -1.0)):
            on = inner & (idx[:, a] == at)
            select |= on
            normals[on] = sign * r[:, a]
    return select, normals


def ball_outer_normals(centers, center, radius: float, depth: float) -> tuple[np.ndarray, np.ndarray]:
    """The outer particles of a ball-shaped body, and the inward radial direction at each one.

    Args:
        centers: Particle centres [m], shape (N, 3).
        center: Centre of the envelope sphere [m], shape (3,).
        radius: Radius of the envelope sphere [m].
        depth: A particle is outer when its centre lies farther than ``radius - depth`` from ``center`` [m].

    Returns:
        ``(select, normals)``: bool, shape (N,), and the unit inward radial directions, shape (N, 3) (zero at the
        centre itself).
    """
    x = np.asarray(centers, dtype=np.float64) - np.asarray(center, dtype=np.float64)
    dist = np.linalg.norm(x, axis=1)
    normals = np.zeros_like(x)
    nz = dist > 0
    normals[nz] = -x[nz] / dist[nz, None]
    return (dist > radius - depth) & nz, normals


# --- force error against the exact visible areas -------------------------------------------------------------


def visible_area_error(forces, exact_areas, pressure: float, mean_radius: float) -> dict:
    """Per-particle force error against the exact visible projected areas, over P pi rbar^2.

    The exact force on particle i along axis a is ``P (A[i, -a] - A[i, +a])``: what the lamp converges to as its
    cells shrink (:func:`warp_lamp.reference.visible_area_reference` gives A, columns in ``LAMPS`` order). The
    error of a particle is the length of its force error vector over ``P pi rbar^2``.

    Args:
        forces: The lamp's forces [N], shape (N, 3), in the axes of the exact areas (an axis-aligned lamp).
        exact_areas: Exact visible area of each particle from each lamp [m^2], shape (N, 6).
        pressure: The pressure the forces were computed with [Pa].
        mean_radius: rbar [m].

    Returns:
        ``rms``: RMS over the surface particles (those with any exact visible area; the README's table),
        ``rms_all``: RMS over all particles, ``worst``: the largest error and ``worst_particle`` its index,
        ``surface``: the number of surface particles.
    """
    f = np.asarray(forces, dtype=np.float64)
    a = np.asarray(exact_areas, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"forces: expected shape (N, 3), got {f.shape}")
    if a.shape != (len(f), 6):
        raise ValueError(f"exact_areas: expected shape ({len(f)}, 6), got {a.shape}")
    if not (np.isfinite(pressure) and pressure > 0):
        raise ValueError(f"pressure: must be finite and > 0, got {pressure!r}")
    if not (np.isfinite(mean_radius) and mean_radius > 0):
        raise ValueError(f"mean_radius: must be finite and > 0, got {mean_radius!r}")
    exact = pressure * (a[:, 0::2] - a[:, 1::2])
    err = np.linalg.norm(f - exact, axis=1) / (pressure * np.pi * mean_radius**2)
    surface = a.sum(axis=1) > 0
    k = int(np.argmax(err)) if len(err) else -1
    return {
        "rms": float(np.sqrt(np.mean(err[surface] ** 2))) if surface.any() else 0.0,
        "rms_all": float(np.sqrt(np.mean(err**2))) if len(err) else 0.0,
        "worst": float(err[k]) if len(err) else 0.0,
        "worst_particle": k,
        "surface": int(surface.sum()),
    }


# --- slot block load ratios ----------------------------------------------------------------------------------


def slot_load_ratios(scene, forces, pressure: float) -> dict:
    """Wall and floor load ratios of the slot block (:func:`warp_lamp.scenes.scene_slot_block`).

    - Walls: the lateral force pushing into each wall, summed over the lattice column next to the slot
      (iy = ``wall_lo`` pushed toward -y, iy = ``wall_hi`` toward +y) over the slot's depth (iz >= ``k0``), over
      P L D: the load the fluid in the slot puts on that wall.
    - Floor: the downward force on the layer under the slot (iz = ``floor``, ``j0`` <= iy < ``j1``), over P L w;
      ``floor_plus`` also counts the two corner columns (iy = ``wall_lo`` and ``wall_hi``).

    Args:
        scene: The slot block (a :class:`~warp_lamp.scenes.CutScene` with ``cut["kind"] == "slot"``).
        forces: Particle forces [N], shape (N, 3), in the block's axes.
        pressure: The pressure the forces were computed with [Pa].

    Returns:
        ``wall_lo``, ``wall_hi``, ``floor``, ``floor_plus``: each 1 where the lamp puts on that part the load the
        fluid does.
    """
    cut = getattr(scene, "cut", None)
    if not isinstance(cut, dict) or cut.get("kind") != "slot":
        raise ValueError("scene: expected a slot block (scenes.scene_slot_block)")
    f = np.asarray(forces, dtype=np.float64)
    if f.shape != (scene.n, 3):
        raise ValueError(f"forces: expected shape ({scene.n}, 3), got {f.shape}")
    if not (np.isfinite(pressure) and pressure > 0):
        raise ValueError(f"pressure: must be finite and > 0, got {pressure!r}")
    idx = scene.index
    top = idx[:, 2] >= cut["k0"]
    lo = (idx[:, 1] == cut["wall_lo"]) & top
    hi = (idx[:, 1] == cut["wall_hi"]) & top
    layer = idx[:, 2] == cut["floor"]
    floor = layer & (idx[:, 1] >= cut["j0"]) & (idx[:, 1] < cut["j1"])
    floor_plus = layer & (idx[:, 1] >= cut["wall_lo"]) & (idx[:, 1] <= cut["wall_hi"])
    side = pressure * cut["length"] * cut["depth"]
    bottom = pressure * cut["length"] * cut["width"]
    return {
        "wall_lo": float(-f[lo, 1].sum() / side),
        "wall_hi": float(f[hi, 1].sum() / side),
        "floor": float(-f[floor, 2].sum() / bottom),
        "floor_plus": float(-f[floor_plus, 2].sum() / bottom),
    }


# --- PFC's measurement-sphere stress, for engines that hand out their contacts (issue 24) --------------------


def _lens_volume(R: float, r: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Volume of the intersection of balls of radii R and r whose centres are d apart (they overlap, and neither
    holds the other)."""
    return np.pi * (R + r - d) ** 2 * (d * d + 2 * d * r - 3 * r * r + 2 * d * R + 6 * r * R - 3 * R * R) / (12 * d)


def sphere_stress(centers, radii, pairs, forces, center, diameter: float) -> np.ndarray:
    """Stress in a measurement sphere, PFC's formula with its porosity correction, compression positive.

    sigma = -(1 - n) / sum V_p * sum_p sum_c (x_c - x_p) (x) F_c,p over the particles p whose centres lie inside
    the measurement sphere, c their contacts, F_c,p the force contact c puts on p, and n the porosity of the
    measurement sphere (particle volume inside it, lens-exact for the particles its surface cuts). The contact
    point x_c lies on the line of centres in the middle of the overlap, r_p - overlap / 2 from x_p (as
    ``examples/dem.py`` and YADE's ScGeom place it). Returns the symmetric part.

    Args:
        centers: Particle centres [m], shape (N, 3).
        radii: Particle radii [m], shape (N,).
        pairs: Contacts, each once, as particle indices (i, j), shape (C, 2), integers.
        forces: Force of each contact on its first particle i [N], shape (C, 3); j takes the opposite.
        center: Centre of the measurement sphere [m], shape (3,).
        diameter: Diameter of the measurement sphere [m].

    Returns:
        sigma [Pa], shape (3, 3), compression positive (a body under fluid pressure P has sigma close to P I).
    """
    x, r = check_particles(centers, radii)
    n = len(r)
    p = np.asarray(pairs)
    if p.dtype.kind not in "iu" or p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"pairs: expected integers of shape (C, 2), got {p.dtype} {p.shape}")
    if p.size and (p.min() < 0 or p.max() >= n):
        k = int(np.flatnonzero(((p < 0) | (p >= n)).any(axis=1))[0])
        raise ValueError(f"pairs: indices must lie in [0, {n}); contact {k} is {p[k].tolist()}")
    if p.size and np.any(p[:, 0] == p[:, 1]):
        k = int(np.flatnonzero(p[:, 0] == p[:, 1])[0])
        raise ValueError(f"pairs: a particle cannot touch itself; contact {k} is {p[k].tolist()}")
    f = np.asarray(forces, dtype=np.float64)
    if f.shape != (len(p), 3):
        raise ValueError(f"forces: expected shape ({len(p)}, 3), one row per contact, got {f.shape}")
    if f.size and not np.isfinite(f).all():
        k = int(np.flatnonzero(~np.isfinite(f).all(axis=1))[0])
        raise ValueError(f"forces: non-finite value at contact {k}: {f[k].tolist()}")
    c = check_vec3("center", center)
    R = check_positive("diameter", diameter) / 2.0
    rel = x - c
    dist = np.linalg.norm(rel, axis=1)
    inside = dist < R
    if not inside.any():
        raise ValueError(f"diameter: no particle centre lies inside the measurement sphere of diameter {diameter!r}")
    i, j = p[:, 0].astype(np.int64), p[:, 1].astype(np.int64)
    d = x[j] - x[i]
    length = np.linalg.norm(d, axis=1)
    if np.any(length == 0):
        k = int(np.flatnonzero(length == 0)[0])
        raise ValueError(f"pairs: contact {k} joins two particles at the same centre")
    nrm = d / length[:, None]
    overlap = r[i] + r[j] - length
    # Branch vectors from each particle's centre to the contact point, in the middle of the overlap.
    bi = (r[i] - 0.5 * overlap)[:, None] * nrm
    bj = bi - d
    total = (bi[inside[i]].T @ f[inside[i]]) - (bj[inside[j]].T @ f[inside[j]])
    vol = 4.0 / 3.0 * np.pi * r**3
    whole = dist + r <= R
    lens = ~whole & (dist < R + r)
    solid = vol[whole].sum() + _lens_volume(R, r[lens], dist[lens]).sum()
    porosity = 1.0 - solid / (4.0 / 3.0 * np.pi * R**3)
    sigma = -(1.0 - porosity) / vol[inside].sum() * total
    return 0.5 * (sigma + sigma.T)
