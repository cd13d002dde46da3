"""VTK files for ParaView: per-particle fields and porosity grids, through the optional ``pyevtk`` writer.

``pip install "warp-lamp[vtk]"`` (or ``pip install ".[vtk]"`` in a clone) installs it; it is imported only when a
function here is called. Files are VTK XML (``.vtu`` for particles, ``.vti`` for grids), which ParaView opens
directly: show the particles with the Point Gaussian representation (radius array ``radius``), and colour by any
field.
"""

from __future__ import annotations

import numpy as np

from warp_lamp.validate import check_box, check_particles, host_array

__all__ = ["write_vtk_particles", "write_vtk_porosity"]

_INSTALL = "pip install 'warp-lamp[vtk]' (or pip install '.[vtk]' in a clone of warp_lamp)"


def _hl():
    try:
        from pyevtk import hl
    except ImportError as e:
        raise ImportError(f"the VTK export needs pyevtk, which is not installed: {_INSTALL}") from e
    return hl


def _strip(path) -> str:
    """pyevtk appends the extension itself."""
    path = str(path)
    for ext in (".vtu", ".vti"):
        if path.endswith(ext):
            return path[: -len(ext)]
    return path


def _field_data(field_data) -> dict | None:
    """Whole-file values (the inputs of a run: pressure, criterion, ...) as the 1-D float64 arrays VTK field data
    holds; None when there are none."""
    if not field_data:
        return None
    out = {}
    for name, value in field_data.items():
        arr = np.atleast_1d(np.asarray(host_array(value), dtype=np.float64)).ravel()
        out[name] = np.ascontiguousarray(arr)
    return out


def write_vtk_particles(path, centers, radii, *, field_data: dict | None = None, **fields) -> str:
    """Write particles as VTK points with their radius and any per-particle fields.

    Args:
        path: File name, with or without ``.vtu``.
        centers: Particle centres [m], shape (N, 3) (NumPy, or a warp array on any device).
        radii: Particle radii [m], shape (N,), or one number.
        field_data: Values for the whole file, by name (numbers or short arrays: the run's pressure [Pa], cells per
            diameter, ...), written as VTK field data.
        **fields: Per-particle arrays by name: shape (N,) (scalars; booleans and integers written as integers,
            Int32 and Int64) or (N, 3) (vectors, e.g. ``force=`` from :func:`warp_lamp.lamp_forces` [N]).

    Returns:
        The path written, with its extension.
    """
    c, r = check_particles(centers, radii)
    n = c.shape[0]
    data = {"radius": np.ascontiguousarray(r)}
    for name, value in fields.items():
        arr = np.asarray(host_array(value))
        if arr.dtype.kind == "b":
            arr = arr.astype(np.int32)
        elif arr.dtype.kind in "iu":
            arr = arr.astype(np.int32 if arr.size == 0 or np.abs(arr).max() < 2**31 else np.int64)
        elif arr.dtype.kind == "f":
            arr = arr.astype(np.float64)
        if arr.shape == (n,):
            data[name] = np.ascontiguousarray(arr)
        elif arr.shape == (n, 3):
            data[name] = tuple(np.ascontiguousarray(arr[:, k]) for k in range(3))
        else:
            raise ValueError(f"{name}: expected shape ({n},) or ({n}, 3), got {arr.shape}")
    x, y, z = (np.ascontiguousarray(c[:, k]) for k in range(3))
    return _hl().pointsToVTK(_strip(path), x, y, z, data=data, fieldData=_field_data(field_data))


def write_vtk_porosity(path, porosity, lower, upper, *, field_data: dict | None = None, **fields) -> str:
    """Write a porosity grid (or any per-cell fields) as VTK image data: one cell per CFD cell.

    Args:
        path: File name, with or without ``.vti``.
        porosity: Per-cell porosity, shape (nx, ny, nz), as :func:`warp_lamp.porosity` returns it.
        lower: Lower corner of the box [m], 3 values.
        upper: Upper corner of the box [m], 3 values.
        field_data: Values for the whole file, by name (numbers or short arrays), as VTK field data.
        **fields: More per-cell arrays of the same shape, by name.

    Returns:
        The path written, with its extension.
    """
    eps = np.asarray(host_array(porosity), dtype=np.float64)
    if eps.ndim != 3:
        raise ValueError(f"porosity: expected shape (nx, ny, nz), got {eps.shape}")
    lo, hi = check_box(lower, upper)
    cells = {"porosity": np.asfortranarray(eps)}
    for name, value in fields.items():
        arr = np.asarray(host_array(value), dtype=np.float64)
        if arr.shape != eps.shape:
            raise ValueError(f"{name}: expected shape {eps.shape} like porosity, got {arr.shape}")
        cells[name] = np.asfortranarray(arr)
    spacing = tuple(float(x) for x in (hi - lo) / np.asarray(eps.shape))
    return _hl().imageToVTK(
        _strip(path),
        origin=tuple(float(x) for x in lo),
        spacing=spacing,
        cellData=cells,
        fieldData=_field_data(field_data),
    )
