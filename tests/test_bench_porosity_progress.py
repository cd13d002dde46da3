"""`bench porosity --paper` says how long it takes before it starts, and its progress bar covers all of it."""

from typing import ClassVar

import numpy as np
import pytest

from warp_lamp import bench_porosity as bp
from warp_lamp import cli
from warp_lamp.scenes import Scene


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


def test_bench_porosity_paper_says_how_long_before_it_starts(small, capsys, monkeypatch):
    """The CLI prints the expected time of --paper on stderr before the first porosity call (the full run: 77 s of
    CPU time, 4 min 37 s wall-clock, measured on the shared 2-core dev machine; --quick: about a minute), and the
    run completes."""
    seen = []
    inner = bp.porosity

    def first(*args, **kwargs):
        if not seen:
            seen.append(capsys.readouterr().err)
        return inner(*args, **kwargs)

    monkeypatch.setattr(bp, "porosity", first)
    assert cli.main(["bench", "porosity", "--quick", "--paper", "--device", "cpu", "--no-progress"]) == 0
    assert "bench porosity --quick --paper takes about a minute" in seen[0]
    assert "77 s of CPU time on a 2-core machine, 4 min 37 s while it was shared" in bp.paper_note(quick=False)
    assert "the progress bar covers all of it" in bp.paper_note(quick=False)
