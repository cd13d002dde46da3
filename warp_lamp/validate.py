"""Host-side input checks: each error names the argument and, for data, the first bad index.

Every check here runs on the host, before anything is allocated or launched. Device paths that a CUDA graph may
capture never raise: they skip bad elements and count them (see :class:`warp_lamp.ShiningLamp`).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Iterator

import numpy as np

__all__ = [
    "DEFAULT_MAX_BYTES",
    "EXACT_CELLS",
    "LAMPS",
    "WALL_REST",
    "array_device",
    "check_box",
    "check_budget",
    "check_device_match",
    "check_force_range",
    "check_grid_cells",
    "check_integer",
    "check_mask",
    "check_max_bytes",
    "check_particle_arrays",
    "check_particles",
    "check_positions",
    "check_positive",
    "check_pressure",
    "check_shape",
    "check_subdivisions",
    "check_vec3",
    "check_warp_array",
    "format_bytes",
    "format_value",
    "host_array",
    "lamp_mask",
    "lamp_names",
    "lamp_rotation",
    "radii_unit_hint",
    "resolve_device",
    "unit_mixup_hint",
    "user_stacklevel",
    "walls_behind_message",
]

#: Default budget for the device memory one lamp grid or one porosity call may take [bytes].
DEFAULT_MAX_BYTES = 2 << 30

#: Most cells one lamp grid (one axis) may have: P_a A_a keeps 26 significant bits, so every partial sum of
#: P_a A_a times at most 2**27 cells has at most 53 and is exact in float64; the forces then sum to exactly zero in
#: any order.
EXACT_CELLS = 1 << 27

#: Largest |P_a A_a| [N]: its Veltkamp split multiplies it by 2**27 + 1, and it is then multiplied by up to 2**27
#: cells, both of which must stay finite in float64.
_MAX_PRESSURE_AREA = np.finfo(np.float64).max / 2.0**56
#: Smallest nonzero |P_a A_a| [N]: below the smallest normal float64, the 26-bit rounding is no longer exact.
_MIN_PRESSURE_AREA = np.finfo(np.float64).tiny
_FLOAT32_MAX = float(np.finfo(np.float32).max)


def format_bytes(n: float) -> str:
    """``n`` bytes for a message: exact with thousands separators, and in GiB or TiB when large."""
    if not math.isfinite(n):
        return "more bytes than float64 counts"
    text = f"{int(n):,} bytes"
    if n >= 1 << 40:
        text += f" ({n / (1 << 40):.3g} TiB)"
    elif n >= 1 << 30:
        text += f" ({n / (1 << 30):.3g} GiB)"
    return text


def format_value(value) -> str:
    """``value`` for a message, as Python writes it: NumPy scalars and arrays as plain numbers and lists
    (``-0.012``, not ``np.float64(-0.012)``)."""
    if isinstance(value, np.generic):
        value = value.item()
    elif isinstance(value, np.ndarray):
        value = value.tolist()
    return repr(value)


def resolve_device(device=None, *, name: str = "device"):
    """The Warp device ``device`` names (None: Warp's default), or one clear error naming ``name``.

    A CUDA name on a machine without a GPU that Warp can use is refused here, before Warp is asked for it (Warp
    itself prints two raw driver errors first); so is a CUDA ordinal past the GPUs present.

    Args:
        device: None, a ``warp.Device``, or a name such as ``"cpu"``, ``"cuda"``, ``"cuda:1"``.
        name: The argument to name in the error.

    Raises:
        ValueError: no such device on this machine, saying which exist.
        TypeError: neither a device nor a name.
    """
    import warp as wp

    if device is None:
        return wp.get_device(None)
    if isinstance(device, wp.Device):
        return device
    if not isinstance(device, str):
        raise TypeError(f"{name}: expected a Warp device or its name ('cpu', 'cuda:0'), got {type(device).__name__}")
    alias = device.strip()
    if alias.startswith("cuda"):
        count = wp.get_cuda_device_count()
        if count == 0:
            raise ValueError(
                f"{name}: {device!r} asks for a CUDA GPU, but this machine has none that Warp can use; use "
                "device='cpu' (or leave device=None)"
            )
        ordinal = alias[5:] if alias.startswith("cuda:") else None
        if alias != "cuda" and (ordinal is None or not ordinal.isdigit() or int(ordinal) >= count):
            present = ", ".join(["cpu", *(f"cuda:{k}" for k in range(count))])
            raise ValueError(f"{name}: no Warp device {device!r}; present: {present}")
    try:
        return wp.get_device(alias)
    except (ValueError, RuntimeError):
        present = ", ".join(d.alias for d in wp.get_devices())
        raise ValueError(f"{name}: no Warp device {device!r}; present: {present}") from None


def _diameter_and_spread(centers: np.ndarray, radii: np.ndarray) -> tuple[float, float]:
    """The mean diameter and the widest extent of the centres along an axis, the two lengths the unit hints
    compare."""
    return 2.0 * float(np.mean(radii)), float(np.max(np.ptp(centers, axis=0)))


def unit_mixup_hint(centers: np.ndarray, radii: np.ndarray) -> str:
    """A sentence for an error when the radii look tiny against the spread of the centres, the sign of centres and
    radii in different units (centres in millimetres, radii in metres); '' when they look consistent.

    N particles of mean diameter d packed densely span about N^(1/3) d; centres that spread a hundred times wider
    than that are far from any body of touching spheres (a DEM specimen, a packing, a granular flow).

    Args:
        centers: Particle centres, shape (N, 3), float64, finite.
        radii: Particle radii, shape (N,), float64, > 0.
    """
    if len(radii) < 2:
        return ""
    d, spread = _diameter_and_spread(centers, radii)
    dense = max(1.0, len(radii) ** (1.0 / 3.0)) * d
    if spread <= 100.0 * dense:
        return ""
    return (
        f"the centres spread over {spread:.4g} while the mean radius is {d / 2:.4g}, {spread / dense:,.0f} times "
        f"wider than {len(radii):,} touching spheres would span: are the centres and the radii in one unit (SI: "
        "metres)? Centres in millimetres with radii in metres look like this"
    )


def user_stacklevel() -> int:
    """The ``stacklevel`` for ``warnings.warn``, called from inside warp_lamp, that names the caller's first line
    outside the package: a warning raised again by an inner re-check of the same input then points at the same
    line, and Python shows it once."""
    import os
    import sys

    package = os.path.dirname(os.path.abspath(__file__))
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package + os.sep):
        frame, level = frame.f_back, level + 1
    return level


def host_array(value):
    """``value`` as something NumPy converts: a warp array (on any device) is copied to the host once, and a
    one-shot iterator (a generator, ``map``, ``iter(...)``) is read once into a list, so that it is not consumed by
    one check and then seen empty by the next."""
    import warp as wp

    if isinstance(value, wp.array):
        return value.numpy()
    if isinstance(value, Iterator):
        return list(value)
    return value


def array_device(*values):
    """The device of the first warp array among ``values``, or None when none is one."""
    import warp as wp

    for v in values:
        if isinstance(v, wp.array):
            return v.device
    return None


def check_device_match(device, **arrays):
    """The device a host-level call runs on: where its warp arrays live, unless ``device`` says otherwise.

    Args:
        device: The caller's ``device`` argument (None: where the arrays live, else Warp's default).
        **arrays: The call's array arguments by name; warp arrays among them must share one device.

    Raises:
        ValueError: warp arrays on two devices, or ``device`` naming another device than theirs.
    """
    import warp as wp

    found = None
    for name, value in arrays.items():
        if isinstance(value, wp.array):
            if found is None:
                found = (name, value.device)
            elif value.device != found[1]:
                raise ValueError(f"{name}: on {value.device}, but {found[0]} is on {found[1]}")
    if device is None:
        return found[1] if found else wp.get_device(None)
    dev = resolve_device(device)
    if found and dev != found[1]:
        raise ValueError(
            f"device: {dev} was asked for, but {found[0]} lives on {found[1]}; leave device=None to compute where "
            "the arrays live, or copy them first"
        )
    return dev


#: Lamp names in bit order: "-x" is the lamp at minus infinity on x, shining toward +x.
LAMPS = ("-x", "+x", "-y", "+y", "-z", "+z")


def lamp_names(lamps) -> tuple[str, ...]:
    """The lamps that are on, as a tuple of names from :data:`LAMPS`: ``"all"``, one name, or any iterable of names.

    The iterable is read once, here, so that a generator is not consumed by validation and then seen empty.
    """
    if isinstance(lamps, str):
        lamps = LAMPS if lamps == "all" else (lamps,)
    if not isinstance(lamps, Iterable):
        raise ValueError(f"lamps: expected 'all' or names from {LAMPS}, got {format_value(lamps)}")
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


def _as_float(name: str, value, what: str) -> np.ndarray:
    value = host_array(value)
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name}: expected {what}, got a string {value!r}")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: not convertible to a float array ({e})") from None
    return arr


def check_particles(centers, radii) -> tuple[np.ndarray, np.ndarray]:
    """Return float64 copies of ``centers`` (N, 3) and ``radii`` (N,), or raise ValueError naming the problem.

    Both may be NumPy arrays, nested sequences, or warp arrays on any device (``vec3``/``vec3d`` centres, float32
    or float64 radii), which are copied to the host once.
    """
    c = _as_float("centers", centers, "an (N, 3) array")
    r = _as_float("radii", radii, "an (N,) array or one number")
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
        raise ValueError(f"radii: must be finite and > 0; index {k} is {format_value(r[k])}")
    hint = radii_unit_hint(c, r)
    if hint:
        import warnings

        warnings.warn(hint, UserWarning, stacklevel=user_stacklevel())
    return c, r


def radii_unit_hint(centers: np.ndarray, radii: np.ndarray) -> str:
    """A sentence for a warning when the particles are ten times wider than the whole cloud of their centres, the
    sign of radii in other units than the centres (radii in millimetres, centres in metres): every sphere then
    swallows all the others. '' when they look consistent, or for fewer than 8 particles (a clump may overlap).

    Args:
        centers: Particle centres, shape (N, 3), float64, finite.
        radii: Particle radii, shape (N,), float64, > 0.
    """
    if len(radii) < 8:
        return ""
    d, spread = _diameter_and_spread(centers, radii)
    if d <= 10.0 * spread:
        return ""
    return (
        f"radii: the mean diameter {d:.4g} is {d / max(spread, 1e-300):,.0f} times the spread of the centres "
        f"({spread:.4g}), so every sphere covers all the others: are the radii and the centres in one unit (SI: "
        "metres)? Radii in millimetres with centres in metres look like this"
    )


def check_positions(name: str, positions, n: int) -> np.ndarray:
    """Finite float64 positions of shape (n, 3) (NumPy, sequences, or a warp ``vec3`` array on any device)."""
    x = _as_float(name, positions, f"an ({n}, 3) array")
    if x.shape != (n, 3):
        raise ValueError(f"{name}: expected shape ({n}, 3), one row per particle of the last update, got {x.shape}")
    if n and not np.isfinite(x).all():
        k = _first_bad(~np.isfinite(x))
        raise ValueError(f"{name}: non-finite value at index {k}: {x[k].tolist()}")
    return x


def check_mask(name: str, mask, n: int) -> np.ndarray:
    """A particle mask of shape (n,), as int32 0/1: booleans or numbers (nonzero is on), never strings."""
    m = np.asarray(host_array(mask))
    if m.dtype.kind not in "biuf":
        raise TypeError(f"{name}: expected booleans or numbers, shape ({n},), got dtype {m.dtype}")
    if m.shape != (n,):
        raise ValueError(f"{name}: expected shape ({n},), got {m.shape}")
    if m.dtype.kind == "f" and n and not np.isfinite(m).all():
        k = int(np.flatnonzero(~np.isfinite(m))[0])
        raise ValueError(f"{name}: non-finite value at index {k}: {format_value(m[k])}")
    return (m != 0).astype(np.int32)


def check_positive(name: str, value, *, allow_zero: bool = False) -> float:
    """One finite real number > 0 (>= 0 with ``allow_zero``); strings, None and booleans are refused by type."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__} {format_value(value)}")
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        need = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name}: must be finite and {need}, got {format_value(value)}")
    return v


def check_integer(name: str, value, *, minimum: int = 0) -> int:
    """One integer >= ``minimum`` (Python or NumPy integers; not booleans, floats or strings)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name}: expected an integer >= {minimum}, got {type(value).__name__} {format_value(value)}")
    if value < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {format_value(value)}")
    return int(value)


def check_pressure(pressure) -> np.ndarray:
    """Pressure as float64 (Px, Py, Pz) [Pa]: one number for all axes, or one per axis."""
    pressure = host_array(pressure)
    p = np.asarray(pressure, dtype=object)
    if p.shape == (1,):
        pressure = p[0]
    return check_vec3("pressure", pressure)


def check_vec3(name: str, value, *, positive: bool = False) -> np.ndarray:
    """Three finite float64 values (a scalar is repeated), > 0 where ``positive``."""
    value = host_array(value)
    if isinstance(value, (str, bytes)) or value is None:
        raise TypeError(f"{name}: expected a number or 3 numbers, got {value!r}")
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
        raise ValueError(f"{name}: must be {need}; index {k} is {format_value(arr[k])}")
    return arr


def check_box(lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """A box's corners as float64 (3,) arrays, ``upper`` above ``lower`` on every axis."""
    lo = check_vec3("lower", lower)
    hi = check_vec3("upper", upper)
    if np.any(hi <= lo):
        k = int(np.flatnonzero(hi <= lo)[0])
        raise ValueError(
            f"upper: must exceed lower on every axis; axis {k} has {format_value(hi[k])} <= {format_value(lo[k])}"
        )
    return lo, hi


def check_shape(shape) -> tuple[int, int, int]:
    """Three integers >= 1 (cells along x, y, z)."""
    value = host_array(shape)
    # np.asarray((True, 4, 4)) is an integer array: a bool among the entries is caught before it is promoted.
    flagged = isinstance(value, (bool, np.bool_)) or (
        isinstance(value, (tuple, list)) and any(isinstance(x, (bool, np.bool_)) for x in value)
    )
    sh = np.asarray(value).reshape(-1)
    if flagged or sh.shape != (3,) or not np.issubdtype(sh.dtype, np.integer):
        raise ValueError(f"shape: expected 3 integers (nx, ny, nz), got {format_value(shape)}")
    if np.any(sh < 1):
        k = int(np.flatnonzero(sh < 1)[0])
        raise ValueError(f"shape: every entry must be >= 1; index {k} is {int(sh[k])}")
    return tuple(int(x) for x in sh)


def check_subdivisions(subdivisions) -> tuple[int, int, int]:
    """Sub-cells per cell edge: an integer >= 1 for every axis, or three (along x, y, z)."""
    value = host_array(subdivisions)
    if isinstance(value, (tuple, list, np.ndarray)):
        items = list(np.asarray(value, dtype=object).reshape(-1))
        if len(items) == 3 and all(
            not isinstance(x, bool) and isinstance(x, (int, np.integer)) and x >= 1 for x in items
        ):
            return tuple(int(x) for x in items)
    elif not isinstance(value, bool) and isinstance(value, (int, np.integer)) and value >= 1:
        return (int(value),) * 3
    raise ValueError(f"subdivisions: expected an integer >= 1, or three (x, y, z), got {format_value(subdivisions)}")


def check_max_bytes(max_bytes) -> float:
    """A memory budget [bytes]: a number >= 0 (``math.inf`` for none). NaN, negatives and non-numbers raise."""
    if isinstance(max_bytes, bool) or not isinstance(max_bytes, numbers.Real):
        raise TypeError(
            f"max_bytes: expected a number of bytes, got {type(max_bytes).__name__} {format_value(max_bytes)}"
        )
    if math.isnan(max_bytes) or max_bytes < 0:
        raise ValueError(
            f"max_bytes: expected a number of bytes >= 0 (math.inf for no budget), got {format_value(max_bytes)}"
        )
    return max_bytes


def check_budget(need: float, max_bytes, what: str, remedy: str) -> None:
    """Raise ValueError, before anything is allocated, when ``need`` bytes exceed ``max_bytes``.

    Args:
        need: Bytes the call would allocate (a float: inf when the count itself overflows).
        max_bytes: The caller's budget [bytes], validated here.
        what: The start of the message: the argument to blame and what needs ``need`` bytes.
        remedy: How to need fewer.
    """
    max_bytes = check_max_bytes(max_bytes)
    if not (need <= max_bytes):
        raise ValueError(
            f"{what}, over the budget of max_bytes = {format_bytes(max_bytes)} (raise max_bytes, or {remedy})"
        )


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
        raise ValueError(f"{name}: must be finite; flat index {k} is {format_value(r.ravel()[k])}")
    if r.shape == (4,):
        norm = float(np.linalg.norm(r))
        if abs(norm - 1.0) > 1e-6:
            raise ValueError(f"{name}: a quaternion (x, y, z, w) must have unit norm, got {format_value(norm)}")
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


def check_grid_cells(name: str, counts, max_bytes, bytes_per_cell: int) -> np.ndarray:
    """Lamp-grid cell counts (3, 2), checked in float64 before any integer conversion: the budget, and at most
    :data:`EXACT_CELLS` cells per grid so that the forces sum exactly.

    Args:
        name: The argument that set the counts (``cell_size``, ``cells_per_diameter``, ``counts``).
        counts: Cells of each grid along (u, v), shape (3, 2), as floats (may be huge or inf).
        max_bytes: Budget for the per-cell arrays [bytes].
        bytes_per_cell: Device bytes per cell.

    Returns:
        The counts as int64, shape (3, 2).
    """
    c = np.asarray(counts, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        per_grid = c[:, 0] * c[:, 1]
        cells = float(np.sum(per_grid))
        need = cells * bytes_per_cell
    if math.isfinite(need):
        what = f"{name}: the grid's {int(cells):,} cells need {format_bytes(need)}"
    else:
        what = f"{name}: the grid's cell count overflows float64"
    check_budget(need, max_bytes, what, "use larger cells")
    if np.any(per_grid > EXACT_CELLS):
        a = int(np.flatnonzero(per_grid > EXACT_CELLS)[0])
        raise ValueError(
            f"{name}: grid {a} has {int(per_grid[a]):,} cells, over the 2**27 that keep every sum of P A count exact "
            "in float64; use larger cells"
        )
    return c.astype(np.int64)


def check_force_range(pressure, cell_area, cells_per_grid, *, float32: bool = False) -> None:
    """Refuse a force per cell ``P_a A_a`` [N] that leaves the range where the forces are exact.

    Args:
        pressure: P_a per axis [Pa], shape (3,), finite.
        cell_area: A_a, the cell area of each grid [m^2], shape (3,).
        cells_per_grid: Cells of each grid, shape (3,): the largest count a particle can have on that axis.
        float32: The forces go to a float32 array, whose range must hold P_a A_a times the largest count.
    """
    p = np.asarray(pressure, dtype=np.float64)
    area = np.asarray(cell_area, dtype=np.float64)
    with np.errstate(over="ignore"):
        pa = np.abs(p * area)
    for a in range(3):
        if p[a] != 0.0 and area[a] == 0.0:
            raise ValueError(f"pressure: the cell area of grid {a} underflows to 0 m^2, so P A would vanish")
        if not np.isfinite(pa[a]) or pa[a] > _MAX_PRESSURE_AREA:
            raise ValueError(
                f"pressure: P times the cell area of grid {a} is {pa[a]:.3g} N, over the {_MAX_PRESSURE_AREA:.3g} N "
                "that keeps the 26-bit rounding and every P A count exact in float64 (check the units)"
            )
        if 0.0 < pa[a] < _MIN_PRESSURE_AREA:
            raise ValueError(
                f"pressure: P times the cell area of grid {a} is {pa[a]:.3g} N, below the smallest normal float64, "
                "where the 26-bit rounding is not exact (check the units)"
            )
        if float32 and pa[a] * float(cells_per_grid[a]) > _FLOAT32_MAX:
            raise ValueError(
                f"pressure: P A up to {pa[a] * float(cells_per_grid[a]):.3g} N on axis {a} overflows the float32 "
                "force array (check the units)"
            )


def check_warp_array(name: str, arr, dtype, device, owner: str, n: int | None = None) -> None:
    """Refuse, naming ``name``, what a capture-safe device path cannot take: not a warp array, another dtype,
    not 1-D or contiguous, on another device than ``owner``'s, or shorter than ``n``.

    Args:
        name: The argument.
        arr: The array.
        dtype: The warp dtype it must have.
        device: The device it must live on.
        owner: Who needs it, for the message ("the lamp").
        n: Fewest entries, or None.
    """
    import warp as wp

    if not isinstance(arr, wp.array):
        raise TypeError(f"{name}: expected a warp array of {dtype.__name__}, got {type(arr).__name__}")
    if arr.dtype != dtype:
        raise TypeError(f"{name}: expected dtype {dtype.__name__}, got {getattr(arr.dtype, '__name__', arr.dtype)}")
    if arr.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D array, got shape {arr.shape}")
    if arr.device != device:
        raise ValueError(f"{name}: on device {arr.device}, {owner} is on {device}")
    if n is not None and arr.shape[0] < n:
        raise ValueError(f"{name}: has {arr.shape[0]} entries, need {n}")
    if not arr.is_contiguous:
        raise ValueError(f"{name}: must be contiguous")


def check_particle_arrays(positions, radii, active, device, owner: str) -> int:
    """The device arrays of an update (:func:`check_warp_array` each): positions ``vec3``, radii ``float32`` and an
    optional ``int32`` mask, as many as the positions, on ``owner``'s device. Returns N."""
    import warp as wp

    check_warp_array("positions", positions, wp.vec3, device, owner)
    n = positions.shape[0]
    check_warp_array("radii", radii, wp.float32, device, owner, n)
    if active is not None:
        check_warp_array("active", active, wp.int32, device, owner, n)
    return n


#: Most walls a lamp takes (``kernels/walls.py``).
MAX_WALLS = 8

#: A body rests on a wall (which then seals every ray that meets the body: the fluid does not get under it) when
#: the gap between the wall and its nearest particle lies within this fraction of that particle's radius, on either
#: side: a contact or a DEM overlap, not a lifted body (fluid in the gap) or a cut one (a fluid level).
WALL_REST = 0.1


def check_walls(walls) -> np.ndarray:
    """Walls that bound the fluid as planes, shape (W, 4) float64: unit normal (pointing from the wall into the
    fluid) and offset d, the fluid being ``n . x > d``.

    Args:
        walls: None or an empty sequence (no walls), or a sequence of ``(point, normal)`` pairs in world
            coordinates [m], each a 3-vector; the normal need not be unit length.

    Raises:
        ValueError: naming ``walls`` and the wall's index: not pairs of 3-vectors, non-finite, a zero normal, or
            more than :data:`MAX_WALLS`.
    """
    if walls is None:
        return np.zeros((0, 4))
    walls = host_array(walls)
    if isinstance(walls, (str, bytes)) or not isinstance(walls, Iterable):
        raise ValueError(f"walls: expected a sequence of (point, normal) pairs, got {walls!r}")
    planes = []
    for k, wall in enumerate(walls):
        try:
            pair = np.asarray(wall, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"walls: wall {k} is not a (point, normal) pair of 3-vectors: {wall!r}") from None
        if pair.shape != (2, 3):
            raise ValueError(f"walls: wall {k} must be a (point, normal) pair of 3-vectors, got shape {pair.shape}")
        if not np.isfinite(pair).all():
            raise ValueError(f"walls: wall {k} has a non-finite value: {pair.tolist()}")
        point, normal = pair
        # Scaled by its largest component first, so that neither 1e200 nor 1e-200 over- or underflows the norm.
        big = float(np.abs(normal).max())
        if not big > 0.0:
            raise ValueError(f"walls: wall {k} has a zero normal")
        n = normal / big
        n = n / np.linalg.norm(n)
        planes.append([*n, float(n @ point)])
    if len(planes) > MAX_WALLS:
        raise ValueError(f"walls: at most {MAX_WALLS} walls, got {len(planes)}")
    return np.array(planes, dtype=np.float64).reshape(-1, 4)


def walls_behind_message(centers, radii, planes: np.ndarray) -> str:
    """'' unless every particle lies wholly behind some wall (n . c - d + r <= 0), where no fluid can reach the
    body: a warning that names the walls (most likely a normal pointing out of the fluid).

    Args:
        centers: Particle centres [m], shape (N, 3), host, in the planes' coordinates.
        radii: Particle radii [m], shape (N,) or a scalar.
        planes: Walls as :func:`check_walls` gives them, shape (W, 4).
    """
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    if not len(planes) or not len(c):
        return ""
    r = np.broadcast_to(np.asarray(radii, dtype=np.float64), (len(c),))
    g = c @ planes[:, :3].T - planes[:, 3] + r[:, None]
    behind = g <= 0.0
    if not behind.any(axis=1).all():
        return ""
    names = np.flatnonzero(behind.any(axis=0)).tolist()
    return (
        f"walls: every particle lies behind wall(s) {names}, where the fluid does not reach, so every force is 0; "
        "a wall's normal points from the wall into the fluid"
    )
