"""tolerance=: the cheapest setting whose table error meets the tolerance (warp_lamp.tolerance)."""

import numpy as np
import pytest

import warp_lamp as wl
from warp_lamp.bench.modes import P, exact_areas
from warp_lamp.measures import visible_area_error
from warp_lamp.scenes import scene_lattice_ball
from warp_lamp.tolerance import choose_settings, load_table


def _row(criterion, k, error, ratio, **area):
    return {"criterion": criterion, "cells_per_diameter": k, "error": error, "ratio": {"cpu": ratio}, **area}


SYNTHETIC = {
    "kinds": {"cpu": {}},
    "rows": [
        _row(1, 4, 0.10, 1.0),
        _row(1, 8, 0.03, 3.0),
        _row(1, 16, 0.011, 12.0),
        _row("area", 2, 0.05, 2.0, resolver="subpoints", depth_slots=3, subpoints=8),
        _row("area", 4, 0.004, 9.0, resolver="subpoints", depth_slots=3, subpoints=8),
        _row("area", 4, 0.0002, 90.0, resolver="exact", depth_slots=4),
    ],
}


@pytest.mark.parametrize(
    ("tol", "want"),
    [(0.2, (1, 4)), (0.06, ("area", 2)), (0.03, (1, 8)), (0.01, ("area", 4)), (0.001, ("area", 4))],
)
def test_the_cheapest_eligible_setting_is_chosen(tol, want):
    """Among the settings whose error meets the tolerance, the one with the smallest time ratio wins."""
    c = choose_settings(tol, "cpu", table=SYNTHETIC, margin=1.0)
    assert (c.criterion, c.cells_per_diameter) == want
    assert c.error <= tol
    cheaper = [r for r in SYNTHETIC["rows"] if r["ratio"]["cpu"] < c.time_ratio]
    assert all(r["error"] > tol for r in cheaper)


def test_a_tolerance_no_setting_reaches_is_refused_by_name():
    """A tolerance tighter than the table's best, or not a positive number, raises naming ``tolerance``."""
    with pytest.raises(ValueError, match=r"tolerance: 1e-05 is tighter than any setting"):
        choose_settings(1e-5, "cpu", table=SYNTHETIC)
    # The margin: a setting whose table error is the tolerance itself is not eligible with the default margin.
    assert choose_settings(0.03, "cpu", table=SYNTHETIC, margin=1.0).cells_per_diameter == 8
    assert choose_settings(0.03, "cpu", table=SYNTHETIC).criterion == "area"
    for bad in (0.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="tolerance"):
            choose_settings(bad, "cpu", table=SYNTHETIC)
    with pytest.raises(TypeError, match="tolerance"):
        choose_settings("0.01", "cpu", table=SYNTHETIC)


def test_tolerance_leaves_the_settings_to_the_choice():
    """Explicit criterion, cells or a grid beside ``tolerance`` are refused, naming what to leave out."""
    ball = scene_lattice_ball(diameter=0.03, particle_diameter=0.005)
    c, r = ball.centers, ball.radii
    with pytest.raises(ValueError, match=r"tolerance: .* leave out cells_per_diameter, criterion"):
        wl.lamp_forces(c, r, P, tolerance=0.05, criterion="area", cells_per_diameter=8, device="cpu")
    with pytest.raises(ValueError, match=r"tolerance: .* leave out grid"):
        wl.lamp_forces(c, r, P, tolerance=0.05, grid=wl.LampGrid.enclosing(c, r), device="cpu")
    with pytest.raises(ValueError, match=r"tolerance: .* needs a grid spec"):
        wl.ShiningLamp(wl.LampGrid.enclosing(c, r), tolerance=0.05, device="cpu")


@pytest.mark.parametrize("tol", [0.1, 0.03, 0.01])
def test_the_choice_runs_and_meets_the_tolerance_on_a_ball(device, tol):
    """lamp_forces(tolerance=t) equals the chosen settings given explicitly, and its measured error is <= t on a
    smaller ball of the table's lattice family (another scene than the table's)."""
    ball = scene_lattice_ball(diameter=0.05, seed=3)
    c, r = ball.centers, ball.radii
    choice = choose_settings(tol, device)
    f = wl.lamp_forces(c, r, P, tolerance=tol, device=device)
    g = wl.lamp_forces(c, r, P, cells_per_diameter=choice.cells_per_diameter, device=device, **choice.options())
    np.testing.assert_array_equal(f, g)
    err = visible_area_error(f, exact_areas(ball)[0], P, float(r.mean()))["rms"]
    assert err <= tol
    lamp = wl.ShiningLamp(wl.LampGrid.spec(c, r), tolerance=tol, device=device)
    assert lamp.choice == choice
    assert lamp.diagnostics().choice == choice


def test_the_shipped_table_covers_every_candidate_on_the_cpu():
    """The package's table has an error and a CPU time for every setting, criterion 1 at 4 as its unit."""
    table = load_table()
    rows = table["rows"]
    assert {r["criterion"] for r in rows} == {1, "area"}
    assert all(r["error"] > 0 and r["ratio"]["cpu"] > 0 for r in rows)
    unit = [r for r in rows if r["criterion"] == 1 and r["cells_per_diameter"] == 4]
    assert len(unit) == 1 and unit[0]["ratio"]["cpu"] == 1.0


def test_a_deep_gather_row_is_chosen_with_its_gather_and_rows_without_a_kind_are_skipped():
    """A table row of the deep gather carries ``gather`` into the choice's lamp options and its description; a row
    without a time for the device's kind is never chosen there."""
    deep = _row("area", 4, 0.007, 8.0, resolver="subpoints", depth_slots=4, subpoints=8, gather="deep")
    table = {"kinds": {"cpu": {}}, "rows": [_row(1, 32, 0.006, 12.0), deep]}
    c = choose_settings(0.01, "cpu", table=table, margin=1.2)
    want = {"criterion": "area", "resolver": "subpoints", "depth_slots": 4, "subpoints": 8, "gather": "deep"}
    assert c.options() == want
    assert "deep gather" in c.describe()
    untimed = {"kinds": {"cpu": {}}, "rows": [_row(1, 32, 0.006, 12.0), {**deep, "ratio": {"h100": 8.0}}]}
    assert choose_settings(0.01, "cpu", table=untimed, margin=1.2).criterion == 1


def test_merge_kind_missing_only_times_just_the_rows_a_kind_lacks(monkeypatch):
    """With ``missing_only``, only the rows without the device's kind are timed (after criterion 1 at 4, their unit),
    the kind's other rows keep their times, and the run is recorded under ``completed``."""
    from warp_lamp.bench import tolerance as bt

    timed = []

    def fake_times(device, repeats, scene, settings=bt.SETTINGS):
        timed.append(list(settings))
        return [2.0 * (i + 1) for i in range(len(settings))]

    monkeypatch.setattr(bt, "_times", fake_times)
    base = {"criterion": 1, "resolver": None, "depth_slots": None, "subpoints": None, "cells_per_diameter": 4}
    old = {**base, "cells_per_diameter": 32, "time_s": {"cpu": 9.0}, "ratio": {"cpu": 12.0}}
    new = {**base, "cells_per_diameter": 48, "time_s": {}, "ratio": {}}
    table = {"kinds": {"cpu": {}}, "rows": [{**base, "time_s": {"cpu": 1.0}, "ratio": {"cpu": 1.0}}, old, new]}
    bt.merge_kind(table, "cpu", missing_only=True)
    assert timed == [[(1, None, None, None, 4, None), (1, None, None, None, 48, None)]]
    assert new["time_s"]["cpu"] == 4.0 and new["ratio"]["cpu"] == 2.0
    assert old["ratio"]["cpu"] == 12.0 and table["rows"][0]["ratio"]["cpu"] == 1.0
    assert table["completed"]["cpu"]["rows"] == 1 and table["completed"]["cpu"]["base_s"] == 2.0
