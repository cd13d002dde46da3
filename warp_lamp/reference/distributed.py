"""NumPy references of the distributed kernels (``kernels/distributed.py``): keys to global ids, the top-bit flip, the
merge of D-slot key lists over ranks, the owner test of the scatter (with walls too), and the fixed-point porosity
sums."""

from __future__ import annotations

import numpy as np

from warp_lamp.reference.porosity import sphere_box_volume

__all__ = [
    "EMPTY_KEY",
    "fixed_units_reference",
    "global_keys_reference",
    "merge_lists_reference",
    "reach_reference",
    "scatter_reference",
    "scatter_walls_reference",
]

EMPTY_KEY = np.uint64(0xFFFFFFFFFFFFFFFF)
_TOP = np.uint64(1 << 63)
_LOW = np.uint64(0xFFFFFFFF)


def global_keys_reference(keys, gids, *, flip: bool = False) -> np.ndarray:
    """Keys whose low 32 bits (a local index i) become gids[i]; EMPTY stays EMPTY; with ``flip`` the top bit of
    every result is inverted (unsigned order read as signed order).

    Args:
        keys: uint64 keys, shape (M,).
        gids: Global id of each local index, shape (N,).
        flip: Xor the top bit.
    """
    keys = np.asarray(keys, dtype=np.uint64)
    out = keys.copy()
    lit = keys != EMPTY_KEY
    local = (keys[lit] & _LOW).astype(np.int64)
    out[lit] = (keys[lit] & ~_LOW) | np.asarray(gids, dtype=np.int64)[local].astype(np.uint64)
    return out ^ _TOP if flip else out


def merge_lists_reference(lists) -> np.ndarray:
    """Per row, the D smallest distinct keys of the union of the ranks' rows, ascending, EMPTY padded.

    Args:
        lists: One uint64 array per rank, shape (M, D) each.
    """
    stacked = np.concatenate([np.asarray(x, dtype=np.uint64) for x in lists], axis=1)
    d = np.asarray(lists[0]).shape[1]
    out = np.full((stacked.shape[0], d), EMPTY_KEY, dtype=np.uint64)
    for m, row in enumerate(stacked):
        keep = np.unique(row[row != EMPTY_KEY])[:d]
        out[m, : len(keep)] = keep
    return out


def scatter_reference(reduced, keys, gids, caller, axis_of_cell, n) -> np.ndarray:
    """The counts one rank scatters: +1 (low lamp) / -1 (high lamp) on the cell's axis to the caller row of the
    rank's owner, for every cell whose reduced key is the rank's own key in global ids.

    Args:
        reduced: Reduced keys (global ids), two per cell, shape (2 C,).
        keys: The rank's keys (local indices in id order), shape (2 C,).
        gids: Global id of each local index, shape (N,).
        caller: Caller row of each local index, shape (N,), or empty for the identity.
        axis_of_cell: Each cell's axis, shape (C,).
        n: Particles of the rank.
    """
    counts = np.zeros((n, 3), dtype=np.int64)
    mine = global_keys_reference(keys, gids)
    for slot in np.flatnonzero((np.asarray(reduced) != EMPTY_KEY) & (mine == np.asarray(reduced))):
        i = int(keys[slot] & _LOW)
        row = int(caller[i]) if len(caller) else i
        counts[row, axis_of_cell[slot // 2]] += 1 if slot % 2 == 0 else -1
    return counts


def reach_reference(centers, radii, corner, cell, counts, criterion: int) -> np.ndarray:
    """The cells the spheres light, as a box per grid: (min i, max i, min j, max j) of every cell (i, j) of grid a
    whose ray meets a sphere (criterion 1: the ray through the cell centre passes within r of the centre; criterion
    0: the cell's rectangle meets the projected disk); (big, -1, big, -1) for a grid no sphere lights. Brute force
    over every cell, in float64.

    Args:
        centers: Sphere centres in the grid's local coordinates [m], shape (N, 3).
        radii: Radii [m], shape (N,).
        corner, cell, counts: The grids' corners, cell edges and cell counts (``LampGrid``), shape (3, 2) each.
        criterion: 0 or 1.
    """
    big = np.iinfo(np.int32).max
    out = np.array([big, -1, big, -1] * 3, dtype=np.int64)
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        nu, nv = (int(x) for x in counts[a])
        iu = np.arange(nu)
        jv = np.arange(nv)
        for c, r in zip(np.asarray(centers, dtype=np.float64), np.asarray(radii, dtype=np.float64), strict=True):
            pu, pv = c[u] - corner[a, 0], c[v] - corner[a, 1]
            if criterion == 1:
                du = (iu + 0.5) * cell[a, 0] - pu
                dv = (jv + 0.5) * cell[a, 1] - pv
            else:
                du = np.maximum(np.maximum(iu * cell[a, 0] - pu, pu - (iu + 1) * cell[a, 0]), 0.0)
                dv = np.maximum(np.maximum(jv * cell[a, 1] - pv, pv - (jv + 1) * cell[a, 1]), 0.0)
            hit = dv[:, None] ** 2 + du[None, :] ** 2 <= r * r
            if hit.any():
                jj, ii = np.nonzero(hit)
                out[4 * a : 4 * a + 4] = (
                    min(out[4 * a], ii.min()), max(out[4 * a + 1], ii.max()),
                    min(out[4 * a + 2], jj.min()), max(out[4 * a + 3], jj.max()),
                )  # fmt: skip
    return out


def scatter_walls_reference(reduced, keys, gids, caller, axis_of_cell, n, walled, n_walls, recoils=None) -> tuple:
    """The counts one rank scatters when walls bound the fluid, given who takes each ray of the reduced keys
    (``walled``, two per cell: a global id >= 0, wall w as -2 - w, or -1 for nobody): a particle's +1 (low lamp) /
    -1 (high lamp) goes to the rank's caller row where the reduced key is the rank's own key in global ids; a wall's
    goes to the wall's counts, on every rank.

    Args:
        reduced: Reduced keys (global ids), two per cell, shape (2 C,).
        keys: The rank's keys (local indices in id order), shape (2 C,).
        gids: Global id of each local index, shape (N,).
        caller: Caller row of each local index, shape (N,), or empty for the identity.
        axis_of_cell: Each cell's axis, shape (C,).
        n: Particles of the rank.
        walled: Who takes each ray, shape (2 C,).
        n_walls: Number of walls W.
        recoils: Optional, shape (2 C,): the wall (>= 0, or -1) at each lamp's end of the fluid, which takes the
            opposite of the lamp's count.

    Returns:
        (counts, wall_counts): int64, shapes (N, 3) and (W, 3).
    """
    walled = np.asarray(walled)
    taken = np.where(walled >= 0, np.asarray(reduced), EMPTY_KEY)
    counts = scatter_reference(taken, keys, gids, caller, axis_of_cell, n)
    wall_counts = np.zeros((n_walls, 3), dtype=np.int64)
    for slot in np.flatnonzero(walled <= -2):
        wall_counts[-2 - int(walled[slot]), axis_of_cell[slot // 2]] += 1 if slot % 2 == 0 else -1
    if recoils is not None:
        for slot in np.flatnonzero(np.asarray(recoils) >= 0):
            wall_counts[int(recoils[slot]), axis_of_cell[slot // 2]] -= 1 if slot % 2 == 0 else -1
    return counts, wall_counts


def fixed_units_reference(local, radii, h, shape, method: str, bits: int = 40) -> np.ndarray:
    """Per cell, the sum over spheres of round(v 2^bits / cell volume), v the sphere-cell volume in float64: the
    whole sphere in the cell of its centre (``"centroid"``), its bounding cube's overlap (``"polyhedron"``) or the
    exact ball-box volume (``"exact"``); int64 (Python integers summed).

    Args:
        local: Centres relative to the box's lower corner [m], shape (N, 3).
        radii: Radii [m], shape (N,).
        h: Cell edges [m], 3 values.
        shape: Cells along x, y, z.
        method: ``"centroid"``, ``"polyhedron"`` or ``"exact"``.
        bits: Fractional bits of a cell volume.
    """
    local = np.asarray(local, dtype=np.float64).reshape(-1, 3)
    radii = np.asarray(radii, dtype=np.float64)
    h = np.asarray(h, dtype=np.float64)
    shape = tuple(int(x) for x in shape)
    scale = 2.0**bits / float(np.prod(h))
    units = np.zeros(shape, dtype=np.int64)
    for c, r in zip(local, radii, strict=True):
        if method == "centroid":
            idx = np.floor(c / h)
            if np.all((idx >= 0) & (idx < shape)):
                units[tuple(idx.astype(int))] += int(np.floor(4.0 / 3.0 * np.pi * r**3 * scale + 0.5))
            continue
        first = np.clip(np.floor((c - r) / h), 0, np.asarray(shape) - 1).astype(int)
        last = np.clip(np.floor((c + r) / h), 0, np.asarray(shape) - 1).astype(int)
        if np.any(c + r < 0) or np.any(c - r >= h * shape):
            continue
        for i in range(first[0], last[0] + 1):
            for j in range(first[1], last[1] + 1):
                for k in range(first[2], last[2] + 1):
                    lo = np.array([i, j, k]) * h - c
                    if method == "exact":
                        v = float(sphere_box_volume(lo, lo + h, r))
                    else:
                        v = float(np.prod(np.maximum(np.minimum(lo + h, r) - np.maximum(lo, -r), 0.0)))
                    if v > 0:
                        units[i, j, k] += int(np.floor(v * scale + 0.5))
    return units
