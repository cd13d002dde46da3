"""Host-side input checks: each error names the argument and, for data, the first bad index."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

__all__ = [
    "DEFAULT_MAX_BYTES",
    "LAMPS",
    "check_box",
    "check_budget",
    "check_particles",
    "check_pressure",
    "check_shape",
    "check_subdivisions",
    "check_vec3",
    "lamp_mask",
    "lamp_names",
    "lamp_rotation",
]

#: Default budget for the device memory one lamp grid or one porosity call may take [bytes].
DEFAULT_MAX_BYTES = 2 << 30


#: Lamp names in bit order: "-x" is the lamp at minus infinity on x, shining toward +x.
LAMPS = ("-x", "+x", "-y", "+y", "-z", "+z")


def lamp_names(lamps) -> tuple[str, ...]:
    """The lamps that are on, as a tuple of names from :data:`LAMPS`: ``"all"``, one name, or any iterable of names.

    The iterable is read once, here, so that a generator is not consumed by validation and then seen empty.
    """
    if isinstance(lamps, str):
        lamps = LAMPS if lamps == "all" else (lamps,)
    if not isinstance(lamps, Iterable):
        raise ValueError(f"lamps: expected 'all' or names from {LAMPS}, got {lamps!r}")
    names = tuple(lamps)
    for name in names:
        if name not in LAMPS:
            raise ValueError(f"lamps: unknown lamp {name!r}; expected 'all' or names from {LAMPS}")
    return names


def lamp_mask(lamps) -> int:
    """Bit mask of the lamps that are on (bit k for ``LAMPS[k]``); ``lamps`` as for :func:`lamp_names`."""
    mask = 0
    for name in lamp_names(lamps):
        mask |= 1 << LAMPS.index(name)
    return mask


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
    p = np.asarray(pressure, dtype=object)
    if p.shape == (1,):
        pressure = p[0]
    return check_vec3("pressure", pressure)


def check_vec3(name: str, value, *, positive: bool = False) -> np.ndarray:
    """Three finite float64 values (a scalar is repeated), > 0 where ``positive``."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: expected a number or 3 numbers ({e})") from None
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,):
        raise ValueError(f"{name}: expected a number or 3 numbers, got shape {arr.shape}")
    bad = ~np.isfinite(arr) | ((arr <= 0) if positive else False)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        need = "finite and > 0" if positive else "finite"
        raise ValueError(f"{name}: must be {need}; index {k} is {arr[k]!r}")
    return arr


def check_box(lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """A box's corners as float64 (3,) arrays, ``upper`` above ``lower`` on every axis."""
    lo = check_vec3("lower", lower)
    hi = check_vec3("upper", upper)
    if np.any(hi <= lo):
        k = int(np.flatnonzero(hi <= lo)[0])
        raise ValueError(f"upper: must exceed lower on every axis; axis {k} has {hi[k]!r} <= {lo[k]!r}")
    return lo, hi


def check_shape(shape) -> tuple[int, int, int]:
    """Three integers >= 1 (cells along x, y, z)."""
    sh = np.asarray(shape).reshape(-1)
    if sh.shape != (3,) or not np.issubdtype(sh.dtype, np.integer):
        raise ValueError(f"shape: expected 3 integers (nx, ny, nz), got {shape!r}")
    if np.any(sh < 1):
        k = int(np.flatnonzero(sh < 1)[0])
        raise ValueError(f"shape: every entry must be >= 1; index {k} is {int(sh[k])}")
    return tuple(int(x) for x in sh)


def check_subdivisions(subdivisions) -> int:
    """An integer >= 1."""
    if isinstance(subdivisions, bool) or not isinstance(subdivisions, (int, np.integer)) or subdivisions < 1:
        raise ValueError(f"subdivisions: expected an integer >= 1, got {subdivisions!r}")
    return int(subdivisions)


def check_budget(need: int, max_bytes, what: str, remedy: str) -> None:
    """Raise ValueError, before anything is allocated, when ``need`` bytes exceed ``max_bytes``.

    Args:
        need: Bytes the call would allocate.
        max_bytes: The caller's budget [bytes].
        what: The start of the message: the argument to blame and what needs ``need`` bytes.
        remedy: How to need fewer.
    """
    if need > max_bytes:
        raise ValueError(f"{what}, over the budget of {int(max_bytes):,} bytes ({remedy})")


def lamp_rotation(rotation, *, name: str = "rotation") -> np.ndarray:
    """A lamp frame's orientation as a float64 3 x 3 rotation matrix (columns: the lamp axes in world coordinates).

    Accepts None (the identity), a 3 x 3 matrix, or a unit quaternion (x, y, z, w). Refuses, naming ``name``, what
    is not finite, not orthonormal to 1e-6, or a reflection (det -1). The matrix is re-orthonormalised (polar
    factor), so that R^T R = I to rounding.
    """
    if rotation is None:
        return np.eye(3)
    try:
        r = np.asarray(rotation, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: expected a 3 x 3 rotation matrix or a unit quaternion ({e})") from None
    if not np.isfinite(r).all():
        k = int(np.flatnonzero(~np.isfinite(r).ravel())[0])
        raise ValueError(f"{name}: must be finite; flat index {k} is {r.ravel()[k]!r}")
    if r.shape == (4,):
        norm = float(np.linalg.norm(r))
        if abs(norm - 1.0) > 1e-6:
            raise ValueError(f"{name}: a quaternion (x, y, z, w) must have unit norm, got {norm!r}")
        x, y, z, w = r / norm
        r = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
    if r.shape != (3, 3):
        raise ValueError(f"{name}: expected a 3 x 3 rotation matrix or a unit quaternion, got shape {r.shape}")
    err = float(np.abs(r.T @ r - np.eye(3)).max())
    if err > 1e-6:
        raise ValueError(f"{name}: not orthonormal (|R^T R - I| = {err:.2e}, above 1e-6)")
    if np.linalg.det(r) < 0:
        raise ValueError(f"{name}: a reflection (det = -1), not a rotation")
    if np.array_equal(r, np.eye(3)):
        return np.eye(3)
    u, _, vt = np.linalg.svd(r)
    return u @ vt
