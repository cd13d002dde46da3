"""Lamp frames on the host: forces back to world coordinates, stress tensors through their principal frame, and
the fixed set of orientations that frame averaging uses."""

from __future__ import annotations

import sys
import warnings

import numpy as np

from warp_lamp.validate import check_force_range, check_pressure, format_value, lamp_rotation, user_stacklevel

__all__ = [
    "check_pressure_signs",
    "lamp_force_factors",
    "lamp_frame_rotations",
    "lamp_pressure",
    "lamp_stress_frame",
    "pressure_area",
    "round_rows26",
]


def _quantum26(x: np.ndarray) -> np.ndarray:
    """2^(e - 25) for 2^e <= |x| < 2^(e+1); 0 for x = 0 (no rounding)."""
    _, exponent = np.frexp(np.abs(x))
    return np.where(x != 0, np.ldexp(1.0, exponent - 26), 0.0)


def round_rows26(x: np.ndarray) -> np.ndarray:
    """Each row of x rounded to the nearest multiples (ties to even) of the 26-bit spacing of its largest entry.

    Every entry of a row is then a multiple of one power of two with at most 26 significant bits, so any sum of
    integer counts times the row is exact in float64 while the integers stay small (|count| < 2^25 per particle
    and axis, summed over three axes): the forces of all particles then sum to exactly zero. For a single
    nonzero entry this is the Veltkamp split's rounding to 26 bits (the same numbers, ties included).
    """
    x = np.asarray(x, dtype=np.float64)
    q = _quantum26(np.abs(x).max(axis=-1, keepdims=True))
    safe = np.where(q > 0, q, 1.0)
    return np.where(q > 0, np.rint(x / safe) * safe, x)


def lamp_force_factors(pressure, cell_area, rotation=None) -> np.ndarray:
    """F[j, a]: the world force component j [N] per unit count on lamp axis a, shape (3, 3).

    F = P_a A_a R[j, a], each row rounded by :func:`round_rows26`; the forces are ``counts @ F.T``, summed in the
    order a = 0, 1, 2, as the device does. With the identity this is ``diag(pressure_area)``: P_a A_a rounded to
    26 bits.

    Args:
        pressure: Pressure per lamp axis [Pa], 3 values.
        cell_area: Area per count on each lamp axis [m^2], 3 values: the cell area, divided by the area
            criterion's units per cell and multiplied by a frame's share of an average where those apply
            (``ShiningLamp`` passes its own).
        rotation: Lamp frame (columns: lamp axes in world coordinates); the identity by default.
    """
    r = lamp_rotation(rotation)
    area = np.asarray(cell_area, dtype=np.float64)
    p = np.asarray(pressure, dtype=np.float64)
    x = (p * area)[None, :] * r
    if not np.isfinite(x).all() or np.abs(x).max(initial=0.0) > 2.0**960:
        raise ValueError(
            f"pressure: P times the cell area ({(p * area).tolist()} N per count) is outside the range in which "
            "the forces can be rounded exactly"
        )
    return round_rows26(x)


def lamp_stress_frame(sigma) -> tuple[np.ndarray, np.ndarray]:
    """The principal frame of a stress tensor [Pa] (compression positive, as the lamp's pressure).

    Returns:
        (R, p): a rotation whose columns are the principal axes in world coordinates (right-handed, each as close
        to the world axis of the same index as the eigenvalues allow), and the principal values p, so that
        sigma = R diag(p) R^T. Use R as a lamp frame (``LampGrid(..., rotation=R)``) and p as its pressures.
    """
    s = _check_tensor(sigma)
    values, vectors = np.linalg.eigh(s)
    # Order and sign the axes to stay near the world axes: the permutation that best matches |R|, then signs.
    best = max(_permutations(), key=lambda perm: sum(abs(vectors[i, perm[i]]) for i in range(3)))
    r = vectors[:, list(best)]
    p = values[list(best)]
    for k in range(3):
        if r[k, k] < 0:
            r[:, k] = -r[:, k]
    if np.linalg.det(r) < 0:
        r[:, 2] = -r[:, 2]
    return lamp_rotation(r), p


def _permutations():
    return [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]


def _check_tensor(sigma) -> np.ndarray:
    s = np.asarray(sigma, dtype=np.float64)
    if s.shape != (3, 3):
        raise ValueError(f"pressure: a stress tensor must be 3 x 3, got shape {s.shape}")
    if not np.isfinite(s).all():
        k = int(np.flatnonzero(~np.isfinite(s).ravel())[0])
        raise ValueError(f"pressure: stress tensor must be finite; flat index {k} is {format_value(s.ravel()[k])}")
    scale = float(np.abs(s).max())
    asym = float(np.abs(s - s.T).max())
    if asym > 1e-12 * scale:
        raise ValueError(f"pressure: stress tensor must be symmetric (|sigma - sigma^T| = {asym:.3e})")
    return 0.5 * (s + s.T)


def lamp_pressure(pressure, rotation=None) -> tuple[np.ndarray, np.ndarray | None]:
    """The pressure per lamp axis [Pa] in a lamp frame, from a number, three numbers, or a stress tensor.

    A stress tensor (3 x 3, symmetric, compression positive) is applied through its principal values, which
    become the three lamp pressures: the same numbers given per axis get the same forces, the same checks and the
    same warning (:func:`check_pressure_signs`). A tensor must be diagonal in the lamp frame ``rotation`` to within
    1e-9 of its largest entry: the lamp pushes along its three axes only, so the shear of a tensor in another frame
    cannot be applied, and is refused rather than dropped. Without a ``rotation`` (None), the tensor's principal
    frame (:func:`lamp_stress_frame`) is returned as the frame to use. A pure shear (trace 0, off-diagonal only)
    is, in its principal frame, a push along one diagonal and a pull along the other: it is applied as such, with
    the warning for mixed signs.

    Returns:
        (p, frame): the pressures along the lamp axes, and the frame chosen for a tensor when ``rotation`` is None
        (else None).
    """
    if np.ndim(pressure) != 2:
        p = check_pressure(pressure)
        check_pressure_signs(p)
        return p, None
    s = _check_tensor(pressure)
    scale = float(np.abs(s).max())
    frame = None
    if rotation is None:
        frame, _ = lamp_stress_frame(s)
        r = frame
    else:
        r = lamp_rotation(rotation)
    local = r.T @ s @ r
    off = float(np.abs(local - np.diag(np.diag(local))).max())
    if off > 1e-9 * max(scale, np.finfo(float).tiny):
        raise ValueError(
            f"pressure: the stress tensor is not diagonal in the lamp frame (shear {off:.4g} Pa there): build the "
            "grid with rotation=warp_lamp.frames.lamp_stress_frame(sigma)[0], or pass the tensor without a grid"
        )
    p = np.diag(local).copy()
    # Rounding of the frame leaves principal values of a pure shear's null axis at about 1e-16 of the scale.
    p[np.abs(p) <= 1e-12 * scale] = 0.0
    check_pressure_signs(p)
    return p, frame


#: (pressures, file, line) already warned about by :func:`check_pressure_signs`: one call of the library checks
#: the same pressure more than once, and Warp's launches reset Python's own once-per-line record.
_SIGNS_WARNED: set = set()


def check_pressure_signs(p) -> None:
    """The one rule on the signs of the three lamp pressures, however they were given (one number, three, or a
    stress tensor's principal values): compression (> 0) pushes, tension (< 0) pulls, and any mix is applied as
    given; a mix of signs warns (UserWarning, once per value and line of the caller), since a fluid cannot push
    on some faces and pull on others: it is most often a tensor written with tension positive, or one sign slip.
    All of one sign (uniform suction included) is silent."""
    p = np.asarray(p, dtype=np.float64)
    if (p > 0).any() and (p < 0).any():
        level = user_stacklevel()
        caller = sys._getframe(level - 1)
        key = (tuple(p.tolist()), caller.f_code.co_filename, caller.f_lineno)
        if key in _SIGNS_WARNED:
            return
        _SIGNS_WARNED.add(key)
        warnings.warn(
            f"pressure: the lamp pressures (principal values) {[float(x) for x in p]} Pa mix compression (> 0, "
            "pushes) and tension (< 0, the lamp pulls there); compression is positive in warp_lamp",
            stacklevel=level,
        )


def _halton(index: int, base: int) -> float:
    f, x = 1.0, 0.0
    while index > 0:
        f /= base
        x += f * (index % base)
        index //= base
    return x


def lamp_frame_rotations(frames: int) -> np.ndarray:
    """The fixed orientations of frame averaging, shape (frames, 3, 3): the identity first, then Shoemake's
    uniform map of the Halton point (bases 2, 3, 5) of index k to a unit quaternion, for k = 1 .. frames - 1.

    Deterministic and low-discrepancy: the same K gives the same frames in every call and on every machine, and
    the first K of a larger set are the smaller set.
    """
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames < 1:
        raise ValueError(f"frames: expected an integer >= 1, got {format_value(frames)}")
    out = [np.eye(3)]
    for k in range(1, int(frames)):
        u1, u2, u3 = _halton(k, 2), _halton(k, 3), _halton(k, 5)
        a, b = np.sqrt(1.0 - u1), np.sqrt(u1)
        q = (
            a * np.sin(2 * np.pi * u2),
            a * np.cos(2 * np.pi * u2),
            b * np.sin(2 * np.pi * u3),
            b * np.cos(2 * np.pi * u3),
        )
        out.append(lamp_rotation(q))
    return np.array(out)


def _round26(x: np.ndarray) -> np.ndarray:
    t = x * 134217729.0
    return t - (t - x)


def pressure_area(pressure, grid) -> np.ndarray:
    """Force per lit cell on each axis [N], shape (3,): P_a times the cell area of grid a.

    Rounded to 26 significant bits (relative change below 1.5e-8), so that P_a A_a times any cell count is
    exact in float64: the forces of all particles then sum to exactly zero, in any order of summation. A
    simulator that needs that exact float64 sum from a :class:`~warp_lamp.ShiningLamp` (whose forces are float32)
    computes ``lamp.counts_numpy() * pressure_area(P, lamp.grid)`` (axis-aligned frame, criterion 0 or 1).

    Raises:
        ValueError: when P_a A_a leaves the range where this is exact (above about 1e291 N, or nonzero below the
            smallest normal float64), naming ``pressure``.
    """
    p = check_pressure(pressure)
    check_force_range(p, grid.cell_area, grid.counts[:, 0] * grid.counts[:, 1])
    return _round26(p * grid.cell_area)
