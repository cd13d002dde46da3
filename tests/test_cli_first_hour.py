"""The command line's first hour: flags before the sub-command kept, one-line errors naming the flag, ``--json -``,
writability checked first, saved results of the wrong kind refused, no developer words, the first-run note only
when true, and the user's own particles in every mode, with the inputs written beside the outputs."""

import json
import re
from pathlib import Path

import numpy as np
import pytest

import warp_lamp as wl
from warp_lamp import cli
from warp_lamp.scenes import scene_lattice_ball

ROOT = Path(__file__).resolve().parents[1]
H100 = ROOT / "bench" / "results" / "h100-2026-11-22.json"
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
    import warp_lamp.bench_porosity
    import warp_lamp.scenes

    monkeypatch.setattr(warp_lamp.scenes, "scene_sphere_specimen", refuse)
    monkeypatch.setattr(warp_lamp.bench, "bench_lamp", refuse)
    monkeypatch.setattr(warp_lamp.bench_porosity, "bench_porosity", refuse)


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
