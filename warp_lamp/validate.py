"""Host-side input checks: each error names the argument and, for data, the first bad index."""

from __future__ import annotations

import numpy as np

__all__ = ["check_particles", "check_pressure"]


def _first_bad(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask.reshape(mask.shape[0], -1).any(axis=1))[0])


def check_particles(centers, radii) -> tuple[np.ndarray, np.ndarray]:
    """Return float64 copies of ``centers`` (N, 3) and ``radii`` (N,), or raise ValueError naming the problem."""
    try:
        c = np.asarray(centers, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"centers: not convertible to a float array ({e})") from None
    try:
        r = np.asarray(radii, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"radii: not convertible to a float array ({e})") from None
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"centers: expected shape (N, 3), got {c.shape}")
    if r.ndim == 0:
        r = np.full(c.shape[0], float(r))
    if r.shape != (c.shape[0],):
        raise ValueError(f"radii: expected shape ({c.shape[0]},) to match centers, got {r.shape}")
    if c.shape[0] and not np.isfinite(c).all():
        k = _first_bad(~np.isfinite(c))
        raise ValueError(f"centers: non-finite value at index {k}: {c[k].tolist()}")
    if r.shape[0] and not (np.isfinite(r) & (r > 0)).all():
        k = _first_bad(~(np.isfinite(r) & (r > 0)))
        raise ValueError(f"radii: must be finite and > 0; index {k} is {r[k]!r}")
    return c, r


def check_pressure(pressure) -> np.ndarray:
    """Pressure as float64 (Px, Py, Pz) [Pa]: one number for all axes, or one per axis."""
    try:
        p = np.asarray(pressure, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"pressure: expected a number or 3 numbers ({e})") from None
    if p.ndim == 0:
        p = np.full(3, float(p))
    if p.shape == (1,):
        p = np.full(3, float(p[0]))
    if p.shape != (3,):
        raise ValueError(f"pressure: expected a number or 3 numbers, got shape {p.shape}")
    if not np.isfinite(p).all():
        k = int(np.flatnonzero(~np.isfinite(p))[0])
        raise ValueError(f"pressure: must be finite; index {k} is {p[k]!r}")
    return p
