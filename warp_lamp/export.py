"""Files for ParaView and for engines: per-particle fields and porosity grids as VTK (through the optional ``pyevtk``
writer), and per-particle forces as CSV or a LAMMPS per-atom dump an engine reads back (:func:`write_forces`, NumPy
only).

``pip install "warp-lamp[vtk]"`` (or ``pip install ".[vtk]"`` in a clone) installs it; it is imported only when a
function here is called. Files are VTK XML (``.vtu`` for particles, ``.vti`` for grids), which ParaView opens
directly: show the particles with the Point Gaussian representation (radius array ``radius``), and colour by any
field.
"""

from __future__ import annotations

import numpy as np

from warp_lamp.validate import check_box, check_particles, host_array

__all__ = ["FORCE_FORMATS", "write_forces", "write_vtk_particles", "write_vtk_porosity"]

#: Formats :func:`write_forces` writes.
FORCE_FORMATS = ("csv", "lammps")

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


def write_forces(
    path,
    forces,
    *,
    ids=None,
    fmt: str | None = None,
    unit: str = "N",
    timestep: int = 0,
    box=None,
) -> str:
    """Per-particle forces in a file an engine reads back, one row per particle in the order given.

    Ids are the file's own where it had them; otherwise the particle's position in it counted from 1 (LAMMPS
    atom ids and PFC ball ids start at 1; YADE's body ids start at 0: subtract 1 there).

    - ``csv``: a header ``id,fx [unit],fy [unit],fz [unit]`` then ``id,fx,fy,fz`` rows (``%.17g``).
    - ``lammps``: one timestep of a LAMMPS dump: ``ITEM: UNITS si`` (where ``unit`` is N), ``ITEM: TIMESTEP``,
      ``ITEM: NUMBER OF ATOMS``, ``ITEM: BOX BOUNDS ff ff ff`` (``box``), ``ITEM: ATOMS id fx fy fz``; LAMMPS reads
      it with ``read_dump FILE TIMESTEP fx fy fz box no`` (or any reader of dumps).

    The file is written to a temporary name beside ``path`` and renamed, so that a reader never sees half of it.

    Args:
        path: The file.
        forces: Forces, shape (N, 3), in ``unit``.
        ids: Ids, shape (N,), integers; default 1 .. N.
        fmt: ``csv`` or ``lammps``; default from the extension (``.dump``, ``.lammpstrj``: lammps; else csv).
        unit: The forces' unit in words (``N``, or ``Pa*mm^2`` for lengths in millimetres), written in the header.
        timestep: The LAMMPS timestep written (the dump's that was read, say).
        box: ``(lower, upper)``, each shape (3,), for the LAMMPS box bounds (the particles' bounding box, say);
            default zeros (``read_dump ... box no`` ignores it).

    Returns:
        The path written.
    """
    import os
    import tempfile

    f = np.asarray(host_array(forces), dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"forces: expected shape (N, 3), got {f.shape}")
    if ids is None:
        ids = np.arange(1, len(f) + 1, dtype=np.int64)
    ids = np.asarray(ids)
    if ids.shape != (len(f),) or ids.dtype.kind not in "iu":
        raise ValueError(f"ids: expected {len(f)} integers, got {ids.dtype} {ids.shape}")
    if fmt is None:
        fmt = "lammps" if str(path).lower().endswith((".dump", ".lammpstrj")) else "csv"
    if fmt not in FORCE_FORMATS:
        raise ValueError(f"fmt: expected one of {FORCE_FORMATS}, got {fmt!r}")
    if isinstance(timestep, bool) or not isinstance(timestep, (int, np.integer)) or timestep < 0:
        raise ValueError(f"timestep: expected an integer >= 0, got {timestep!r}")
    sep = "," if fmt == "csv" else " "
    rows = "".join(
        f"{int(i)}{sep}{a:.17g}{sep}{b:.17g}{sep}{c:.17g}\n" for i, (a, b, c) in zip(ids, f.tolist(), strict=True)
    )
    if fmt == "csv":
        text = f"id,fx [{unit}],fy [{unit}],fz [{unit}]\n" + rows
    else:
        lo, hi = (np.zeros(3), np.zeros(3)) if box is None else (np.asarray(box[0]), np.asarray(box[1]))
        units = "ITEM: UNITS\nsi\n" if unit == "N" else ""
        bounds = "".join(f"{a:.17g} {b:.17g}\n" for a, b in zip(lo.tolist(), hi.tolist(), strict=True))
        text = (
            f"{units}ITEM: TIMESTEP\n{int(timestep)}\nITEM: NUMBER OF ATOMS\n{len(f)}\n"
            f"ITEM: BOX BOUNDS ff ff ff\n{bounds}ITEM: ATOMS id fx fy fz\n" + rows
        )
    folder = os.path.dirname(os.path.abspath(str(path)))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".warp_lamp_forces_")
    try:
        with os.fdopen(fd, "w") as out:
            out.write(text)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 would make the file private
        os.replace(tmp, str(path))
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    return str(path)
