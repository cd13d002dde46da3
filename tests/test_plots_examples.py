"""The pictures say what they show (errors in one unit, labels apart, typeset symbols, a legend, the scene's units)
and the examples behave on a first run (a missing extra, a written file, CPU-sized defaults, one experiment)."""

import importlib.util
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import load_example

ROOT = Path(__file__).resolve().parents[1]
H100 = ROOT / "bench" / "results" / "h100-2026-11-22.json"
TRIAXIAL = ROOT / "bench" / "results" / "h100-2026-11-22-triaxial.json"


@pytest.fixture
def plt():
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot

    yield pyplot
    pyplot.close("all")


def texts(fig) -> list[str]:
    """Every string drawn on a figure: titles, axis labels, legends, annotations, figure texts."""
    out = [t.get_text() for t in fig.texts]
    if fig._suptitle is not None:
        out.append(fig._suptitle.get_text())
    for ax in fig.axes:
        out += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel()] + [t.get_text() for t in ax.texts]
        legend = ax.get_legend()
        if legend is not None:
            out += [t.get_text() for t in legend.get_texts()]
    for legend in fig.legends:
        out += [t.get_text() for t in legend.get_texts()]
    return [t for t in out if t]


def test_bench_plot_errors_in_percent_and_point_labels_apart(plt, tmp_path):
    """Every panel's error axis is in per cent (the lone-sphere panels were a fraction beside a panel in %), and
    no two point labels ("d/3", "d/4", ...) overlap."""
    from warp_lamp.bench import plot

    plot(json.loads(H100.read_text()), str(tmp_path / "b.png"))
    fig = plt.gcf()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        assert "%" in ax.get_xlabel(), ax.get_xlabel()
        boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in ax.texts if t.get_text().startswith("d/")]
        assert boxes
        for i, (a, box_a) in enumerate(boxes):
            for b, box_b in boxes[i + 1 :]:
                assert not box_a.overlaps(box_b), (ax.get_title(), a, b)


def test_triaxial_plot_typesets_its_symbols_names_dilation_and_says_it_wrote(plt, tmp_path, capsys):
    """`triaxial.py --plot` (redrawn here from the saved H100 run) prints that it wrote the file; its labels are
    typeset (sigma_3 as $\\sigma_3$, eps_a as $\\varepsilon_a$), and the negative volumetric strain is called
    dilation."""
    triaxial = load_example("triaxial")
    out = tmp_path / "t.png"
    triaxial.main(["--from-json", str(TRIAXIAL), "--plot", str(out)])
    assert f"wrote {out}" in capsys.readouterr().out and out.stat().st_size > 10_000
    saved = json.loads(TRIAXIAL.read_text())
    words = texts(triaxial.plot_history(saved["summary"], saved, str(out)))
    joined = " ".join(words)
    assert r"$\sigma_3$" in joined and r"$\varepsilon_a$" in joined and r"\sigma_\mathrm{lat}" in joined
    assert not re.search(r"(?<!\\)\b(sigma_|eps_|phi_|szz\b)", joined), joined  # plain-text names, untypeset
    assert any("dilation" in w for w in words)


def test_owner_map_has_a_legend_and_without_matplotlib_names_the_install(plt, tmp_path, monkeypatch, capsys):
    """owner_map.py puts its colours in a legend, not in the title; without matplotlib it stops with the pip
    command instead of a ModuleNotFoundError."""
    owner_map = load_example("owner_map")
    fig = owner_map.main(["--ratios", "2", "--out", str(tmp_path / "o.png"), "--device", "cpu"])
    assert [len(legend.get_texts()) for legend in fig.legends] == [3]
    assert "(red)" not in fig._suptitle.get_text()
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(SystemExit) as e:
        owner_map.main(["--out", str(tmp_path / "x.png")])
    assert "pip install '.[plot]'" in str(e.value) and "warp-lamp[plot]" in str(e.value)


def test_wetted_slice_labels_the_scene_units(plt):
    """The wetted-slice picture of a unitless lattice block labels its lengths in lattice spacings, never metres."""
    folder = ROOT / "bench" / "experiments"
    monkey_path = [str(folder), *sys.path]
    sys_path, sys.path[:] = list(sys.path), monkey_path
    try:
        spec = importlib.util.spec_from_file_location("wetted_slice", folder / "wetted_slice.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path[:] = sys_path
    from warp_lamp.scenes import scene_slot_block

    fig = module.figure(scene_slot_block((10, 10, 8), width=4, depth=3), 2.0, window=None)
    words = texts(fig)
    assert all("lattice spacings" in ax.get_xlabel() for ax in fig.axes)
    assert not any(re.search(r"\[m\]|\d m\b", w) for w in words), words


def test_sphere_test_picks_cpu_sized_defaults_and_says_so(monkeypatch, capsys):
    """examples/sphere_test.py with no arguments on a CPU runs the CI's size (2 cells per diameter, 2,500 cycles)
    and says why, instead of four resolutions of 40,000 cycles; given sizes are kept."""
    sphere_test = load_example("sphere_test")
    runs = []

    class Stub:
        def __init__(self, k, **kwargs):
            self.k, self.device = k, sphere_test.wp.get_device(kwargs.get("device"))

        def run(self, steps, **kwargs):
            runs.append((self.k, steps))
            return {"cycles": 0, "ratio": 0.0, "seconds": 0.0}

        def measure(self):
            return np.eye(3)

    monkeypatch.setattr(sphere_test, "SphereTest", Stub)
    sphere_test.main(["--device", "cpu"])
    assert runs == [(2.0, 2500)]
    assert "the full study" in capsys.readouterr().err
    runs.clear()
    sphere_test.main(["--device", "cpu", "--cells", "4", "--steps", "300"])
    assert runs == [(4.0, 300)]


def test_frames_block_example_is_the_benchmarks_experiment(capsys):
    """examples/frames_block.py (the README's picture) prints the benchmark's turned-block rows: the same mean
    and p90 angles as the saved result's frames section at 4 cells per diameter, one experiment with one number."""
    frames_block = load_example("frames_block")
    results = frames_block.main(["--device", "cpu"])
    saved = {
        r["lamp"]: r
        for r in json.loads(H100.read_text())["frames"]
        if r["body"] == "block rotated" and r["cells_per_diameter"] == 4.0 and r["device"] == "cpu"
    }
    for name, lamp in (("axis-aligned lamp", "axis-aligned"), ("lamp turned with the block", "rotated with the body")):
        assert results[name]["mean_deg"] == pytest.approx(saved[lamp]["mean_deg"], rel=1e-9)
        assert results[name]["p90_deg"] == pytest.approx(saved[lamp]["p90_deg"], rel=1e-9)
    assert "mean  1.89 deg, p90  7.13 deg" in capsys.readouterr().out
