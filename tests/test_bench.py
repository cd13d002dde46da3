"""The benchmark CLI runs its quick subset and reports what it measured.

The benchmark's mode sections (small bodies, area criterion, wetted surface, lamp frames) on tiny inputs, and one
end-to-end quick run.

`bench porosity --paper` says how long it takes before it starts, and its progress bar covers all of it."""

import json
from typing import ClassVar

import numpy as np
import pytest
import warp as wp

import warp_lamp as wl
from warp_lamp import cli
from warp_lamp.bench import modes as bm
from warp_lamp.bench import porosity as bp
from warp_lamp.reference import visible_area_reference
from warp_lamp.scenes import (
    Scene,
    scene_lattice_ball,
    scene_lattice_box,
    scene_overlapping_polydisperse,
    scene_slot_block,
)


def test_bench_quick_runs_and_writes_json(tmp_path, capsys):
    """`warp-lamp bench --quick --repeats 1 --json` (the CLI's main, in this process) runs on the CPU, prints the
    tables and writes consistent JSON: the lone-sphere error falls with resolution, the forces balance exactly and
    the specimen's mean pressure is under P (the loads act at the particles' centres)."""
    out = tmp_path / "bench.json"
    argv = ["bench", "--quick", "--device", "cpu", "--json", str(out), "--no-progress", "--repeats", "1"]
    assert cli.main(argv) == 0
    stdout = capsys.readouterr().out
    assert "atomic_min" in stdout and "E_area" in stdout
    result = json.loads(out.read_text())
    assert result["devices"]["cpu"]["copy_GBps"] > 0
    speed = result["speed"][0]
    assert speed["n"] > 1000 and speed["eager_s"] > 0 and speed["bvh_cast_s"] > 0 and speed["reference_s"] > 0
    errors = {(e["criterion"], e["cells_per_diameter"]): e for e in result["errors"]}
    assert errors[(1, 16)]["E_area"] < errors[(1, 4)]["E_area"] < errors[(1, 2)]["E_area"]
    assert all(e["force_sum"] == [0.0, 0.0, 0.0] for e in result["errors"])
    assert 0.7 < errors[(1, 4)]["mean_pressure_over_P"] < 1.0


@pytest.fixture(scope="module")
def ball():
    """A 30 mm lattice ball of 5 mm particles (75 spheres): a small body that builds in milliseconds."""
    return scene_lattice_ball(0.03, 0.005)


def two_spheres():
    """Two spheres on one x line, r = 0.5 and 0.45, 2.6 apart: from -x the big one hides the small one, from +x the
    small one leaves an annulus of the big one visible; from y and z both are seen whole."""
    c = np.array([[0.013, 0.021, -0.007], [2.613, 0.021, -0.007]])
    return Scene("two spheres", c, np.array([0.5, 0.45]), c.mean(axis=0))


def test_time_update_leaves_the_lamp_at_the_scene(device, ball):
    """time_update reports eager, replay (CUDA only) and moving times, update_s is the replay on CUDA and the eager
    update on the CPU, and the lamp ends updated at the scene's own positions (not the moved ones)."""
    grid = wl.LampGrid.enclosing(ball.centers, ball.radii, cells_per_diameter=4)
    lamp = wl.ShiningLamp(grid, device=device)
    t = bm.time_update(lamp, ball, device, repeats=2)
    assert t["eager_s"] > 0 and t["moving_s"] > 0
    if wp.get_device(device).is_cuda:
        assert t["replay_s"] > 0 and t["update_s"] == t["replay_s"]
    else:
        assert t["replay_s"] is None and t["update_s"] == t["eager_s"]
    fresh = wl.lamp_update(ball.centers, ball.radii, grid=grid, device=device)
    np.testing.assert_array_equal(lamp.counts_numpy(), fresh.counts_numpy())
    assert bm.time_update(lamp, ball, device, repeats=1, moving=False)["moving_s"] is None


def test_small_body_section_times_both_paths_with_equal_counts(device, ball):
    """Each row times the default lamp and the v4 baseline (split 0, no order) on the same grid, their counts are
    bitwise equal, and the speed-up is v4's time over the default's; lattice rows take a cell or 'd/k'."""
    rows = bm.section_small_body(
        device, repeats=2, specimen=ball, cells_per_diameter=(2, 4), large=((5, 0.25), (5, "d/4"))
    )
    assert [r["grid"] for r in rows] == ["d/2", "d/4", "cell 0.25", "d/4"]
    assert [r["n"] for r in rows] == [ball.n, ball.n, 125, 125]
    for r in rows:
        assert r["same_counts"] and r["device"] == wp.get_device(device).alias
        assert r["v4"]["split"] == 0 and r["v4"]["order"] is False
        assert r["speedup"]["eager"] == pytest.approx(r["v4"]["eager_s"] / r["default"]["eager_s"])
    d = 2 * float(scene_lattice_box(5).radii.mean())
    assert rows[2]["cells_per_diameter"] == pytest.approx(d / 0.25) and rows[3]["cells_per_diameter"] == 4.0
    with pytest.raises(ValueError, match=r"large: a grid is a cell size or 'd/k'"):
        bm.section_small_body(device, repeats=1, specimen=ball, cells_per_diameter=(), large=((3, "h/4"),))


def test_area_section_on_two_spheres_hand_areas(device):
    """The exact reference gives the hand areas (pi r^2 whole, an annulus pi (r1^2 - r2^2), zero hidden); the
    exact resolver gets within 1e-3 P pi rbar^2 of them where criterion 1 is off by more than 1e-2; every row
    balances, and criterion 1 at 4 cells per diameter is the ratio's unit."""
    s = two_spheres()
    areas, _ = bm.exact_areas(s)
    whole = np.pi * s.radii**2
    annulus = np.pi * (0.5**2 - 0.45**2)
    np.testing.assert_allclose(areas[0], [whole[0], annulus, *[whole[0]] * 4], rtol=1e-12)
    np.testing.assert_allclose(areas[1], [0.0, *[whole[1]] * 5], rtol=1e-12)
    out = bm.section_area(
        device, repeats=1, specimen=s, criterion1_cpd=(2, 4), area_cpd=(2, 3), estimators=(("exact", 3),)
    )
    rows = {(r["criterion"], r["cells_per_diameter"]): r for r in out["rows"]}
    assert rows[(1, 4.0)]["ratio"] == 1.0
    assert all(r["balanced"] and r["surface"] == 2 for r in out["rows"])
    assert min(rows[(1, 2.0)]["rms"], rows[(1, 4.0)]["rms"]) > 1e-2
    assert rows[("area", 2.0)]["rms"] < 1e-3 and rows[("area", 3.0)]["rms"] < 1e-3


def test_area_section_beats_refinement_and_caches_the_reference(device, ball):
    """On a small ball the sub-point resolver at 3 cells per diameter beats criterion 1 at 8; criterion 1's error
    falls with refinement; the exact reference is computed once per scene; the lattice rows compare the area
    criterion's defaults with criterion 1 at cell 0.25."""
    first, _ = bm.exact_areas(ball)
    out = bm.section_area(
        device,
        repeats=1,
        specimen=ball,
        criterion1_cpd=(2, 4, 8),
        area_cpd=(3,),
        estimators=(("subpoints", 3),),
        large=(4,),
    )
    assert bm.exact_areas(ball)[0] is first
    np.testing.assert_array_equal(first, visible_area_reference(ball.centers, ball.radii))
    c1 = [r["rms"] for r in out["rows"] if r["criterion"] == 1]
    assert c1 == sorted(c1, reverse=True)
    area = next(r for r in out["rows"] if r["criterion"] == "area")
    assert area["rms"] < c1[-1] and area["resolver"] == "subpoints" and area["subpoints"] == 8
    big = out["large"]
    assert [(r["criterion"], r["cell"]) for r in big[:2]] == [(1, 0.25), ("area", 0.25)]
    assert big[0]["ratio"] == 1.0 and big[2]["cells_per_diameter"] == pytest.approx(3.0)


def test_wetted_section_slot_walls_and_floor(device, ball):
    """On a small slot block the wetted surface (rho = one mean radius) loads both walls and the floor (>= 0.8 of
    the fluid's load) where the first-surface lamp loads the walls with nothing; every row balances exactly."""
    slot = scene_slot_block((10, 12, 8), width=4, depth=3)
    rows = bm.section_wetted(device, repeats=1, specimen=ball, slot=slot)
    assert [(r["n"], r["surfaces"]) for r in rows] == [
        (ball.n, "first"),
        (ball.n, "all"),
        (slot.n, "first"),
        (slot.n, "all"),
    ]
    assert all(r["balanced"] and r["loaded"] > 0 for r in rows)
    assert "ratios" not in rows[0] and rows[1]["rho"] == pytest.approx(float(ball.radii.mean()))
    first, wet = rows[2]["ratios"], rows[3]["ratios"]
    assert abs(first["wall_lo"]) < 0.05 and abs(first["wall_hi"]) < 0.05
    assert min(wet["wall_lo"], wet["wall_hi"], wet["floor"]) >= 0.8
    assert wet["floor"] > first["floor"] + 0.1
    assert rows[3]["rounds"] >= 1 and rows[3]["nonconverged"] is False


def test_frames_section_rotated_lamp_recovers_the_aligned_block(device, ball):
    """The rotated block under a lamp rotated with it has the aligned block's direction error (to float32
    rounding), under an axis-aligned lamp a larger one; averaging two frames lowers the ball's error; all rows
    balance exactly."""
    rows = bm.section_frames(device, repeats=1, block_size=6, ball=ball, cells_per_diameter=(4,), frames=(1, 2))
    assert [(r["body"], r["lamp"], r["frames"]) for r in rows] == [
        ("block aligned", "axis-aligned", 1),
        ("block rotated", "axis-aligned", 1),
        ("block rotated", "rotated with the body", 1),
        ("ball", "axis-aligned", 1),
        ("ball", "axis-aligned", 2),
    ]
    aligned, turned, with_lamp, ball1, ball2 = rows
    assert aligned["particles"] == 24 and aligned["loaded"] == 24
    assert with_lamp["mean_deg"] == pytest.approx(aligned["mean_deg"], abs=1e-4)
    assert turned["mean_deg"] > aligned["mean_deg"] + 1.0
    assert ball2["mean_deg"] < ball1["mean_deg"]
    assert all(r["balanced"] and r["update_s"] > 0 for r in rows)


@pytest.fixture(scope="module")
def tiny_result(ball):
    """The four sections on tiny inputs, on the CPU."""
    slot = scene_slot_block((8, 10, 6), width=2, depth=2)
    return {
        "small_body": bm.section_small_body("cpu", repeats=1, specimen=ball, cells_per_diameter=(2,)),
        "area": [
            bm.section_area(
                "cpu",
                repeats=1,
                specimen=ball,
                criterion1_cpd=(2, 4),
                area_cpd=(2,),
                estimators=(("exact", 3),),
                overlap=scene_overlapping_polydisperse(80),
                overlap_cpd=(4,),
                lone_samples=2,
            )
        ],
        "wetted": bm.section_wetted("cpu", repeats=1, specimen=ball, slot=slot),
        "frames": bm.section_frames("cpu", repeats=1, block_size=5, ball=ball, cells_per_diameter=(4,), frames=(1,)),
    }


def test_tables_json_and_plot(tiny_result, tmp_path):
    """The rows are strict JSON (no NaN, no numpy types), format_modes prints a table per section with a line per
    row (nothing for a result without them), and plot_area draws the area curves."""
    text = json.dumps(tiny_result, allow_nan=False)
    assert json.loads(text) == tiny_result
    tables = bm.format_modes(tiny_result)
    for head in ("Small bodies:", "Area criterion on", "Wetted surface:", "Lamp frames:"):
        assert head in tables
    area = tiny_result["area"][0]
    rows = sum(len(v) for k, v in tiny_result.items() if k != "area")
    assert tables.count("| cpu |") == rows + len(area["rows"]) + len(area["overlap"]) + len(area["lone"])
    assert len(area["overlap"]) == 1 and len(area["lone"]) == 2
    assert bm.format_modes({}) == ""
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    bm.plot_area(ax, tiny_result)
    assert len(ax.get_lines()) == 2  # criterion 1 and the exact resolver
    fig.savefig(tmp_path / "area.png")
    plt.close(fig)
    assert (tmp_path / "area.png").stat().st_size > 0


def test_bench_modes_quick_end_to_end():
    """bench_modes(quick) on the CPU, one repeat (no time is checked): every section, strict JSON, and the figures
    the issues stand on: the slot's walls and floor >= 0.9 with rho = one mean radius (issue 10), sub-points D = 3
    at 3 cells per diameter under 1% where criterion 1 at 4 is over 5% (issue 15), the rotated block's error at
    least doubled under an axis-aligned lamp and restored with a rotated one (issue 12), equal counts on both depth
    paths (issue 11)."""
    result = bm.bench_modes(["cpu"], quick=True, progress=False, repeats=1)
    assert json.loads(json.dumps(result, allow_nan=False)) == result
    assert [len(result[k]) for k in ("small_body", "area", "wetted", "frames")] == [4, 1, 4, 14]
    assert all(r["same_counts"] for r in result["small_body"])
    area = {
        (r["criterion"], r["resolver"], r["depth_slots"], r["cells_per_diameter"]): r for r in result["area"][0]["rows"]
    }
    assert len(area) == 4 + 12 and area[(1, None, 1, 4.0)]["ratio"] == 1.0
    assert area[("area", "subpoints", 3, 3.0)]["rms"] < 0.01 < 0.05 < area[(1, None, 1, 4.0)]["rms"]
    slot = next(r for r in result["wetted"] if r["surfaces"] == "all" and "ratios" in r)["ratios"]
    assert min(slot["wall_lo"], slot["wall_hi"], slot["floor"]) >= 0.9
    frames = {(r["body"], r["lamp"], r["frames"], r["cells_per_diameter"]): r for r in result["frames"]}
    aligned = frames[("block aligned", "axis-aligned", 1, 4.0)]["mean_deg"]
    assert frames[("block rotated", "axis-aligned", 1, 4.0)]["mean_deg"] > 2 * aligned
    assert frames[("block rotated", "rotated with the body", 1, 4.0)]["mean_deg"] == pytest.approx(aligned, abs=1e-3)


class Recorder:
    """A Progress stand-in that records its total, each step and its close, in order, in ``Recorder.events``."""

    events: ClassVar[list] = []

    def __init__(self, total, desc, *, enabled=True):
        Recorder.events.append(("open", total))

    def step(self, what):
        Recorder.events.append(("step", what))

    def close(self):
        Recorder.events.append(("close", None))


@pytest.fixture
def small(monkeypatch):
    """The benchmark on a few spheres: the same code path, seconds instead of minutes."""
    rng = np.random.default_rng(0)

    def scene(radius, size=(0.04, 0.04, 0.04), **kwargs):
        c = rng.uniform(0.0, 0.02, (12, 3))
        return Scene("small box", c, np.full(12, 0.003), np.full(3, 0.01))

    monkeypatch.setattr(bp, "_error_scene", lambda quick: (scene(0.003), np.zeros(3), np.full(3, 0.02), (2, 2, 2)))
    monkeypatch.setattr(bp, "scene_overlapping_box", scene)
    monkeypatch.setattr(bp, "_time_overlap_peer", lambda *a, **k: None)
    monkeypatch.setattr(bp, "table_1", lambda: [])
    real = bp.porosity

    def porosity(*args, **kwargs):
        Recorder.events.append(("porosity", kwargs.get("method")))
        return real(*args, **kwargs)

    monkeypatch.setattr(bp, "porosity", porosity)
    monkeypatch.setattr(bp, "Progress", Recorder)
    Recorder.events = []


def test_the_progress_bar_covers_the_paper_experiment(small):
    """With paper=True the one bar is opened for the whole work: every porosity call of the paper's experiment
    happens before it closes, and it closes with as many steps as it announced."""
    result = bp.bench_porosity(["cpu"], quick=True, paper=True)
    assert result["paper"]["cases"]
    kinds = [e[0] for e in Recorder.events]
    assert kinds.count("open") == 1 and kinds[-1] == "close"
    assert max(i for i, k in enumerate(kinds) if k == "porosity") < kinds.index("close")
    assert kinds.count("step") == next(e[1] for e in Recorder.events if e[0] == "open")


def test_bench_porosity_paper_says_how_long_before_it_starts(small, capsys, monkeypatch, tmp_path):
    """The CLI (in this process, on a few spheres) writes every method's rows, the voxel error falling with
    subdivision, and prints the expected time of --paper on stderr before the first porosity call (the full run: 77 s of
    CPU time, 4 min 37 s wall-clock, measured on the shared 2-core dev machine; --quick: about a minute), and the
    run completes."""
    seen = []
    inner = bp.porosity

    def first(*args, **kwargs):
        if not seen:
            seen.append(capsys.readouterr().err)
        return inner(*args, **kwargs)

    monkeypatch.setattr(bp, "porosity", first)
    out = tmp_path / "porosity.json"
    argv = ["bench", "porosity", "--quick", "--paper", "--device", "cpu", "--no-progress", "--json", str(out)]
    assert cli.main(argv) == 0
    assert "bench porosity --quick --paper takes about a minute" in seen[0]
    rows = json.loads(out.read_text())["bench"]["rows"]
    assert {r["method"] for r in rows} == {"centroid", "polyhedron", "exact", "voxel", "midpoint"}
    voxel = [r["rms"] for r in rows if r["method"] == "voxel"]
    assert len(voxel) > 1 and voxel == sorted(voxel, reverse=True)
    assert "77 s of CPU time on a 2-core machine, 4 min 37 s while it was shared" in bp.paper_note(quick=False)
    assert "the progress bar covers all of it" in bp.paper_note(quick=False)


def test_paper_experiment_polyhedron_reads_zero_where_voxel_does_not():
    """Section 3.2 of the paper on the quick box (2.5 mm spheres, 587 of them, overlapping densely): the
    polyhedron method reads porosity <= 0 in over a quarter of the cells (measured 98%), the voxel method in none."""
    out = bp.paper_experiment("cpu", radii=(0.0025,), subdivisions=20, quick=True)
    methods = out["cases"][0]["methods"]
    assert methods["polyhedron"]["at_most_0"] > 0.25 and methods["voxel"]["at_most_0"] == 0
    assert [t["midpoint"] for t in out["table_1"]] == [t["paper"] for t in out["table_1"]]
