"""An independent brute-force answer for the wetted-surface mode (``surfaces="all"``), float64, for the tests.

Nothing from ``warp_lamp.wetted``, its kernels or its reference is used: the fluid is found from its definition on a
lattice of points much finer than the lamp's cells, and each lamp ray is walked along the lattice.

- Probe centres: lattice points z (spacing ``g``) with ``|z - c_i| >= r_i + rho`` for every sphere and
  ``n . z - d >= rho`` for every wall, 6-connected (scipy's ``ndimage.label``) to the lattice's outer layer, which
  lies beyond every inflated sphere (on the fluid side of the walls).
- Fluid: a lattice point outside every sphere and wall within ``rho`` of such a probe centre (scipy's exact
  Euclidean distance transform of the lattice).
- Loads: the lattice holds every lamp ray (the centre line of a cell of grid a: ``g`` divides half a cell), walked
  from beyond the box to beyond it; a change from fluid to dry going +a is a +1 on axis a for the low lamp and a
  change from dry to fluid a -1 for the high lamp, each to the sphere nearest the change's midpoint by
  ``|p - c| - r`` (to a wall instead where a wall that cuts axis a is nearer).

The lattice sees the continuum's fluid to within about one spacing: a throat narrower than ``g`` is closed to it,
the fluid's edge may move inward by up to ``sqrt(3) g / 2``, and an interval along a ray shorter than ``g`` may be
missed.
"""

from dataclasses import dataclass

import numpy as np
from scipy import ndimage


@dataclass
class BruteFluid:
    """The fluid on a lattice: ``fluid[i, j, k]`` at ``origin + (i, j, k) g``; spheres and walls (planes n, d)."""

    origin: np.ndarray
    g: float
    fluid: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    planes: list


def brute_fluid(centers, radii, rho, lower, upper, *, walls=(), g) -> BruteFluid:
    """The fluid of probe radius ``rho`` around the spheres (and walls ``[(point, normal), ...]``, the fluid on the
    normal's side) on a lattice of spacing ``g`` through ``lower``, covering [lower, upper] and a margin."""
    c = np.asarray(centers, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    lower, upper = np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64)
    planes = []
    for p, n in walls:
        n = np.asarray(n, dtype=np.float64) / np.linalg.norm(n)
        planes.append((n, float(n @ np.asarray(p, dtype=np.float64))))
    lo = np.minimum(lower, (c - r[:, None]).min(axis=0) - rho) - rho - 3 * g
    hi = np.maximum(upper, (c + r[:, None]).max(axis=0) + rho) + rho + 3 * g
    first = np.floor((lo - lower) / g).astype(np.int64)  # lattice index of lo relative to lower (<= 0)
    last = np.ceil((hi - lower) / g).astype(np.int64)
    origin = lower + first * g
    axes = [origin[k] + np.arange(last[k] - first[k] + 1) * g for k in range(3)]
    shape = tuple(len(x) for x in axes)
    allowed = np.ones(shape, dtype=bool)
    solid = np.zeros(shape, dtype=bool)
    for ci, ri in zip(c, r, strict=True):
        sl, sub = [], []
        for k in range(3):
            i0 = max(int(np.floor((ci[k] - ri - rho - origin[k]) / g)) - 1, 0)
            i1 = min(int(np.ceil((ci[k] + ri + rho - origin[k]) / g)) + 2, shape[k])
            sl.append(slice(i0, i1))
            sub.append(axes[k][i0:i1] - ci[k])
        d2 = sub[0][:, None, None] ** 2 + sub[1][None, :, None] ** 2 + sub[2][None, None, :] ** 2
        allowed[tuple(sl)] &= d2 >= (ri + rho) ** 2
        solid[tuple(sl)] |= d2 < ri * ri
    for n, d in planes:
        value = n[0] * axes[0][:, None, None] + n[1] * axes[1][None, :, None] + n[2] * axes[2][None, None, :] - d
        allowed &= value >= rho
        solid |= value < 0
    labels, _ = ndimage.label(allowed)
    border = np.concatenate([labels[[0, -1]].ravel(), labels[:, [0, -1]].ravel(), labels[:, :, [0, -1]].ravel()])
    reached = np.isin(labels, np.unique(border[border > 0]))
    near = ndimage.distance_transform_edt(~reached, sampling=g) <= rho
    return BruteFluid(origin, g, near & ~solid, c, r, planes)


def brute_counts(fluid: BruteFluid, lower, counts, h):
    """Per-particle counts of the lamps of the box grid ``LampGrid(lower, lower + counts h, h)`` on the lattice.

    Returns:
        (low, high): int64 arrays (N, 3): +1 per fluid-to-dry change along +a (the -a lamp), -1 per dry-to-fluid
        change (the +a lamp), per particle and axis.
    """
    g, c, r = fluid.g, fluid.centers, fluid.radii
    half = 0.5 * h / g
    if abs(half - round(half)) > 1e-9:
        raise ValueError("g: must divide half a cell")
    base = np.rint((np.asarray(lower, dtype=np.float64) - fluid.origin) / g).astype(np.int64)
    low = np.zeros((len(r), 3), dtype=np.int64)
    high = np.zeros((len(r), 3), dtype=np.int64)
    step = round(h / g)
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        iu = base[u] + round(half) + step * np.arange(counts[u])
        iv = base[v] + round(half) + step * np.arange(counts[v])
        lines = np.moveaxis(fluid.fluid, (a, u, v), (0, 1, 2))[:, iu[:, None], iv[None, :]]
        change = lines[1:] != lines[:-1]
        t, ku, kv = np.nonzero(change)
        entering = lines[t, ku, kv]  # fluid before the change: fluid to dry going +a
        p = np.empty((len(t), 3))
        p[:, a] = fluid.origin[a] + (t + 0.5) * g
        p[:, u] = fluid.origin[u] + iu[ku] * g
        p[:, v] = fluid.origin[v] + iv[kv] * g
        gap = np.linalg.norm(p[:, None, :] - c[None], axis=2) - r[None]
        owner = np.argmin(gap, axis=1)
        best = gap[np.arange(len(t)), owner]
        wall = np.full(len(t), np.inf)
        for n, d in fluid.planes:
            if n[a] != 0:
                wall = np.minimum(wall, p @ n - d)
        mine = ~(wall < best)
        np.add.at(low[:, a], owner[mine & entering], 1)
        np.add.at(high[:, a], owner[mine & ~entering], -1)
    return low, high
