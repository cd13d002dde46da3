"""Reading a user's particles: CSV, NumPy, VTK XML points, LAMMPS/LIGGGHTS dumps and YADE's text export, from
small files written here; bad files give one line naming the file, the line and the column."""

import base64
import re
import zlib

import numpy as np
import pytest

from warp_lamp.particles_io import ParticleFileError, guess_units, read_particles

RNG = np.random.default_rng(7)
CENTERS = RNG.uniform(-0.05, 0.05, (9, 3))
RADII = RNG.uniform(0.002, 0.003, 9)
IDS = np.arange(101, 110)


def write(path, text: str):
    path.write_text(text)
    return path


def check(got, *, ids=True, rtol=1e-12, scale=1.0):
    centers, radii, got_ids, info = got
    np.testing.assert_allclose(centers, CENTERS * scale, rtol=rtol, atol=1e-15)
    np.testing.assert_allclose(radii, RADII * scale, rtol=rtol)
    if ids:
        np.testing.assert_array_equal(got_ids, IDS)
    else:
        assert got_ids is None
    assert info.count == 9
    np.testing.assert_allclose(info.lower, (CENTERS * scale).min(axis=0), rtol=rtol)
    return info


def rows(fmt="{:.17g}", sep=" ", diameter=False, ids=False):
    out = []
    for k in range(9):
        vals = [*CENTERS[k], RADII[k] * (2 if diameter else 1)]
        text = sep.join(fmt.format(v) for v in vals)
        out.append((f"{IDS[k]}{sep}" if ids else "") + text)
    return "\n".join(out) + "\n"


# --- CSV ----------------------------------------------------------------------------------------------------


def test_csv_with_a_plain_header(tmp_path):
    """x,y,z,radius,id: centres, radii and ids read back exactly; the summary names count, bounds and units."""
    lines = [f"{c[0]:.17g},{c[1]:.17g},{c[2]:.17g},{r:.17g},{i}" for c, r, i in zip(CENTERS, RADII, IDS, strict=True)]
    info = check(read_particles(write(tmp_path / "p.csv", "x,y,z,radius,id\n" + "\n".join(lines) + "\n")))
    text = info.summary()
    assert "read 9 particles" in text and "CSV" in text and "radii look like metres" in text


@pytest.mark.parametrize(
    ("header", "sep", "diameter", "scale"),
    [
        ("ID;X [mm];Y [mm];Z [mm];Diameter [mm]", ";", True, 1e-3),  # semicolons, a unit, diameters
        ("id\tpos_x\tpos_y\tpos_z\tr", "\t", False, 1.0),
        ("id Points:0 Points:1 Points:2 rad", " ", False, 1.0),  # ParaView's names, whitespace
        ("particle_id, x (cm), y (cm), z (cm), radius (cm)", ", ", False, 1e-2),
    ],
)
def test_csv_headers_are_read_liberally(tmp_path, header, sep, diameter, scale):
    """Delimiters, case, underscores, ParaView's Points:0, diameters and a unit in brackets (converted to metres)."""
    body = rows(sep=sep, diameter=diameter, ids=True)
    path = write(tmp_path / "p.csv", header + "\n" + body)
    centers, radii, ids, info = read_particles(path)
    np.testing.assert_allclose(centers, CENTERS * scale, rtol=1e-12)
    np.testing.assert_allclose(radii, RADII * scale, rtol=1e-12)
    np.testing.assert_array_equal(ids, IDS)
    if scale != 1.0:
        assert "converted to metres" in info.summary()


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("x,y,z,radius\n1,2,3,0.1\n1,2,oops,0.1\n", r"p\.csv, line 3, column 3: not a number: 'oops'"),
        ("x,y,z,radius\n1,2,3,0.1\n1,2,3\n", r"p\.csv, line 3, column 4: expected 4 fields"),
        ("x,y,z,radius\n1,2,3,0.1\n1,2,3,-0.5\n", r"p\.csv, line 3, column 4: radius must be finite and > 0"),
        ("x,y,z,radius\n1,2,3,0.1\n1,nan,3,0.5\n", r"p\.csv, line 3, column 2: a centre coordinate is not finite"),
        ("x,y,radius\n1,2,0.1\n", r"p\.csv, line 1: the header names no z column"),
        ("a,x,y,z\n1,2,3,4\n", r"p\.csv, line 1: the header names no radius or diameter column"),
        ("", r"p\.csv: no header and no data"),
    ],
)
def test_bad_csv_names_file_line_and_column(tmp_path, text, match):
    """Each fault is one line: the file, the line and the column of the first bad field."""
    with pytest.raises(ParticleFileError, match=match) as e:
        read_particles(write(tmp_path / "p.csv", text))
    assert "\n" not in str(e.value)


# --- NumPy --------------------------------------------------------------------------------------------------


def test_npy_and_npz(tmp_path):
    """An (N, 4) .npy; .npz with centres as one array or three, radii or diameters, and ids."""
    np.save(tmp_path / "p.npy", np.column_stack([CENTERS, RADII]))
    check(read_particles(tmp_path / "p.npy"), ids=False)
    np.savez(tmp_path / "a.npz", centers=CENTERS, radii=RADII, ids=IDS)
    check(read_particles(tmp_path / "a.npz"))
    np.savez(tmp_path / "b.npz", x=CENTERS[:, 0], y=CENTERS[:, 1], z=CENTERS[:, 2], diameter=2 * RADII)
    check(read_particles(tmp_path / "b.npz"), ids=False)
    np.save(tmp_path / "bad.npy", np.zeros((3, 5)))
    with pytest.raises(ParticleFileError, match=r"bad\.npy: expected an \(N, 4\) array"):
        read_particles(tmp_path / "bad.npy")
    np.savez(tmp_path / "bad.npz", centers=CENTERS, radii=RADII[:4])
    with pytest.raises(ParticleFileError, match=r"bad\.npz: radii: expected shape \(9,\)"):
        read_particles(tmp_path / "bad.npz")


# --- VTK XML ------------------------------------------------------------------------------------------------


def _b64_block(data: bytes, header: str, compress: bool, together: bool) -> str:
    ht = np.dtype("<u8" if header == "UInt64" else "<u4")
    if compress:
        comp = zlib.compress(data)
        head = np.array([1, len(data), len(data), len(comp)], dtype=ht).tobytes()
        return base64.b64encode(head).decode() + base64.b64encode(comp).decode()
    head = np.array([len(data)], dtype=ht).tobytes()
    if together:
        return base64.b64encode(head + data).decode()
    return base64.b64encode(head).decode() + base64.b64encode(data).decode()


def write_vtk(
    path, *, mode, header="UInt32", compress=False, together=False, kind="UnstructuredGrid", name="radius", order="<"
):
    """A VTK XML file of CENTERS with a point array ``name``, in the given encoding, as VTK's writers lay it out."""
    arrays = [
        ("Points", CENTERS.astype(order + "f8"), 3),
        (name, RADII.astype(order + "f8"), 1),
        ("id", IDS.astype(order + "i8"), 1),
    ]
    vtype = {"Points": "Float64", name: "Float64", "id": "Int64"}
    pieces, appended, raw = [], "", b""
    for label, arr, comps in arrays:
        attrs = f'type="{vtype[label]}" Name="{label}" NumberOfComponents="{comps}"'
        if mode == "ascii":
            body = " ".join(repr(float(v)) if arr.dtype.kind == "f" else str(int(v)) for v in arr.ravel())
            pieces.append(f'<DataArray {attrs} format="ascii">\n{body}\n</DataArray>')
        elif mode == "binary":
            pieces.append(
                f'<DataArray {attrs} format="binary">\n{_b64_block(arr.tobytes(), header, compress, together)}\n'
                "</DataArray>"
            )
        elif mode == "appended":
            pieces.append(f'<DataArray {attrs} format="appended" offset="{len(appended)}"/>')
            appended += _b64_block(arr.tobytes(), header, compress, together)
        else:  # raw
            pieces.append(f'<DataArray {attrs} format="appended" offset="{len(raw)}"/>')
            ht = np.dtype(order + ("u8" if header == "UInt64" else "u4"))
            raw += np.array([arr.nbytes], dtype=ht).tobytes() + arr.tobytes()
    comp = ' compressor="vtkZLibDataCompressor"' if compress else ""
    endian = "LittleEndian" if order == "<" else "BigEndian"
    head = (
        f'<?xml version="1.0"?>\n<VTKFile type="{kind}" version="1.0" byte_order="{endian}" '
        f'header_type="{header}"{comp}>\n<{kind}>\n<Piece NumberOfPoints="9" NumberOfCells="0">\n'
    )
    xml = head + f"<Points>\n{pieces[0]}\n</Points>\n<PointData>\n{pieces[1]}\n{pieces[2]}\n</PointData>\n"
    xml += f"</Piece>\n</{kind}>\n"
    data = xml.encode()
    if mode == "appended":
        data += f'<AppendedData encoding="base64">\n_{appended}\n</AppendedData>\n'.encode()
    elif mode == "raw":
        data += b'<AppendedData encoding="raw">\n_' + raw + b"\n</AppendedData>\n"
    path.write_bytes(data + b"</VTKFile>\n")
    return path


@pytest.mark.parametrize(
    "options",
    [
        {"mode": "ascii"},
        {"mode": "binary"},  # VTK: header and data encoded apart
        {"mode": "binary", "together": True},  # other writers: in one base64 stream
        {"mode": "binary", "header": "UInt64", "compress": True},
        {"mode": "appended", "header": "UInt64"},
        {"mode": "appended", "compress": True},
        {"mode": "raw", "header": "UInt64"},
        {"mode": "raw", "compress": False, "order": ">"},
        {"mode": "ascii", "kind": "PolyData", "name": "radii"},
    ],
)
def test_vtk_points_in_every_encoding(tmp_path, options):
    """ASCII, inline base64, appended base64 and raw, UInt32/UInt64 headers, zlib, big-endian, .vtu and .vtp."""
    ext = ".vtp" if options.get("kind") == "PolyData" else ".vtu"
    check(read_particles(write_vtk(tmp_path / f"p{ext}", **options)))


def test_vtk_written_by_pyevtk_reads_back(tmp_path):
    """What warp_lamp's own VTK export (pyevtk: raw appended, UInt64 headers) writes reads back bitwise."""
    pytest.importorskip("pyevtk")
    from warp_lamp.export import write_vtk_particles

    path = write_vtk_particles(tmp_path / "p", CENTERS, RADII, force=np.ones((9, 3)))
    check(read_particles(path), ids=False, rtol=0)


def test_vtk_without_a_radius_array_or_broken(tmp_path):
    """No radius or diameter array, and malformed XML: one line with the file and the line."""
    path = write_vtk(tmp_path / "p.vtu", mode="ascii", name="velocity")
    with pytest.raises(ParticleFileError, match=r"p\.vtu, line \d+: no radius or diameter point array"):
        read_particles(path)
    text = path.read_text().replace("</Points>", "", 1)
    with pytest.raises(ParticleFileError, match=r"p\.vtu, line \d+, column \d+: not well-formed XML"):
        read_particles(write(tmp_path / "p.vtu", text))


# --- LAMMPS / LIGGGHTS ---------------------------------------------------------------------------------------


def dump_frame(step, columns, values, box="ITEM: BOX BOUNDS pp pp pp\n-0.1 0.1\n-0.1 0.1\n-0.1 0.1\n", n=None):
    n = len(values) if n is None else n
    body = "\n".join(" ".join(f"{v:.17g}" for v in row) for row in values)
    return f"ITEM: TIMESTEP\n{step}\nITEM: NUMBER OF ATOMS\n{n}\n{box}ITEM: ATOMS {columns}\n{body}\n"


def test_lammps_dump_last_timestep_or_the_one_asked(tmp_path):
    """A LIGGGHTS-style dump with two timesteps: the last by default, or the one asked for; the summary says so."""
    old = np.column_stack([IDS, np.ones(9), CENTERS + 1.0, np.zeros((9, 3)), RADII])
    new = np.column_stack([IDS, np.ones(9), CENTERS, np.zeros((9, 3)), RADII])
    cols = "id type x y z vx vy vz radius"
    path = write(tmp_path / "dump.liggghts", dump_frame(0, cols, old) + dump_frame(1000, cols, new))
    info = check(read_particles(path))
    assert info.timestep == 1000 and "2 timesteps" in info.summary()
    c, _, _, info = read_particles(path, timestep=0)
    np.testing.assert_allclose(c, CENTERS + 1.0, rtol=1e-12)
    with pytest.raises(ParticleFileError, match=r"no timestep 5; the file has 0, 1000"):
        read_particles(path, timestep=5)


def test_lammps_scaled_coordinates_orthogonal_and_triclinic(tmp_path):
    """xs ys zs with the box (orthogonal, and triclinic with its bounding-box convention), diameter column."""
    lo, hi = np.array([-0.1, -0.2, -0.3]), np.array([0.1, 0.2, 0.3])
    s = (CENTERS - lo) / (hi - lo)
    box = "ITEM: BOX BOUNDS pp pp pp\n" + "".join(f"{a:.17g} {b:.17g}\n" for a, b in zip(lo, hi, strict=True))
    path = write(tmp_path / "a.dump", dump_frame(5, "id xs ys zs diameter", np.column_stack([IDS, s, 2 * RADII]), box))
    check(read_particles(path))
    # Triclinic: x = xlo + xs lx + ys xy + zs xz, y = ylo + ys ly + zs yz, z = zlo + zs lz.
    xy, xz, yz = 0.02, -0.01, 0.03
    L = hi - lo
    zs = (CENTERS[:, 2] - lo[2]) / L[2]
    ys = (CENTERS[:, 1] - lo[1] - zs * yz) / L[1]
    xs = (CENTERS[:, 0] - lo[0] - ys * xy - zs * xz) / L[0]
    bounds = [
        (lo[0] + min(0, xy, xz, xy + xz), hi[0] + max(0, xy, xz, xy + xz), xy),
        (lo[1] + min(0, yz), hi[1] + max(0, yz), xz),
        (lo[2], hi[2], yz),
    ]
    box = "ITEM: BOX BOUNDS xy xz yz pp pp pp\n" + "".join(f"{a:.17g} {b:.17g} {t:.17g}\n" for a, b, t in bounds)
    values = np.column_stack([IDS, xs, ys, zs, RADII])
    check(read_particles(write(tmp_path / "t.dump", dump_frame(5, "id xs ys zs radius", values, box))), rtol=1e-9)


def test_lammps_units_and_bad_dumps(tmp_path):
    """ITEM: UNITS cgs is converted to metres; a dump without radii, or cut short, is one line with its line."""
    units = "ITEM: UNITS\ncgs\n" + dump_frame(1, "id x y z radius", np.column_stack([IDS, CENTERS * 100, RADII * 100]))
    info = check(read_particles(write(tmp_path / "u.lammpstrj", units)), rtol=1e-12)
    assert "converted to metres" in info.summary()
    no_r = dump_frame(1, "id type x y z", np.column_stack([IDS, np.ones(9), CENTERS]))
    with pytest.raises(ParticleFileError, match=r"r\.dump, line 9: ITEM: ATOMS has no radius or diameter column"):
        read_particles(write(tmp_path / "r.dump", no_r))
    short = dump_frame(1, "id x y z radius", np.column_stack([IDS, CENTERS, RADII]), n=12)
    with pytest.raises(ParticleFileError, match=r"s\.dump, line \d+: the file ends 3 atom lines short of the 12"):
        read_particles(write(tmp_path / "s.dump", short))
    bad = dump_frame(1, "id x y z radius", np.column_stack([IDS, CENTERS, RADII])).replace("\n102 ", "\n102 x", 1)
    with pytest.raises(ParticleFileError, match=r"b\.dump, line 11, column 2: not a number"):
        read_particles(write(tmp_path / "b.dump", bad))


# --- YADE ---------------------------------------------------------------------------------------------------


def test_yade_text_export(tmp_path):
    """yade.export.text: '#format x_y_z_r' and a comment, tab separated (%g, 6 digits); id_x_y_z_r_matId; no
    #format line at all."""
    body = "".join(f"{c[0]:g}\t{c[1]:g}\t{c[2]:g}\t{r:g}\n" for c, r in zip(CENTERS, RADII, strict=True))
    info = check(
        read_particles(write(tmp_path / "y.txt", "#format x_y_z_r\n# made by yade\n" + body)), ids=False, rtol=1e-5
    )
    assert info.format == "YADE text"
    body = "".join(
        f"{i}\t{c[0]:.17g}\t{c[1]:.17g}\t{c[2]:.17g}\t{r:.17g}\t3\n"
        for i, c, r in zip(IDS, CENTERS, RADII, strict=True)
    )
    check(read_particles(write(tmp_path / "z.txt", "#format id_x_y_z_r_matId\n" + body)))
    check(read_particles(write(tmp_path / "plain.txt", rows())), ids=False)
    bad = rows().splitlines()
    bad[2] = bad[2].replace(" ", " ?", 1)
    with pytest.raises(ParticleFileError, match=r"w\.txt, line 4, column 2: not a number: '\?"):
        read_particles(write(tmp_path / "w.txt", "#format x_y_z_r\n" + "\n".join(bad) + "\n"))


def test_units_guess():
    """Metres, millimetres (or no unit) and the implausible ends are told apart by the median radius."""
    assert "metres" in guess_units(np.array([0.0025]))
    assert "millimetres" in guess_units(np.array([2.5]))
    assert "tiny" in guess_units(np.array([1e-7])) and "large" in guess_units(np.array([500.0]))


def test_bad_arguments(tmp_path):
    """An unknown format, a timestep for a file without them, and a missing file."""
    np.save(tmp_path / "p.npy", np.column_stack([CENTERS, RADII]))
    with pytest.raises(ValueError, match=r"fmt: unknown format 'xls'"):
        read_particles(tmp_path / "p.npy", fmt="xls")
    with pytest.raises(ValueError, match=r"timestep: only LAMMPS dumps have timesteps"):
        read_particles(tmp_path / "p.npy", timestep=3)
    with pytest.raises(ParticleFileError, match=re.escape(f"{tmp_path / 'none.csv'}: cannot read it")):
        read_particles(tmp_path / "none.csv")
