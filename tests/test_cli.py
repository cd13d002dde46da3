"""The warp-lamp command line: one-line errors before any work, a full report, saved results and VTK files."""

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pytest
import warp as wp

import warp_lamp
from warp_lamp import cli

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
    import warp_lamp.bench_porosity
    import warp_lamp.scenes

    monkeypatch.setattr(warp_lamp.scenes, "scene_sphere_specimen", refuse)
    monkeypatch.setattr(warp_lamp.bench, "bench_lamp", refuse)
    monkeypatch.setattr(warp_lamp.bench_porosity, "bench_porosity", refuse)


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
    whose forces balance and whose porosity lies in [0, 1] (the first-run note: tests/test_cli_first_hour.py)."""
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
