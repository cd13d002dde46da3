"""Read a user's particles from the files DEM codes write: CSV, NumPy, VTK points, LAMMPS/LIGGGHTS dumps, YADE.

:func:`read_particles` returns centres, radii, ids (where the file has them) and a :class:`ParticlesInfo` saying
what was read: the format, the count, the bounds, the radii, and a guess at the length unit. A file that cannot
be read raises :class:`ParticleFileError`, one line naming the file, the line and the column.

Formats (by extension, else by content):

- **CSV** (``.csv``, ``.tsv``, ``.txt`` with a header): a header row naming x, y, z and radius (or diameter), an
  optional id; any of ``, ; tab`` or spaces between fields. Names are read liberally: case, spaces, ``_`` and a unit
  in brackets are ignored (``X [mm]``, ``pos_x``, ``Points:0`` as ParaView writes it, ``r``, ``rad``, ``d``), and a
  unit in the header (``[mm]``, ``(cm)``, ``[um]``) is converted to metres.
- **NumPy** ``.npy``: an (N, 4) array of x, y, z, radius. ``.npz``: named arrays, centres as one (N, 3) array
  (``centers``, ``centres``, ``positions``, ``pos``, ``x``) or three (``x``, ``y``, ``z``), radii as ``radii``,
  ``radius``, ``r`` (or ``diameter``, ``d``), ids as ``ids`` or ``id``.
- **VTK XML points** (``.vtu``, ``.vtp``): the points and a point array named radius (``radius``, ``radii``,
  ``rad``, ``r``) or diameter; ASCII, base64 binary inline or appended, raw appended, UInt32 or UInt64 headers,
  zlib-compressed or not, either byte order: what pyevtk, ParaView and YADE's ``VTKRecorder`` write.
- **LAMMPS / LIGGGHTS dump** (``.dump``, ``.lammpstrj``, ``.liggghts``, or a file starting ``ITEM:``): ``ITEM:
  ATOMS`` with ``x y z`` (or ``xu yu zu``, or scaled ``xs ys zs`` / ``xsu ysu zsu`` with the box, triclinic
  included) and ``radius`` or ``diameter``; of several timesteps the last, or the one asked for. An ``ITEM: UNITS``
  of si, cgs, micro, nano, real or metal is converted to metres.
- **YADE text** (``yade.export.text`` / ``textExt``): a ``#format x_y_z_r`` line (``x_y_z_r_matId``,
  ``id_x_y_z_r_matId``, ``x_y_z_r_attrs``), ``#`` comments, then x y z r per line; without a ``#format`` line, the
  first four columns are x y z r.
"""

from __future__ import annotations

import base64
import csv
import os
import re
import zlib
from dataclasses import dataclass, field
from xml.parsers import expat

import numpy as np

from warp_lamp.validate import radii_unit_hint

__all__ = ["FORMATS", "ParticleFileError", "ParticlesInfo", "guess_units", "read_particles"]

#: Formats :func:`read_particles` reads, by the name ``fmt`` takes.
FORMATS = ("csv", "npy", "npz", "vtk", "lammps", "yade")

_EXTENSIONS = {
    ".csv": "csv",
    ".tsv": "csv",
    ".npy": "npy",
    ".npz": "npz",
    ".vtu": "vtk",
    ".vtp": "vtk",
    ".vtk": "vtk-legacy",
    ".dump": "lammps",
    ".lammpstrj": "lammps",
    ".liggghts": "lammps",
}

#: Length units a header may name, in metres.
_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "\u00b5m": 1e-6, "\u03bcm": 1e-6, "micron": 1e-6, "nm": 1e-9}
_LAMMPS_UNITS = {"si": (1.0, "metres"), "cgs": (1e-2, "centimetres"), "micro": (1e-6, "micrometres")}
_LAMMPS_UNITS.update({"nano": (1e-9, "nanometres"), "real": (1e-10, "angstroms"), "metal": (1e-10, "angstroms")})
_UNIT_NAMES = {1.0: "metres", 1e-2: "centimetres", 1e-3: "millimetres", 1e-6: "micrometres", 1e-9: "nanometres"}


class ParticleFileError(ValueError):
    """A particle file that cannot be read: one line naming the file, and the line and column where known."""

    def __init__(self, path, message: str, *, line: int | None = None, column: int | None = None):
        self.path, self.line, self.column = str(path), line, column
        where = str(path)
        if line is not None:
            where += f", line {line}"
        if column is not None:
            where += f", column {column}"
        super().__init__(f"{where}: {message}")


@dataclass
class ParticlesInfo:
    """What :func:`read_particles` read.

    Attributes:
        path: The file.
        format: One of :data:`FORMATS`.
        count: Particles read.
        lower: Lowest centre on each axis, shape (3,), in the units returned.
        upper: Highest centre on each axis, shape (3,).
        radius_min: Smallest radius.
        radius_mean: Mean radius.
        radius_max: Largest radius.
        scale: Factor applied to the file's lengths (1 unless the file named its unit, or the caller scaled).
        length_unit: ``"m"`` where the lengths returned are known to be metres (the file named its unit, or the
            caller passed ``scale``); None where the file does not say (they are then in the file's own unit).
        units: A guess at the length unit of what is returned, in words (see :func:`guess_units`).
        columns: The columns or arrays read, in words.
        timestep: The LAMMPS timestep read, or None.
        notes: Anything else worth saying (other timesteps, columns ignored).
    """

    path: str
    format: str
    count: int
    lower: np.ndarray
    upper: np.ndarray
    radius_min: float
    radius_mean: float
    radius_max: float
    scale: float = 1.0
    length_unit: str | None = None
    units: str = ""
    columns: str = ""
    timestep: int | None = None
    notes: list = field(default_factory=list)

    def summary(self) -> str:
        """A few lines for a person: count, format, columns, bounds, radii and the units guess."""
        lo = ", ".join(f"{x:.4g}" for x in self.lower)
        hi = ", ".join(f"{x:.4g}" for x in self.upper)
        unit = " m" if self.length_unit == "m" else " (the file's length unit)"
        step = "" if self.timestep is None else f", timestep {self.timestep}"
        lines = [
            f"read {self.count:,} particles from {self.path} ({self.format}{step}; {self.columns})",
            f"centres from ({lo}) to ({hi}); radii {self.radius_min:.4g} .. {self.radius_max:.4g}, "
            f"mean {self.radius_mean:.4g}{unit}",
        ]
        return "\n".join([*lines, *self.notes, f"units: {self.units}"])


def guess_units(radii: np.ndarray) -> str:
    """A guess at the length unit from the median radius, in words, for a person to confirm.

    DEM particles run from about 10 micrometres (powders) to about 0.5 m (rock fill): a median radius in
    [1e-5, 0.05) reads as metres, [0.05, 100) as millimetres or a model without units, anything else as a unit
    mix-up to check.
    """
    if len(radii) == 0:
        return "no particles, no guess"
    r = float(np.median(radii))
    if r < 1e-5:
        return f"radii look tiny (median {r:.3g}): metres for particles under 10 micrometres? check the unit"
    if r < 0.05:
        return f"radii look like metres (median {r:.3g} m = {r * 1e3:.3g} mm)"
    if r < 100.0:
        return (
            f"radii look like millimetres, or a model without units (median {r:.3g}); warp_lamp works in any "
            "consistent units, SI by default: scale by 0.001 for millimetres"
        )
    return f"radii look large (median {r:.3g}): micrometres? check the unit"


# --- the shared text path: fast parse, and an exact line and column on failure ------------------------------


def _table(path, rows: list[tuple[int, str]], ncols: int, split, what: str) -> np.ndarray:
    """Floats of ``rows`` (line number, text), ``ncols`` each, split by ``split``; on any bad row, the error
    names its line and the column (1-based, counting fields) of the first bad field."""
    if not rows:
        return np.zeros((0, ncols))
    try:
        flat = np.array([f for _, text in rows for f in split(text)], dtype=np.float64)
        if flat.size == len(rows) * ncols:
            return flat.reshape(len(rows), ncols)
    except ValueError:
        pass
    for line, text in rows:
        fields = split(text)
        if len(fields) != ncols:
            raise ParticleFileError(
                path, f"expected {ncols} fields ({what}), found {len(fields)}", line=line, column=len(fields) + 1
            )
        for k, f in enumerate(fields):
            try:
                float(f)
            except ValueError:
                raise ParticleFileError(path, f"not a number: {f.strip()!r}", line=line, column=k + 1) from None
    raise ParticleFileError(path, "could not read the table")  # not reached: some row above failed


def _ids(path, values, lines=None, column=None, what="id") -> np.ndarray:
    """Ids as int64: every one a finite whole number (1.7 is refused, not read as 1), naming the line (or index)
    of the first that is not."""
    v = np.asarray(values, dtype=np.float64)
    bad = ~np.isfinite(v) | (v != np.round(v)) | (np.abs(v) > 2.0**53)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        where = {} if lines is None else {"line": int(lines[k]), "column": column}
        extra = "" if lines is not None else f" (particle {k})"
        raise ParticleFileError(path, f"{what} {float(v[k])!r} is not a whole number{extra}", **where)
    return v.astype(np.int64)


def _check_unique(path, ids) -> None:
    """Each id once: a repeated id would make forces written back by id ambiguous."""
    if ids is None or len(ids) < 2:
        return
    order = np.argsort(ids, kind="stable")
    same = np.flatnonzero(ids[order][1:] == ids[order][:-1])
    if same.size:
        first, second = sorted((int(order[same[0]]), int(order[same[0] + 1])))
        raise ParticleFileError(
            path,
            f"id {int(ids[second])} is repeated: particles {first} and {second} (from 0) have it; ids must be unique",
        )


def _check_values(path, centers, radii, lines=None, cols=None, ids=None):
    """Finite centres and radii > 0, naming the line (and column) of the first bad one."""
    bad_c = ~np.isfinite(centers).all(axis=1)
    bad_r = ~(np.isfinite(radii) & (radii > 0))
    for bad, what, col in ((bad_c, "a centre coordinate is not finite", None), (bad_r, "radius", "r")):
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            line = None if lines is None else int(lines[k])
            column = None
            if cols is not None:
                column = cols["r"] if col == "r" else cols["xyz"][int(np.flatnonzero(~np.isfinite(centers[k]))[0])]
            text = what if col is None else f"radius must be finite and > 0, got {float(radii[k])!r}"
            where = "" if line is not None else f" (particle {k}{'' if ids is None else f', id {int(ids[k])}'})"
            raise ParticleFileError(path, text + where, line=line, column=column)


# --- CSV ------------------------------------------------------------------------------------------------------

_NAME_X = {"x", "posx", "positionx", "px", "cx", "centerx", "centrex", "coordx", "xcoord", "points0", "point0"}
_NAME_Y = {n.replace("x", "y").replace("0", "1") for n in _NAME_X} | {"y"}
_NAME_Z = {n.replace("x", "z").replace("0", "2") for n in _NAME_X} | {"z"}
_NAME_R = {"r", "radius", "radii", "rad", "particleradius", "sphereradius"}
_NAME_D = {"d", "diameter", "diam", "dia", "particlediameter", "spherediameter"}
_NAME_ID = {"id", "ids", "particleid", "pid", "index", "atomid", "bodyid"}


def _header_name(text: str) -> tuple[str, float | None]:
    """A header field as a bare lower-case name and the unit (in metres) it names in brackets, if any."""
    unit = None
    m = re.search(r"[\[(]\s*([^\])]+?)\s*[\])]", text)
    if m and m.group(1).strip().lower() in _UNITS:
        unit = _UNITS[m.group(1).strip().lower()]
    bare = re.sub(r"[\[(][^\])]*[\])]", "", text).strip().lower()
    return re.sub(r"[^a-z0-9]", "", bare), unit


def _split_csv(delimiter):
    if delimiter is None:
        return str.split
    return lambda text: next(csv.reader([text], delimiter=delimiter))


def _read_csv(path, text: str):
    lines = [(k + 1, t) for k, t in enumerate(text.splitlines()) if t.strip() and not t.lstrip().startswith("#")]
    if not lines:
        raise ParticleFileError(path, "no header and no data: the file is empty")
    head_line, head = lines[0]
    counts = {d: head.count(d) for d in (",", ";", "\t")}
    delimiter = max(counts, key=counts.get) if max(counts.values()) else None
    split = _split_csv(delimiter)
    names = [_header_name(f) for f in split(head)]
    found, units = {}, {}
    for k, (name, unit) in enumerate(names):
        for key, pool in (("x", _NAME_X), ("y", _NAME_Y), ("z", _NAME_Z), ("r", _NAME_R), ("d", _NAME_D)):
            if name in pool and key not in found:
                found[key], units[key] = k, unit
        if name in _NAME_ID and "id" not in found:
            found["id"] = k
    if all(_is_number(f) for f in split(head)):
        raise ParticleFileError(
            path,
            "the first line holds numbers, not a header: add a header (x, y, z, radius) or, for YADE's text "
            "export, a '#format x_y_z_r' line",
            line=head_line,
        )
    for key in ("x", "y", "z"):
        if key not in found:
            raise ParticleFileError(
                path, f"the header names no {key} column (found {[f.strip() for f in split(head)]})", line=head_line
            )
    if "r" not in found and "d" not in found:
        raise ParticleFileError(
            path,
            f"the header names no radius or diameter column (found {[f.strip() for f in split(head)]})",
            line=head_line,
        )
    ncols = len(names)
    data = _table(path, lines[1:], ncols, split, f"one per header column, separated by {delimiter or 'spaces'!r}")
    rcol = found["r"] if "r" in found else found["d"]
    centers = data[:, [found["x"], found["y"], found["z"]]]
    radii = data[:, rcol] / (1.0 if "r" in found else 2.0)
    scale = 1.0
    declared = {units[k] for k in ("x", "y", "z", "r" if "r" in found else "d")} - {None}
    if len(declared) > 1:
        raise ParticleFileError(path, "the header names different units for the coordinates and radii", line=head_line)
    if declared:
        scale = next(iter(declared))
    ids = None
    if "id" in found:
        ids = _ids(path, data[:, found["id"]], [ln for ln, _ in lines[1:]], found["id"] + 1)
    cols = {"xyz": [found["x"] + 1, found["y"] + 1, found["z"] + 1], "r": rcol + 1}
    _check_values(path, centers, radii, [ln for ln, _ in lines[1:]], cols)
    heads = [f.strip() for f in split(head)]
    what = ", ".join(heads[i] for i in (found["x"], found["y"], found["z"], rcol))
    what = f"columns {what}" + ("" if ids is None else f", ids from {heads[found['id']]}")
    notes = []
    if scale != 1.0:
        notes.append(f"the header gives {_UNIT_NAMES.get(scale, scale)}: converted to metres")
    return centers * scale, radii * scale, ids, what, (scale if declared else None), None, notes


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


# --- YADE text export -------------------------------------------------------------------------------------------


def _read_yade(path, text: str):
    fmt, rows = None, []
    for k, t in enumerate(text.splitlines()):
        s = t.strip()
        if not s:
            continue
        if s.startswith("#"):
            m = re.match(r"#\s*format\s+(\S+)", s)
            if m and fmt is None and not rows:
                fmt = m.group(1)
            continue
        rows.append((k + 1, s))
    tokens = (fmt or "x_y_z_r").split("_")
    if fmt is not None and not {"x", "y", "z", "r"} <= set(tokens):
        raise ParticleFileError(path, f"format {fmt!r} has no x, y, z and r", line=1)
    if not rows:
        return np.zeros((0, 3)), np.zeros(0), None, "no rows", None, None, []
    width = len(rows[0][1].split())
    fixed = [t for t in tokens if t != "attrs"]
    ncols = width if "attrs" in tokens or fmt is None else len(fixed)
    if ncols < 4 or (fmt is None and width < 4):
        raise ParticleFileError(path, f"expected at least 4 fields (x y z r), found {width}", line=rows[0][0])
    data = _table(path, rows, ncols, str.split, f"{fmt or 'x y z r'}")
    pos = {t: i for i, t in enumerate(fixed)}
    centers = data[:, [pos["x"], pos["y"], pos["z"]]]
    radii = data[:, pos["r"]].copy()
    ids = _ids(path, data[:, pos["id"]], [ln for ln, _ in rows], pos["id"] + 1) if "id" in pos else None
    cols = {"xyz": [pos["x"] + 1, pos["y"] + 1, pos["z"] + 1], "r": pos["r"] + 1}
    _check_values(path, centers, radii, [ln for ln, _ in rows], cols)
    what = f"format {fmt}" if fmt else "no #format line: columns 1-4 as x y z r"
    return centers, radii, ids, what, None, None, []


# --- LAMMPS / LIGGGHTS dump -------------------------------------------------------------------------------------


def _read_lammps(path, text: str, timestep: int | None):
    lines = text.splitlines()
    frames, units, k = [], None, 0
    cut = None  # a last timestep still being written: (its TIMESTEP line, its timestep or None)
    try:
        while k < len(lines):
            s = lines[k].strip()
            if not s:
                k += 1
                continue
            if not s.startswith("ITEM:"):
                raise ParticleFileError(path, f"expected an 'ITEM:' line, found {s[:40]!r}", line=k + 1, column=1)
            item = s[5:].strip()
            if item == "TIMESTEP":
                frames.append({"line": k + 1, "timestep": None})
                frames[-1]["timestep"] = _lammps_int(path, lines, k + 1)
                k += 2
            elif item.startswith("UNITS"):
                units = lines[k + 1].strip().lower() if k + 1 < len(lines) else None
                k += 2
            elif item.startswith("NUMBER OF ATOMS") or item.startswith("NUMBER OF ENTRIES"):
                _need_frame(path, frames, k)
                frames[-1]["n"] = _lammps_int(path, lines, k + 1)
                frames[-1]["n_line"] = k + 2
                k += 2
            elif item.startswith("BOX BOUNDS"):
                _need_frame(path, frames, k)
                if k + 4 > len(lines):
                    raise _Cut
                frames[-1]["box"] = (k + 1, item)
                k += 4
            elif item.startswith("ATOMS"):
                _need_frame(path, frames, k)
                n = frames[-1].get("n")
                if n is None:
                    raise ParticleFileError(path, "ITEM: ATOMS before ITEM: NUMBER OF ATOMS", line=k + 1)
                rows = lines[k + 1 : k + 1 + n]
                early = next((j for j, t in enumerate(rows) if t.lstrip().startswith("ITEM:")), None)
                if early is not None:
                    raise ParticleFileError(
                        path,
                        f"ITEM: NUMBER OF ATOMS (line {frames[-1]['n_line']}) says {n:,} but the timestep's ATOMS "
                        f"section holds {early:,} rows before the next ITEM",
                        line=k + 2 + early,
                    )
                after = k + 1 + n
                short_last = after == len(lines) and not text.endswith("\n")
                if after > len(lines) or (short_last and len(lines[-1].split()) < len(item[5:].split())):
                    # the writer has not finished this timestep (its last row may be cut too)
                    raise _Cut(f"the file ends {max(after - len(lines), 1)} atom lines short of the {n:,} announced")
                nxt = next((j for j in range(after, len(lines)) if lines[j].strip()), None)
                if nxt is not None and not lines[nxt].lstrip().startswith("ITEM:"):
                    raise ParticleFileError(
                        path,
                        f"ITEM: NUMBER OF ATOMS (line {frames[-1]['n_line']}) says {n:,} but the timestep's ATOMS "
                        "section holds more rows",
                        line=nxt + 1,
                    )
                frames[-1]["atoms"] = (k + 1, item[5:].split())
                k = after
            else:  # ITEM: TIME and others: one value line
                k += 2
    except _Cut as e:
        cut = (frames[-1]["line"], frames[-1]["timestep"], str(e) or "the file ends inside a timestep")
        frames = frames[:-1]
    frames = [f for f in frames if "atoms" in f]
    if not frames:
        if cut is not None:
            raise ParticleFileError(
                path, f"{cut[2]}, in its first timestep (still being written?): no complete timestep", line=len(lines)
            )
        raise ParticleFileError(path, "no 'ITEM: ATOMS' section: not a LAMMPS dump?")
    notes = []
    if cut is not None:
        import warnings

        step = "" if cut[1] is None else f" {cut[1]}"
        notes.append(
            f"the last timestep{step} (line {cut[0]}) is incomplete (still being written?): read the last complete "
            f"one, {frames[-1]['timestep']}"
        )
        warnings.warn(f"{path}: {notes[-1]}", stacklevel=3)
    if timestep is None:
        frame = frames[-1]
    else:
        match = [f for f in frames if f["timestep"] == timestep]
        if not match:
            have = ", ".join(str(f["timestep"]) for f in frames[:8]) + (", ..." if len(frames) > 8 else "")
            raise ParticleFileError(path, f"no timestep {timestep}; the file has {have}")
        frame = match[-1]
    head_line, cols = frame["atoms"]
    idx = {c: i for i, c in enumerate(cols)}
    n = frame["n"]
    rows = [(head_line + 1 + j, lines[head_line + j]) for j in range(n)]
    data = _table(path, rows, len(cols), str.split, " ".join(cols))
    names, kind = None, "plain"
    for cand in (("x", "y", "z"), ("xu", "yu", "zu"), ("xs", "ys", "zs"), ("xsu", "ysu", "zsu")):
        if all(c in idx for c in cand):
            names, kind = cand, ("scaled" if "s" in cand[0] else "plain")
            break
    if names is None:
        raise ParticleFileError(
            path,
            f"ITEM: ATOMS has no coordinates (x y z, xu yu zu, xs ys zs or xsu ysu zsu): {' '.join(cols)}",
            line=head_line,
        )
    rname = "radius" if "radius" in idx else ("diameter" if "diameter" in idx else None)
    if rname is None:
        raise ParticleFileError(
            path,
            f"ITEM: ATOMS has no radius or diameter column ({' '.join(cols)}); add radius to the dump command "
            "(dump custom ... radius)",
            line=head_line,
        )
    xyz = data[:, [idx[c] for c in names]]
    if kind == "scaled":
        xyz = _unscale(path, lines, frame, xyz)
    radii = data[:, idx[rname]] / (2.0 if rname == "diameter" else 1.0)
    ids = _ids(path, data[:, idx["id"]], [ln for ln, _ in rows], idx["id"] + 1) if "id" in idx else None
    colmap = {"xyz": [idx[c] + 1 for c in names], "r": idx[rname] + 1}
    _check_values(path, xyz, radii, [ln for ln, _ in rows], colmap)
    scale = 1.0
    if units in _LAMMPS_UNITS:
        scale, name = _LAMMPS_UNITS[units]
        if scale != 1.0:
            notes.append(f"ITEM: UNITS {units} ({name}): converted to metres")
    elif units is not None:
        notes.append(f"ITEM: UNITS {units}: kept as written")
    if len(frames) > 1:
        notes.append(f"the file holds {len(frames)} timesteps; read {frame['timestep']} (choose with --timestep)")
    what = f"columns {' '.join(names)} {rname}" + ("" if ids is None else " id")
    declared = scale if units in _LAMMPS_UNITS else None
    return xyz * scale, radii * scale, ids, what, declared, frame["timestep"], notes


class _Cut(Exception):
    """The dump ends inside a timestep (the message says where, if known)."""


def _need_frame(path, frames, k):
    if not frames:
        raise ParticleFileError(path, "an ITEM before the first ITEM: TIMESTEP", line=k + 1)


def _lammps_int(path, lines, k) -> int:
    if k >= len(lines):
        raise _Cut
    try:
        return int(lines[k].split()[0])
    except (IndexError, ValueError):
        raise ParticleFileError(path, "expected an integer", line=k + 1, column=1) from None


def _unscale(path, lines, frame, s: np.ndarray) -> np.ndarray:
    """Scaled coordinates to box coordinates, orthogonal or triclinic (LAMMPS' bounding-box convention)."""
    if "box" not in frame:
        raise ParticleFileError(path, "scaled coordinates need the ITEM: BOX BOUNDS of their timestep")
    k, item = frame["box"]
    rows = [(k + 1 + j, lines[k + j]) for j in range(3)]
    tilted = "xy" in item.split()
    b = _table(path, rows, 3 if tilted else 2, str.split, "lo hi" + (" tilt" if tilted else ""))
    xy, xz, yz = (b[0, 2], b[1, 2], b[2, 2]) if tilted else (0.0, 0.0, 0.0)
    xlo = b[0, 0] - min(0.0, xy, xz, xy + xz)
    xhi = b[0, 1] - max(0.0, xy, xz, xy + xz)
    ylo, yhi = b[1, 0] - min(0.0, yz), b[1, 1] - max(0.0, yz)
    zlo, zhi = b[2, 0], b[2, 1]
    x = xlo + s[:, 0] * (xhi - xlo) + s[:, 1] * xy + s[:, 2] * xz
    y = ylo + s[:, 1] * (yhi - ylo) + s[:, 2] * yz
    z = zlo + s[:, 2] * (zhi - zlo)
    return np.stack([x, y, z], axis=1)


# --- NumPy ------------------------------------------------------------------------------------------------------


def _read_npy(path):
    try:
        a = np.load(path, allow_pickle=False)
    except (ValueError, OSError) as e:
        raise ParticleFileError(path, f"not a NumPy .npy file ({e})") from None
    if a.ndim != 2 or a.shape[1] != 4 or a.dtype.kind not in "iuf":
        raise ParticleFileError(path, f"expected an (N, 4) array of numbers (x, y, z, radius), got {a.dtype} {a.shape}")
    a = a.astype(np.float64)
    _check_values(path, a[:, :3], a[:, 3])
    return a[:, :3], a[:, 3].copy(), None, "an (N, 4) array: x, y, z, radius", None, None, []


def _read_npz(path):
    try:
        z = np.load(path, allow_pickle=False)
        arrays = {k: z[k] for k in z.files}
    except (ValueError, OSError) as e:
        raise ParticleFileError(path, f"not a NumPy .npz file ({e})") from None
    lower = {k.lower(): k for k in arrays}

    def pick(names):
        return next((lower[n] for n in names if n in lower), None)

    ckey = pick(("centers", "centres", "positions", "position", "pos", "points", "x"))
    if ckey is not None and arrays[ckey].ndim == 2:
        centers = arrays[ckey]
        what = [ckey]
    elif all(k in lower for k in ("x", "y", "z")):
        centers = np.stack([arrays[lower[k]] for k in ("x", "y", "z")], axis=1)
        what = ["x", "y", "z"]
    else:
        raise ParticleFileError(path, f"no centres: expected 'centers' (N, 3) or 'x', 'y', 'z'; found {sorted(arrays)}")
    rkey = pick(("radii", "radius", "r", "rad"))
    dkey = pick(("diameter", "diameters", "d"))
    if rkey is None and dkey is None:
        raise ParticleFileError(path, f"no radii: expected 'radii' or 'diameter'; found {sorted(arrays)}")
    radii = arrays[rkey] if rkey is not None else arrays[dkey] / 2.0
    if centers.shape != (len(centers), 3) or centers.dtype.kind not in "iuf":
        raise ParticleFileError(
            path, f"{what[0]}: expected an (N, 3) array of numbers, got {centers.dtype} {centers.shape}"
        )
    if np.shape(radii) != (len(centers),) or np.asarray(radii).dtype.kind not in "iuf":
        raise ParticleFileError(
            path, f"{rkey or dkey}: expected shape ({len(centers)},) to match the centres, got {np.shape(radii)}"
        )
    ikey = pick(("ids", "id"))
    ids = None if ikey is None else _ids(path, np.asarray(arrays[ikey]).reshape(-1), what=ikey)
    if ids is not None and ids.shape != (len(centers),):
        raise ParticleFileError(path, f"{ikey}: expected shape ({len(centers)},), got {arrays[ikey].shape}")
    centers, radii = centers.astype(np.float64), np.asarray(radii, dtype=np.float64)
    _check_values(path, centers, radii, ids=ids)
    text = f"arrays {', '.join(what)}, {rkey or dkey}" + ("" if ikey is None else f", {ikey}")
    return centers, radii, ids, text, None, None, []


# --- VTK XML ----------------------------------------------------------------------------------------------------

_VTK_TYPES = {
    "Float32": "f4",
    "Float64": "f8",
    "Int8": "i1",
    "UInt8": "u1",
    "Int16": "i2",
    "UInt16": "u2",
    "Int32": "i4",
    "UInt32": "u4",
    "Int64": "i8",
    "UInt64": "u8",
}


class _Node:
    __slots__ = ("attrs", "children", "column", "line", "tag", "text")

    def __init__(self, tag, attrs, line, column):
        self.tag, self.attrs, self.line, self.column = tag, attrs, line, column
        self.children, self.text = [], []


def _parse_xml(path, data: bytes) -> _Node:
    parser = expat.ParserCreate()
    root = _Node("#root", {}, 0, 0)
    stack = [root]

    def start(tag, attrs):
        node = _Node(tag, attrs, parser.CurrentLineNumber, parser.CurrentColumnNumber + 1)
        stack[-1].children.append(node)
        stack.append(node)

    def end(tag):
        stack.pop()

    def chars(text):
        stack[-1].text.append(text)

    parser.StartElementHandler, parser.EndElementHandler, parser.CharacterDataHandler = start, end, chars
    try:
        parser.Parse(data, True)
    except expat.ExpatError as e:
        raise ParticleFileError(
            path, f"not well-formed XML ({expat.errors.messages[e.code]})", line=e.lineno, column=e.offset + 1
        ) from None
    return root


def _find(node: _Node, tag: str):
    for child in node.children:
        if child.tag == tag:
            yield child
        yield from _find(child, tag)


def _read_vtk(path, data: bytes):
    raw_blob = None
    start = data.find(b"<AppendedData")
    if start >= 0:
        open_end = data.index(b">", start) + 1
        opening = data[start:open_end]
        if b'encoding="raw"' in opening:
            stop = data.rfind(b"</AppendedData>")
            under = data.index(b"_", open_end)
            raw_blob = data[under + 1 : stop]
            data = data[:open_end] + b"</AppendedData>" + data[stop + len(b"</AppendedData>") :]
    root = _parse_xml(path, data)
    vtk = next(_find(root, "VTKFile"), None)
    if vtk is None:
        raise ParticleFileError(path, "no VTKFile element: not a VTK XML file", line=1)
    kind = vtk.attrs.get("type", "")
    if kind not in ("UnstructuredGrid", "PolyData"):
        raise ParticleFileError(
            path, f"VTKFile type {kind!r}: expected UnstructuredGrid (.vtu) or PolyData (.vtp)", line=vtk.line
        )
    ctx = {
        "order": "<" if vtk.attrs.get("byte_order", "LittleEndian") == "LittleEndian" else ">",
        "header": "u8" if vtk.attrs.get("header_type", "UInt32") == "UInt64" else "u4",
        "zlib": vtk.attrs.get("compressor", "") == "vtkZLibDataCompressor",
        "raw": raw_blob,
    }
    if vtk.attrs.get("compressor") and not ctx["zlib"]:
        raise ParticleFileError(path, f"compressor {vtk.attrs['compressor']}: only zlib is read", line=vtk.line)
    appended = next(_find(vtk, "AppendedData"), None)
    ctx["b64"] = (
        "".join(appended.text).strip().lstrip("_").strip() if appended is not None and raw_blob is None else None
    )
    centers, radii, ids, names = [], [], [], set()
    pieces = list(_find(vtk, "Piece"))
    if not pieces:
        raise ParticleFileError(path, "no Piece element", line=vtk.line)
    for piece in pieces:
        n = int(piece.attrs.get("NumberOfPoints", "0"))
        points = next(_find(piece, "Points"), None)
        if points is None or not points.children:
            raise ParticleFileError(path, "a Piece without Points", line=piece.line)
        xyz = _vtk_array(path, points.children[0], ctx, n, 3)
        point_data = next(_find(piece, "PointData"), None)
        arrays = {} if point_data is None else {a.attrs.get("Name", ""): a for a in point_data.children}
        norm = {re.sub(r"[^a-z0-9]", "", k.lower()): k for k in arrays}
        rname = next((norm[k] for k in ("radius", "radii", "rad", "r", "particleradius") if k in norm), None)
        dname = next((norm[k] for k in ("diameter", "diam", "d") if k in norm), None)
        if rname is None and dname is None:
            raise ParticleFileError(
                path,
                f"no radius or diameter point array (point arrays: {sorted(arrays)})",
                line=(point_data or piece).line,
            )
        name = rname or dname
        r = _vtk_array(path, arrays[name], ctx, n, 1)[:, 0] / (1.0 if rname else 2.0)
        iname = next((norm[k] for k in ("id", "ids", "particleid", "globalids") if k in norm), None)
        ids.append(None if iname is None else _ids(path, _vtk_array(path, arrays[iname], ctx, n, 1)[:, 0], what=iname))
        centers.append(xyz)
        radii.append(r)
        names.add(name if iname is None else f"{name}, {iname}")
    c, r = np.concatenate(centers), np.concatenate(radii)
    i = None if any(x is None for x in ids) else np.concatenate(ids)
    _check_values(path, c, r, ids=i)
    what = f"{kind}, {len(pieces)} piece{'s' if len(pieces) > 1 else ''}, point array {' / '.join(sorted(names))}"
    return c, r, i, what, None, None, []


def _vtk_array(path, node: _Node, ctx, n: int, comps: int) -> np.ndarray:
    if node.tag != "DataArray":
        raise ParticleFileError(path, f"expected a DataArray, found {node.tag}", line=node.line)
    vtype = node.attrs.get("type", "")
    if vtype not in _VTK_TYPES:
        raise ParticleFileError(path, f"DataArray type {vtype!r} is not a number type", line=node.line)
    have = int(node.attrs.get("NumberOfComponents", "1"))
    if have != comps:
        raise ParticleFileError(
            path, f"DataArray {node.attrs.get('Name', '')!r}: {have} components, expected {comps}", line=node.line
        )
    dtype = np.dtype(ctx["order"] + _VTK_TYPES[vtype])
    fmt = node.attrs.get("format", "ascii")
    try:
        if fmt == "ascii":
            values = np.array("".join(node.text).split(), dtype=np.float64)
        elif fmt == "binary":
            values = _decode_b64(path, "".join(node.text).strip(), ctx, dtype, node)
        elif fmt == "appended":
            offset = int(node.attrs["offset"])
            if ctx["raw"] is not None:
                values = _decode_raw(path, ctx["raw"], offset, ctx, dtype, node)
            elif ctx["b64"] is not None:
                values = _decode_b64(path, ctx["b64"][offset:], ctx, dtype, node)
            else:
                raise ParticleFileError(path, "format 'appended' but no AppendedData", line=node.line)
        else:
            raise ParticleFileError(
                path, f"DataArray format {fmt!r}: expected ascii, binary or appended", line=node.line
            )
    except (ValueError, KeyError, zlib.error, base64.binascii.Error) as e:
        if isinstance(e, ParticleFileError):
            raise
        raise ParticleFileError(
            path, f"cannot decode DataArray {node.attrs.get('Name', '')!r} ({e})", line=node.line
        ) from None
    values = np.asarray(values, dtype=np.float64)
    if values.size != n * comps:
        # More values than NumberOfPoints says is as wrong as fewer: which count is right cannot be told.
        raise ParticleFileError(
            path,
            f"DataArray {node.attrs.get('Name', '')!r} holds {values.size} values; NumberOfPoints {n} with "
            f"{comps} component{'s' if comps > 1 else ''} needs {n * comps}",
            line=node.line,
        )
    return values[: n * comps].reshape(n, comps)


def _decode_b64(path, text: str, ctx, dtype, node) -> np.ndarray:
    text = "".join(text.split())
    hsize = np.dtype(ctx["header"]).itemsize
    header_t = np.dtype(ctx["order"] + ctx["header"])
    if ctx["zlib"]:
        first = base64.b64decode(text[: 4 * ((3 * hsize + 2) // 3)])
        nblocks = int(np.frombuffer(first[:hsize], dtype=header_t)[0])
        hlen = 4 * (((3 + nblocks) * hsize + 2) // 3)
        header = np.frombuffer(base64.b64decode(text[:hlen])[: (3 + nblocks) * hsize], dtype=header_t)
        sizes = header[3:].astype(np.int64)
        body = base64.b64decode(text[hlen : hlen + 4 * ((int(sizes.sum()) + 2) // 3)])
        return _inflate(body, sizes, dtype)
    # Uncompressed: VTK encodes the header and the data separately; some writers encode them together.
    hlen = 4 * ((hsize + 2) // 3)
    head = base64.b64decode(text[:hlen])
    nbytes = int(np.frombuffer(head[:hsize], dtype=header_t)[0])
    if hsize % 3 and text[hlen - 1] == "=":
        body = base64.b64decode(text[hlen : hlen + 4 * ((nbytes + 2) // 3)])[:nbytes]
    else:
        body = base64.b64decode(text[: 4 * ((hsize + nbytes + 2) // 3)])[hsize : hsize + nbytes]
    return np.frombuffer(body, dtype=dtype)


def _decode_raw(path, blob: bytes, offset: int, ctx, dtype, node) -> np.ndarray:
    hsize = np.dtype(ctx["header"]).itemsize
    header_t = np.dtype(ctx["order"] + ctx["header"])
    if ctx["zlib"]:
        nblocks = int(np.frombuffer(blob[offset : offset + hsize], dtype=header_t)[0])
        header = np.frombuffer(blob[offset : offset + (3 + nblocks) * hsize], dtype=header_t)
        sizes = header[3:].astype(np.int64)
        start = offset + (3 + nblocks) * hsize
        return _inflate(blob[start : start + int(sizes.sum())], sizes, dtype)
    nbytes = int(np.frombuffer(blob[offset : offset + hsize], dtype=header_t)[0])
    body = blob[offset + hsize : offset + hsize + nbytes]
    if len(body) != nbytes:
        raise ValueError(f"the appended data ends {nbytes - len(body)} bytes short")
    return np.frombuffer(body, dtype=dtype)


def _inflate(body: bytes, sizes: np.ndarray, dtype) -> np.ndarray:
    out, at = [], 0
    for size in sizes:
        out.append(zlib.decompress(body[at : at + int(size)]))
        at += int(size)
    return np.frombuffer(b"".join(out), dtype=dtype)


# --- legacy VTK: refused by format, with the way round it ----------------------------------------------------------


def _refuse_legacy_vtk(path, head: bytes) -> None:
    """Legacy VTK (``# vtk DataFile``, what YADE's ``export.VTKExporter`` writes): no well-kept reader without VTK
    itself reads its POLYDATA (meshio 5.3 reads legacy unstructured grids only), and a hand parser is not worth
    its bugs; say how to get a format that is read."""
    kind = re.search(rb"DATASET\s+(\w+)", head)
    what = f"legacy VTK ({kind.group(1).decode() if kind else 'no DATASET line'})"
    raise ParticleFileError(
        path,
        f"{what} is not read; write the particles as VTK XML or text instead: in YADE, export.text('spheres.txt') "
        "or VTKRecorder (.vtu); in ParaView, File > Save Data as .vtp or .csv (with the radius array)",
        line=1,
    )


# --- the entry point --------------------------------------------------------------------------------------------


def _sniff(path, head: bytes) -> str:
    ext = os.path.splitext(str(path))[1].lower()
    if ext in _EXTENSIONS:
        return _EXTENSIONS[ext]
    if head.startswith(b"\x93NUMPY"):
        return "npy"
    if head.startswith(b"PK"):
        return "npz"
    text = head.decode("utf-8-sig", "replace").lstrip()
    if text.startswith("<?xml") or text.startswith("<VTKFile"):
        return "vtk"
    if text.startswith("# vtk DataFile"):
        return "vtk-legacy"
    if text.startswith("ITEM:"):
        return "lammps"
    lines = [t.strip() for t in text.splitlines() if t.strip()]
    if any(re.match(r"#\s*format\s", t) for t in lines[:5]):
        return "yade"
    first = next((t for t in lines if not t.startswith("#")), "")
    fields = [f for f in re.split(r"[,;\t ]+", first) if f]
    return "yade" if fields and all(_is_number(f) for f in fields) else "csv"


def read_particles(path, *, fmt: str | None = None, timestep: int | None = None, scale: float | None = None):
    """Read particles from a file (see the module's docstring for the formats).

    Args:
        path: The file.
        fmt: One of :data:`FORMATS`; by default from the extension, else from the content.
        timestep: LAMMPS dumps: the timestep to read (default: the last in the file).
        scale: Factor for every length read, after any unit the file names (0.001 for a file in millimetres). Given
            (even 1), it says the lengths are then metres (:attr:`ParticlesInfo.length_unit`).

    Returns:
        (centers, radii, ids, info): centres, shape (N, 3), float64; radii, shape (N,), float64 (diameters
        halved); ids, shape (N,), int64, or None where the file has none; and a :class:`ParticlesInfo`.

    Raises:
        ParticleFileError: the file cannot be read, or holds a bad value: one line naming the file, and the line
            and column where the format has them.
        ValueError: ``fmt``, ``timestep`` or ``scale`` is not valid.
    """
    if fmt is not None and fmt not in FORMATS:
        raise ValueError(f"fmt: unknown format {fmt!r}; expected one of {FORMATS}")
    if timestep is not None and (isinstance(timestep, bool) or not isinstance(timestep, (int, np.integer))):
        raise ValueError(f"timestep: expected an integer, got {timestep!r}")
    scale_given = scale is not None
    scale = 1.0 if scale is None else scale
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale: expected a finite number > 0, got {scale!r}")
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise ParticleFileError(path, f"cannot read it ({e.strerror or e})") from None
    kind = fmt or _sniff(path, data[:4096])
    if kind == "vtk-legacy":
        _refuse_legacy_vtk(path, data[:4096])
    if timestep is not None and kind != "lammps":
        raise ValueError(f"timestep: only LAMMPS dumps have timesteps; {path} reads as {kind}")
    if kind == "npy":
        out = _read_npy(path)
    elif kind == "npz":
        out = _read_npz(path)
    elif kind == "vtk":
        out = _read_vtk(path, data)
    else:
        try:
            # utf-8-sig: a byte-order mark (Excel, Notepad) before the first line is not part of it
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as e:
            line = data[: e.start].count(b"\n") + 1
            raise ParticleFileError(path, f"not a text file ({kind}): byte {e.start} is not UTF-8", line=line) from None
        reader = {"csv": _read_csv, "yade": _read_yade}.get(kind)
        out = _read_lammps(path, text, timestep) if kind == "lammps" else reader(path, text)
    centers, radii, ids, columns, file_scale, step, notes = out
    # The lengths are known to be metres where the file names its unit or the caller scaled them.
    in_metres = file_scale is not None or scale_given
    file_scale = 1.0 if file_scale is None else file_scale
    _check_unique(path, ids)
    centers = np.ascontiguousarray(centers * scale, dtype=np.float64)
    radii = np.ascontiguousarray(radii * scale, dtype=np.float64)
    n = len(radii)
    info = ParticlesInfo(
        path=str(path),
        format={"vtk": "VTK XML", "lammps": "LAMMPS dump", "yade": "YADE text", "csv": "CSV"}.get(kind, kind),
        count=n,
        lower=centers.min(axis=0) if n else np.zeros(3),
        upper=centers.max(axis=0) if n else np.zeros(3),
        radius_min=float(radii.min()) if n else 0.0,
        radius_mean=float(radii.mean()) if n else 0.0,
        radius_max=float(radii.max()) if n else 0.0,
        scale=file_scale * scale,
        length_unit="m" if in_metres else None,
        units=radii_unit_hint(centers, radii) or guess_units(radii),
        columns=columns,
        timestep=step,
        notes=list(notes) + ([f"lengths multiplied by {scale:g}"] if scale != 1.0 else []),
    )
    return centers, radii, ids, info
