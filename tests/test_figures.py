"""The README's figures say only what they draw and use their room: the bench plot names only the line styles it
has; the rock-cutting summary keeps the MSE curves on their own scale, and its sections fill the width."""

import json
from pathlib import Path

import numpy as np
import pytest
from helpers import load_example

ROOT = Path(__file__).resolve().parents[1]

RESULTS = ROOT / "bench" / "results"


def test_bench_plot_names_only_the_line_styles_it_draws():
    """A result timed on CUDA only (the H200's, behind docs/bench_lamp.png) has no dashed CPU curves, and its
    axis says so; with CPU rows added, the label names both styles, and the CPU curves are dashed."""
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from warp_lamp.bench.modes import plot_area

    result = json.loads((RESULTS / "h200-2026-11-25.json").read_text())
    fig, ax = plt.subplots()
    plot_area(ax, result)
    assert "dashed" not in ax.get_ylabel() and "CUDA graph replay" in ax.get_ylabel()
    assert {line.get_linestyle() for line in ax.get_lines()} == {"-"}
    plt.close(fig)
    for sec in result["area"]:
        sec["rows"] += [{**r, "device": "cpu"} for r in sec["rows"]]
    fig, ax = plt.subplots()
    plot_area(ax, result)
    assert "solid" in ax.get_ylabel() and "dashed" in ax.get_ylabel()
    assert {line.get_linestyle() for line in ax.get_lines()} == {"-", "--"}
    plt.close(fig)


def test_rock_cutting_figures_are_not_squashed_and_use_the_width():
    """Redrawn from the H200 study's saved result: the MSE panel's scale is the MSE's (its top under twice the
    largest MSE, the UCS named in the title instead of drawn 10x above), and the three sections cover at least 80%
    of the damage figure's width (stacked in a column, as before, they covered about a third)."""
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rock = load_example("rock_cutting")
    data = json.loads((RESULTS / "h200-2026-11-25-rock-cutting.json").read_text())
    figs = dict(rock.figures(data))
    try:
        summary = figs[""]
        mse_ax = next(a for a in summary.axes if a.get_title().startswith("mechanical specific energy"))
        mse = np.concatenate([line.get_ydata() for line in mse_ax.get_lines()])
        assert mse.size and mse_ax.get_ylim()[1] < 2.0 * mse.max()
        assert f"UCS {data['calibration']['ucs_Pa'] / 1e6:.0f} MPa" in mse_ax.get_title()
        damage = figs["-damage"]
        damage.canvas.draw()  # equal aspect settles the axes' boxes at draw time
        spans = sorted((a.get_position().x0, a.get_position().x1) for a in damage.axes)
        covered, reach = 0.0, 0.0
        for x0, x1 in spans:  # the width the sections cover, overlaps counted once
            covered += max(0.0, x1 - max(x0, reach))
            reach = max(reach, x1)
        assert len(damage.axes) == 3 and covered > 0.8, covered
    finally:
        for fig in figs.values():
            plt.close(fig)
