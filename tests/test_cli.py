"""The warp-lamp command line: one-line errors before any work, a full report, saved results and VTK files.

The command line's first hour: flags before the sub-command kept, one-line errors naming the flag, ``--json -``,
writability checked first, saved results of the wrong kind refused, no developer words, the first-run note only
when true, and the user's own particles in every mode, with the inputs written beside the outputs.

``warp-lamp run`` (``python -m warp_lamp``), the README's first command: its printed report against values
computed here from the scene, the float64 reference's owners and ``lamp_forces``.

Reading a user's particles: CSV, NumPy, VTK XML points, LAMMPS/LIGGGHTS dumps and YADE's text export, from
small files written here; bad files give one line naming the file, the line and the column."""

import base64
import importlib.util
import json
import re
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
import warp as wp

import warp_lamp
import warp_lamp as wl
from warp_lamp import cli
from warp_lamp.particles_io import ParticleFileError, guess_units, read_particles
from warp_lamp.reference import lamp_reference
from warp_lamp.scenes import scene_lattice_ball, scene_sphere_specimen

ROOT = Path(__file__).resolve().parents[1]

H200 = ROOT / "bench" / "results" / "h200-2026-11-22.json"

H200_POROSITY = ROOT / "bench" / "results" / "h200-2026-11-22-porosity.json"


def fail(capsys, argv) -> str:
    """Run argv, expect exit status 2 and a one-line error after the usage; return that line."""
    with pytest.raises(SystemExit) as e:
        cli.main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if re.match(r"warp-lamp( \w+)?: error: ", line)]
    assert "usage: warp-lamp" in err and len(lines) == 1 and err.endswith(lines[0] + "\n"), err
    return lines[0]


@pytest.fixture
def no_work(monkeypatch):
    """Any attempt to build the specimen or run a benchmark fails the test: errors must come first."""

    def refuse(*args, **kwargs):
        raise AssertionError("the work started before the arguments were checked")

    import warp_lamp.bench
    import warp_lamp.bench.porosity
    import warp_lamp.scenes

    monkeypatch.setattr(warp_lamp.scenes, "scene_sphere_specimen", refuse)
    monkeypatch.setattr(warp_lamp.bench, "bench_lamp", refuse)
    monkeypatch.setattr(warp_lamp.bench.porosity, "bench_porosity", refuse)


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--device", "gpu7"], r"--device gpu7: no such Warp device; present: cpu"),
        (["--pressure", "nan"], r"argument --pressure: must be finite, got 'nan'"),
        (["--pressure", "-1"], r"argument --pressure: must be > 0"),
        (["--cells-per-diameter", "0"], r"argument --cells-per-diameter: must be > 0, got '0'"),
        (["run", "--repeats", "0"], r"argument --repeats: must be > 0, got '0'"),
        (["--repeats", "two"], r"argument --repeats: expected an integer, got 'two'"),
        (["--json", "/no/such/folder/run.json"], r"--json /no/such/folder/run.json: the folder /no/such/folder does"),
        (["--json", "."], r"--json \.: is a folder, expected a file name"),
        (["--vtk", "/no/such/folder/out"], r"--vtk /no/such/folder/out: the folder /no/such/folder does not exist"),
        (["bench", "--json", "/no/such/folder/b.json"], r"--json /no/such/folder/b.json: the folder"),
        (["bench", "--from-json", "/no/such/file.json"], r"--from-json /no/such/file.json: cannot read it"),
        (["bench", "--from-json", str(ROOT / "README.md")], r"--from-json .*README.md: not a JSON file"),
        (["bench", "porosity", "--plot", "p.png"], r"--plot is not used by bench porosity"),
        (["bench", "porosity", "--repeats", "3"], r"--repeats is not used by bench porosity"),
        (["bench", "porosity", "--histograms", "h.png"], r"--histograms draws the --paper experiment: add --paper"),
        (["bench", "--paper"], r"--paper is not used by bench lamp"),
        (["bench", "--from-json", str(H200), "--quick"], r"--quick is not used with --from-json"),
        (["bench", "porosity", "--from-json", str(H200), "--histograms", "h.png"], r"not a bench porosity result"),
    ],
)
def test_every_mistake_is_one_line_before_any_work(capsys, no_work, argv, match):
    """Bad values, unwritable or unreadable paths and flags a command does not use: exit 2, the usage and one
    error line, never a traceback, and nothing started."""
    assert re.search(match, fail(capsys, argv))


@pytest.mark.skipif(wp.get_cuda_device_count() > 0, reason="needs a machine without a CUDA GPU")
def test_cuda_device_without_a_gpu_says_so(capsys, no_work):
    """--device cuda:0 on a machine with no GPU says that in one line."""
    assert "this machine has no CUDA GPU that Warp can use" in fail(capsys, ["--device", "cuda:0"])


def test_a_missing_extra_is_reported_at_the_start_with_the_install_commands(capsys, no_work, monkeypatch):
    """Without matplotlib, --plot fails before measuring, naming the install command for a clone and a package."""
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "matplotlib" else real(name, *a))
    line = fail(capsys, ["bench", "--quick", "--plot", "speed.png"])
    assert "--plot needs matplotlib" in line and "pip install '.[plot]'" in line and "'warp-lamp[plot]'" in line


def test_library_errors_are_one_line_too(capsys):
    """A value the parser accepts but the library refuses (a grid far over its memory budget) is one line."""
    assert "--cells-per-diameter 1e+09: the grid's" in fail(capsys, ["--device", "cpu", "--cells-per-diameter", "1e9"])


def test_help_shows_plain_text_defaults_and_version(capsys):
    """The help has no raw markup and shows defaults; --version prints the package's version."""
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    out = capsys.readouterr().out
    assert "``" not in out and "(default: 4.0)" in out and "(default: 5)" in out
    with pytest.raises(SystemExit) as e:
        cli.main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"warp-lamp {warp_lamp.__version__}"


def test_run_reports_its_inputs_and_saves_json_and_vtk(capsys, tmp_path):
    """`warp-lamp --json --vtk` states P, cells per diameter and the grid, and writes a JSON report and VTK files
    whose forces balance and whose porosity lies in [0, 1] (the first-run note: tests/test_cli.py)."""
    pytest.importorskip("pyevtk")
    out = tmp_path / "run.json"
    vtk = tmp_path / "vtk"
    argv = ["--device", "cpu", "--pressure", "2e6", "--cells-per-diameter", "2", "--repeats", "1"]
    assert cli.main([*argv, "--json", str(out), "--vtk", str(vtk)]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    assert "P = 2e+06 Pa" in captured.out and "2 per mean particle diameter" in captured.out
    assert re.search(r"three grids of \d+ x \d+ cells", captured.out)
    report = json.loads(out.read_text())
    assert report["pressure_Pa"] == 2e6 and report["cells_per_diameter"] == 2.0
    assert report["force_sum_N"] == [0.0, 0.0, 0.0] and report["particles"] == 4628
    forces = read_vtk_array(vtk / "specimen_forces.vtu", "force", 3)
    assert forces.shape == (4628, 3) and np.all(forces.sum(axis=0) == 0.0) and np.abs(forces).max() > 0
    eps = read_vtk_array(vtk / "specimen_porosity.vti", "porosity", 1)
    assert eps.shape == (1000,) and 0.0 <= eps.min() < 0.6 and eps.max() == 1.0


def read_vtk_array(path: Path, name: str, components: int) -> np.ndarray:
    """One Float64 array of a pyevtk VTK XML file (raw appended data, UInt64 block headers)."""
    data = path.read_bytes()
    head, appended = data.split(b'<AppendedData encoding="raw">')
    offset = int(re.search(rf'Name="{name}"[^>]*offset="(\d+)"'.encode(), head).group(1))
    blob = appended[appended.index(b"_") + 1 :]
    size = int(np.frombuffer(blob[offset : offset + 8], dtype=np.uint64)[0])
    values = np.frombuffer(blob[offset + 8 : offset + 8 + size], dtype=np.float64)
    return values.reshape(-1, components) if components > 1 else values


def test_bench_table_columns_match_their_headers(capsys):
    """Every row of every table of the saved H200 result has as many cells as its header, missing values print
    as an en dash, and the speed table's last columns hold what their headings say."""
    assert cli.main(["bench", "--from-json", str(H200)]) == 0
    tables, header = 0, None
    for line in capsys.readouterr().out.splitlines():
        if not line.startswith("|"):
            header = None
            continue
        cells = [c.strip() for c in line.strip("|").split("|")]
        if header is None:
            header, tables = cells, tables + 1
        else:
            assert len(cells) == len(header), (header, cells)
            assert "-" not in cells
            row = dict(zip(header, cells, strict=True))
            if "lamp vs cast" in row and row["device"] == "cuda:0" and row["spheres"] == "1,000,000":
                assert row["replay ms"] == "0.325" and row["lamp vs cast"] == "16.3x" and row["NumPy ref s"] == "\u2013"
    assert tables >= 4


def test_saved_results_plot_from_json(tmp_path):
    """--from-json redraws both benchmark figures from the committed H200 results (needs matplotlib)."""
    pytest.importorskip("matplotlib")
    lamp, hist = tmp_path / "lamp.png", tmp_path / "hist.png"
    assert cli.main(["bench", "--from-json", str(H200), "--plot", str(lamp)]) == 0
    assert cli.main(["bench", "porosity", "--from-json", str(H200_POROSITY), "--histograms", str(hist)]) == 0
    assert lamp.stat().st_size > 10_000 and hist.stat().st_size > 10_000


H100 = ROOT / "bench" / "results" / "h100-2026-11-22.json"


@pytest.fixture(scope="module")
def ball_csv(tmp_path_factory):
    """A small body of 387 particles as a CSV in millimetres (the reader converts), and its particles in metres."""
    ball = scene_lattice_ball(diameter=0.05, particle_diameter=0.005)
    path = tmp_path_factory.mktemp("particles") / "ball.csv"
    rows = np.column_stack([np.arange(ball.n), ball.centers * 1e3, ball.radii * 1e3])
    np.savetxt(path, rows, delimiter=",", header="id,x [mm],y [mm],z [mm],radius [mm]", comments="", fmt="%.17g")
    return path, ball.centers, ball.radii


def read_vtk(path: Path, name: str):
    """One array of a pyevtk VTK XML file (raw appended data, UInt64 block headers), and its VTK type name."""
    data = path.read_bytes()
    head, appended = data.split(b'<AppendedData encoding="raw">')
    element = re.search(rf'<DataArray [^>]*Name="{name}"[^>]*>'.encode(), head).group(0).decode()
    attrs = dict(re.findall(r'(\w+)="([^"]*)"', element))
    vtype, comps, offset = attrs["type"], int(attrs["NumberOfComponents"]), int(attrs["offset"])
    blob = appended[appended.index(b"_") + 1 :]
    size = int(np.frombuffer(blob[offset : offset + 8], dtype=np.uint64)[0])
    dtype = {"Float64": np.float64, "Int32": np.int32, "Int64": np.int64}[vtype]
    values = np.frombuffer(blob[offset + 8 : offset + 8 + size], dtype=dtype)
    return (values.reshape(-1, comps) if comps > 1 else values), vtype


def test_flags_before_run_are_kept_and_a_clash_is_refused(capsys, tmp_path):
    """`warp-lamp --pressure 5e6 --cells-per-diameter 2 run --json x.json` runs at 5e6 Pa and 2 cells per
    diameter (run's defaults used to overwrite them); the same flag with two values is refused, and run options
    before bench are refused, each in one line."""
    out = tmp_path / "x.json"
    argv = ["--pressure", "5e6", "--cells-per-diameter", "2", "run", "--json", str(out), "--repeats", "1"]
    assert cli.main([*argv, "--device", "cpu"]) == 0
    report = json.loads(out.read_text())
    assert report["pressure_Pa"] == 5e6 and report["cells_per_diameter"] == 2.0
    assert "P = 5e+06 Pa" in capsys.readouterr().out
    line = fail(capsys, ["--pressure", "5e6", "run", "--pressure", "6e6"])
    assert "--pressure given twice, 5e+06 before run and 6e+06 after it" in line
    assert "--device before bench: it is an option of run" in fail(capsys, ["--device", "cpu", "bench"])


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--cells-per-diameter", "1e-9"], r"--cells-per-diameter 1e-09: cells of .* wider than the whole body"),
        (["--vtk", "/sys/warp-lamp-vtk"], r"--vtk /sys/warp-lamp-vtk: the folder /sys is not writable"),
        (["--resolver", "exact"], r"--resolver is used by --criterion area only"),
        (["--surfaces", "all"], r"--surfaces all needs --probe-radius"),
        (["--probe-radius", "0.001"], r"--probe-radius is used by --surfaces all only"),
        (["--stress", "1", "2", "3", "0", "0", "0", "--pressure", "5e6"], r"--pressure and --stress: give one"),
        (["--frames", "4", "--pressures", "1e6", "2e6", "3e6"], r"--frames averages an isotropic pressure only"),
        (["--pressures", "1e6", "2e6", "run"], r"argument --pressures: expected a number, got 'run'"),
        (["--lamps", "-x,+q"], r"argument --lamps: unknown lamp '\+q'"),
        (["--box", "0", "0", "0", "1", "-1", "1"], r"--box: X1 Y1 Z1 must exceed X0 Y0 Z0; axis y"),
        (["--timestep", "3"], r"--timestep reads --particles FILE"),
        (["--particles", "/no/such/file.csv"], r"--particles /no/such/file.csv: no such file"),
    ],
)
def test_run_mistakes_are_one_line_naming_the_flag_before_any_work(capsys, no_work, argv, match):
    """Values the run cannot use, writes that would fail, and flags that need others: exit 2, one line naming the
    flag, before the specimen is built."""
    if "/sys/" in argv[-1] and cli._can_write_in("/sys"):
        pytest.skip("/sys is writable here")
    assert re.search(match, fail(capsys, argv))


def test_json_dash_is_standard_output(capsys, tmp_path, monkeypatch):
    """`--json -` writes the JSON report to standard output (the text report goes to standard error), and no file
    named '-'; so does bench --from-json ... --json -."""
    monkeypatch.chdir(tmp_path)
    assert cli.main(["--device", "cpu", "--repeats", "1", "--cells-per-diameter", "2", "--json", "-"]) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    assert report["particles"] == 4628 and "balance" in captured.err
    assert cli.main(["bench", "--from-json", str(H100), "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(H100.read_text())
    assert not (tmp_path / "-").exists()


def test_saved_results_of_another_kind_are_refused_in_one_line(capsys, no_work, tmp_path):
    """bench --from-json on JSON that is no lamp result ({"foo": 1}, a porosity result), and bench porosity
    --from-json on a lamp result: one line saying what the file holds, never a traceback or silence."""
    foo = tmp_path / "foo.json"
    foo.write_text('{"foo": 1}')
    assert "not a bench lamp result; it holds the keys 'foo'" in fail(capsys, ["bench", "--from-json", str(foo)])
    line = fail(capsys, ["bench", "--from-json", str(H200_POROSITY)])
    assert "a bench porosity result: use bench porosity --from-json" in line
    line = fail(capsys, ["bench", "porosity", "--from-json", str(H100)])
    assert "not a bench porosity result; it holds a bench lamp result: use bench --from-json" in line
    assert "not a bench porosity result" in fail(capsys, ["bench", "porosity", "--from-json", str(foo)])


def test_bench_output_has_no_developer_words(capsys):
    """The tables of a saved lamp result and of a saved porosity result name no issue, no 'v4' and no
    'baseline'."""
    assert cli.main(["bench", "--from-json", str(H100)]) == 0
    assert cli.main(["bench", "porosity", "--from-json", str(H200_POROSITY)]) == 0
    out = capsys.readouterr().out
    assert "Small bodies" in out and "previous release" in out
    found = re.findall(r"(?i)\bissue\b[^|\n]*|\bv4\b|\bbaseline\b", out)
    assert not found, found


def test_first_run_note_only_when_it_is_true(capsys, monkeypatch):
    """The note that a first run builds and compiles is printed when the kernels are not in Warp's cache, and not
    on a run whose specimen and kernels are cached."""
    argv = ["--device", "cpu", "--repeats", "1", "--cells-per-diameter", "2"]
    assert cli.main(argv) == 0  # the first run in this process may build: it caches everything
    capsys.readouterr()
    assert cli.main(argv) == 0
    assert "first run" not in capsys.readouterr().err
    monkeypatch.setattr(cli, "_compiled", lambda device, modules: False, raising=False)
    assert cli.main(argv) == 0
    assert "this first run compiles the kernels for cpu" in capsys.readouterr().err


MODES = [
    ([], {}),
    (
        ["--criterion", "area", "--resolver", "exact", "--depth-slots", "4"],
        {"criterion": "area", "resolver": "exact", "depth_slots": 4},
    ),
    (["--criterion", "area", "--subpoints", "4"], {"criterion": "area", "subpoints": 4}),
    (["--surfaces", "all", "--probe-radius", "0.0025"], {"surfaces": "all", "probe_radius": 0.0025}),
    (["--lamps", "-x,+x,-y,+y,+z"], {"lamps": ("-x", "+x", "-y", "+y", "+z")}),
    (["--pressures", "1e6", "2e6", "3e6", "--criterion", "0"], {"criterion": 0}),
    (["--stress", "2e7", "1e7", "5e6", "2e6", "0", "0"], {}),
]


@pytest.mark.parametrize(
    ("flags", "options"), MODES, ids=["default", "area-exact", "area-sub", "wetted", "lamps", "per-axis", "stress"]
)
def test_every_mode_on_your_particles_matches_lamp_forces(capsys, tmp_path, ball_csv, flags, options, device):
    """`run --particles FILE` in each mode writes per-particle forces (VTK) bitwise equal to lamp_forces with the
    same options on the same grid, 'lit' as an integer array, and the inputs (pressure, criterion, cells per
    diameter) as field data and in the JSON."""
    pytest.importorskip("pyevtk")
    from warp_lamp.frames import lamp_stress_frame

    path, centers, radii = ball_csv
    out, vtk = tmp_path / "r.json", tmp_path / "vtk"
    argv = ["--particles", str(path), "--device", device, "--repeats", "1", "--json", str(out), "--vtk", str(vtk)]
    assert cli.main([*argv, *flags]) == 0
    text = capsys.readouterr().out
    assert "read 387 particles" in text and "converted to metres" in text
    pressure = 10e6
    rotation = None
    if "--stress" in flags:
        pressure = np.array([[2e7, 2e6, 0], [2e6, 1e7, 0], [0, 0, 5e6]])
        rotation = lamp_stress_frame(pressure)[0]
    elif "--pressures" in flags:
        pressure = np.array([1e6, 2e6, 3e6])
    grid = wl.LampGrid.enclosing(
        centers, radii, cells_per_diameter=4, rotation=rotation, probe_radius=options.get("probe_radius", 0.0)
    )
    expect = wl.lamp_forces(centers, radii, pressure, grid=grid, device=device, **options)
    forces, _ = read_vtk(vtk / "particles_forces.vtu", "force")
    np.testing.assert_array_equal(forces, expect)
    lit, lit_type = read_vtk(vtk / "particles_forces.vtu", "lit")
    assert lit_type == "Int32" and set(np.unique(lit)) <= {0, 1} and lit.sum() > 0
    head = (vtk / "particles_forces.vtu").read_bytes().split(b"<AppendedData")[0].decode()
    for name in ("pressure_Pa", "criterion", "cells_per_diameter"):
        assert f'Name="{name}"' in head.split("<FieldData>")[1].split("</FieldData>")[0], name
    report = json.loads(out.read_text())
    assert report["inputs"]["cells_per_diameter"] == 4.0 and report["inputs"]["criterion"] == options.get(
        "criterion", 1
    )
    assert report["porosity"]["method"] == "voxel" and 0.0 <= report["porosity"]["min"] <= 1.0
    if "--lamps" not in flags:
        assert report["force_sum_N"] == [0.0, 0.0, 0.0]


@pytest.mark.filterwarnings("error")
def test_frames_and_a_porosity_grid_on_your_particles(capsys, tmp_path, ball_csv, device):
    """--frames 4 averages (exact balance, directions nearer the radial than one frame), and --grid, --box,
    --method, --subdivisions give the porosity grid the report and the VTK file hold."""
    path = ball_csv[0]
    out = tmp_path / "r.json"
    argv = ["--particles", str(path), "--device", device, "--repeats", "1", "--json", str(out), "--frames", "4"]
    argv += ["--grid", "2", "2", "3", "--box", "-0.03", "-0.03", "-0.03", "0.03", "0.03", "0.06"]
    argv += ["--method", "midpoint", "--subdivisions", "48"]
    assert cli.main(argv) == 0
    report = json.loads(out.read_text())
    assert report["inputs"]["frames"] == 4 and report["force_sum_N"] == [0.0, 0.0, 0.0]
    p = report["porosity"]
    assert p["method"] == "midpoint" and p["shape"] == [2, 2, 3] and p["subdivisions"] == 48
    assert p["box_m"] == [[-0.03, -0.03, -0.03], [0.03, 0.03, 0.06]]
    _, centers, radii = ball_csv
    box = ([-0.03] * 3, [0.03, 0.03, 0.06])
    eps = wl.porosity(centers, radii, *box, (2, 2, 3), method="midpoint", subdivisions=48, device=device)
    assert [p["min"], p["mean"], p["max"]] == [eps.min(), eps.mean(), eps.max()]
    assert p["max"] == 1.0 and p["min"] < 0.9  # the top layer of cells is empty, the others hold the ball
    assert "averaged over 4 frames" in capsys.readouterr().out


def test_a_bad_particles_file_is_one_line_with_its_line_and_column(capsys, tmp_path):
    """A CSV with a word where a number goes: one line naming the file, the line and the column."""
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y,z,radius\n0,0,0,1\n1,two,0,1\n")
    line = fail(capsys, ["--particles", str(bad), "--device", "cpu"])
    assert re.search(r"--particles .*bad\.csv, line 3, column 2: not a number: 'two'", line)


def test_a_wall_with_every_particle_behind_it_warns_on_the_command_line(ball_csv):
    """--wall whose normal points out of the fluid (every particle behind it): a warning naming the wall."""
    path, centers, radii = ball_csv
    z0 = float((centers[:, 2] - radii).min()) * 1e3
    argv = ["--particles", str(path), "--device", "cpu", "--wall", "0", "0", str(z0), "0", "0", "-1"]
    with pytest.warns(UserWarning, match=r"walls: every particle lies behind wall\(s\) \[0\]"):
        assert cli.main(argv) == 0


def test_walls_and_tolerance_on_the_command_line(capsys, tmp_path, ball_csv, device):
    """--wall bounds the fluid (body plus wall take P times the top window on z, the wall's force is reported, the
    forces equal lamp_forces with the same wall); --tolerance prints its choice and runs it; either beside the
    settings it chooses is refused."""
    path, centers, radii = ball_csv
    z0 = float((centers[:, 2] - radii).min())
    out = tmp_path / "w.json"
    argv = ["--particles", str(path), "--device", device, "--repeats", "1", "--json", str(out)]
    assert cli.main([*argv, "--wall", "0", "0", str(z0 * 1e3), "0", "0", "1"]) == 0
    report = json.loads(out.read_text())
    grid = wl.LampGrid.enclosing(centers, radii, cells_per_diameter=4)
    wall = [((0.0, 0.0, z0), (0.0, 0.0, 1.0))]
    expect = wl.lamp_forces(centers, radii, 10e6, grid=grid, walls=wall, device=device)
    np.testing.assert_allclose(report["force_sum_N"], expect.sum(axis=0), rtol=0, atol=0)
    window = 10e6 * grid.cell_area[2] * grid.counts[2].prod()
    total = report["force_sum_N"][2] + report["wall_forces_N"][0][2]
    assert total == pytest.approx(-window, rel=1e-7)
    assert report["inputs"]["walls"] == [{"point": [0.0, 0.0, z0 * 1e3], "normal": [0.0, 0.0, 1.0]}]
    capsys.readouterr()
    assert cli.main([*argv, "--tolerance", "0.05"]) == 0
    text = capsys.readouterr().out
    assert "choice     tolerance 0.05:" in text
    report = json.loads(out.read_text())
    from warp_lamp.tolerance import choose_settings

    choice = choose_settings(0.05, device)
    assert report["inputs"]["tolerance"] == 0.05 and report["cells_per_diameter"] == choice.cells_per_diameter
    line = fail(capsys, [*argv, "--tolerance", "0.05", "--criterion", "area"])
    assert "--tolerance chooses --criterion itself" in line


def run_cli(*args, device="cpu") -> dict:
    proc = subprocess.run(
        [sys.executable, "-m", "warp_lamp", *args, "--device", device, "--repeats", "1"],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = {}
    for line in proc.stdout.splitlines():
        key, _, rest = line.partition(" ")
        lines[key] = rest.strip()
    return lines


def numbers(text: str) -> list[float]:
    """The numbers in a report line, thousands separators read as such."""
    return [float(x) for x in re.findall(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?", text.replace(",", ""))]


def after_equals(text: str) -> float:
    return numbers(text.split("=", 1)[1])[0]


@pytest.mark.parametrize(
    ("args", "criterion", "cells_per_diameter", "pressure"),
    [
        ((), 1, 4.0, 10e6),
        (("run", "--criterion", "0", "--cells-per-diameter", "2.5", "--pressure", "2.5e6"), 0, 2.5, 2.5e6),
    ],
)
def test_run_report_matches_independent_values(device, args, criterion, cells_per_diameter, pressure):
    """Scene, grid, lit particles and cells per lamp (float64 reference, within its few ambiguous cells), exact
    balance, moment, force magnitudes and the envelope stress (by hand from lamp_forces) are what the report
    prints, to its printed precision."""
    out = run_cli(*args, device=device)
    scene = scene_sphere_specimen()
    grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cells_per_diameter)
    assert numbers(out["scene"].split(":")[1])[:2] == [scene.n, 100.0]
    assert f"cells of {grid.cell[0, 0] * 1e3:.3f} mm" in out["grid"]
    assert f"{grid.n_cells:,} cells" in out["grid"]
    assert f"criterion {criterion}" in out["pressure"]
    assert after_equals(out["pressure"]) == pressure

    ref = lamp_reference(scene.centers, scene.radii, grid, criterion=criterion)
    ambiguous = {name: int(a.sum()) for name, a in ref.ambiguous.items()}
    lit_particles = np.unique(np.concatenate([o[o >= 0] for o in ref.owners.values()]))
    surface = numbers(out["surface"].split("particles")[0])[0]
    assert abs(surface - len(lit_particles)) <= sum(ambiguous.values())
    printed_lit = dict(re.findall(r"'([-+][xyz])': (\d+)", out["surface"]))
    for name in wl.LAMPS:
        assert abs(int(printed_lit[name]) - int((ref.owners[name] >= 0).sum())) <= ambiguous[name], name

    f = wl.lamp_forces(scene.centers, scene.radii, pressure, grid=grid, criterion=criterion, device=device)
    assert numbers(out["balance"]) == [0.0, 0.0, 0.0]
    arm = scene.centers - scene.center
    moment = np.linalg.norm(np.cross(arm, f).sum(axis=0)) / (pressure * np.pi * scene.radius**3)
    assert after_equals(out["moment"]) == pytest.approx(moment, rel=1e-3)
    mag = np.linalg.norm(f, axis=1)
    printed = numbers(out["forces"])
    lit = mag[lit_particles]  # a lit particle with balanced loads shows 0 here, and counts in the minimum
    assert printed == pytest.approx([lit.min(), lit.mean(), mag.max(), mag.sum()], rel=1e-3)
    volume = 4.0 / 3.0 * np.pi * scene.radius**3
    mean_pressure = -np.einsum("ni,ni->", arm, f) / (3.0 * volume * pressure)
    assert after_equals(out["stress"]) == pytest.approx(mean_pressure, abs=1e-4)
    assert 0.8 < mean_pressure < 1.0
    assert numbers(out["skipped"]) == [0, 0]


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
    info = check(read_particles(write_vtk(tmp_path / f"p{ext}", **options)))
    assert f"{options.get('kind', 'UnstructuredGrid')}, 1 piece, point array " in info.columns


def test_vtk_written_by_pyevtk_reads_back(tmp_path):
    """What warp_lamp's own VTK export (pyevtk: raw appended, UInt64 headers) writes reads back bitwise, with the
    whole-file values (field data) in the file."""
    pytest.importorskip("pyevtk")
    from warp_lamp.export import write_vtk_particles

    path = write_vtk_particles(tmp_path / "p", CENTERS, RADII, force=np.ones((9, 3)), field_data={"pressure": 2.5e6})
    check(read_particles(path), ids=False, rtol=0)
    head = open(path, "rb").read().split(b"<AppendedData")[0]
    assert b"<FieldData>" in head and b'Name="pressure"' in head  # the run's inputs travel with the particles


def test_vtk_without_a_radius_array_or_broken(tmp_path):
    """No radius or diameter array, and malformed XML: one line with the file and the line."""
    path = write_vtk(tmp_path / "p.vtu", mode="ascii", name="velocity")
    with pytest.raises(ParticleFileError, match=r"p\.vtu, line \d+: no radius or diameter point array"):
        read_particles(path)
    text = path.read_text().replace("</Points>", "", 1)
    with pytest.raises(ParticleFileError, match=r"p\.vtu, line \d+, column \d+: not well-formed XML"):
        read_particles(write(tmp_path / "p.vtu", text))


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


def test_yade_text_with_one_particle(tmp_path):
    """A text export holding a single particle, with or without a #format line, reads as that one particle."""
    for name, head in (("one.txt", ""), ("onef.txt", "#format x_y_z_r\n")):
        c, r, ids, _ = read_particles(write(tmp_path / name, head + "0.5 1.5 -2 0.25\n"))
        np.testing.assert_array_equal(c, [[0.5, 1.5, -2.0]])
        np.testing.assert_array_equal(r, [0.25])
        assert ids is None


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


def _cube_csv(path: Path, radius: float, scale: float = 1.0) -> Path:
    """An 8 x 8 x 8 simple-cubic block of touching spheres (spacing 2 r), as a CSV with a header."""
    g = np.stack(np.meshgrid(*[np.arange(8) * 2e-3 * scale] * 3, indexing="ij"), -1).reshape(-1, 3)
    np.savetxt(path, np.c_[g, np.full(len(g), radius)], delimiter=",", header="x,y,z,radius", comments="")
    return path


def test_a_misspelt_flag_is_named_with_the_nearest_flag(capsys, no_work):
    """A typo in a flag followed by a value (`--presure 1e6`) is refused by the flag's name, with the nearest one;
    argparse alone took the value for the command and blamed it (the newcomer trial of issues 19-26)."""
    assert "unrecognized flag --presure (did you mean --pressure?)" in fail(capsys, ["--presure", "1e6"])
    line = fail(capsys, ["--cels-per-diameter", "8"])
    assert "unrecognized flag --cels-per-diameter (did you mean --cells-per-diameter?)" in line


def test_negative_numbers_in_exponent_notation_are_values(capsys, tmp_path):
    """`--wall 0 0 -1e-3 0 0 1` reads six numbers (argparse took -1e-3 for a flag and found five)."""
    path = _cube_csv(tmp_path / "cube.csv", 1e-3)
    out = tmp_path / "r.json"
    argv = ["--particles", str(path), "--wall", "0", "0", "-1e-3", "0", "0", "1", "--json", str(out)]
    assert cli.main([*argv, "--device", "cpu", "--repeats", "1"]) == 0
    assert "wall 0" in capsys.readouterr().out


def test_frames_with_walls_and_subdivisions_with_a_sum_method_are_refused(capsys, no_work, tmp_path):
    """--frames with --wall (every turned frame's axes cut the wall: nothing balanced, no wall force reported) and
    --subdivisions with a method that does not subdivide are refused in one line, naming the flags."""
    path = _cube_csv(tmp_path / "cube.csv", 1e-3)
    line = fail(capsys, ["--particles", str(path), "--frames", "4", "--wall", "0", "0", "-0.001", "0", "0", "1"])
    assert "--frames and --wall" in line
    line = fail(capsys, ["--particles", str(path), "--grid", "2", "2", "2", "--method", "exact", "--subdivisions", "8"])
    assert "--subdivisions: --method exact does not use it" in line


def test_radii_in_other_units_than_the_centres_are_named(capsys, tmp_path):
    """Radii in millimetres with centres in metres (every sphere 140 times wider than the cloud of centres) are
    named on the report's units line; the library warns, naming radii (it used to load 8 particles at 1e7 N)."""
    path = _cube_csv(tmp_path / "mixed.csv", 1.0)
    assert cli.main(["--particles", str(path), "--device", "cpu", "--repeats", "1"]) == 0
    out = capsys.readouterr()
    assert "units: radii: the mean diameter 2 is 143 times the spread of the centres" in out.out
    assert "UserWarning" not in out.err
    c, r, _, _ = read_particles(path)
    with pytest.warns(UserWarning, match="radii: the mean diameter"):
        wl.lamp_forces(c, r, 1e6, device="cpu")
    with pytest.warns(UserWarning, match="radii: the mean diameter"):
        wl.porosity(c, r, c.min(0) - 1, c.max(0) + 1, (2, 2, 2), method="exact", device="cpu")


def test_the_grid_and_the_loads_do_not_depend_on_the_length_unit(tmp_path):
    """The same block in metres and in millimetres lights the same cells: an extent a hair under a whole number of
    cells (39.999... in metres, 40 in millimetres) used to leave the extreme spheres on the cell edges (768 against
    704 cells lit per lamp)."""
    c_m, r_m, _, _ = read_particles(_cube_csv(tmp_path / "m.csv", 1e-3))
    lit = []
    for scale in (1.0, 1e3, 0.1, 7.0):
        f = wl.lamp_forces(c_m * scale, r_m * scale, 1.0, device="cpu")
        grid = wl.LampGrid.enclosing(c_m * scale, r_m * scale)
        lit.append((tuple(grid.box_counts.tolist()), np.round(np.abs(f).sum(axis=0) / grid.box_cell[0] ** 2).tolist()))
    assert all(x == lit[0] for x in lit), lit
