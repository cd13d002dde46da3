"""``warp-lamp run`` (``python -m warp_lamp``), the README's first command: its printed report against values
computed here from the scene, the float64 reference's owners and ``lamp_forces``."""

import re
import subprocess
import sys

import numpy as np
import pytest

import warp_lamp as wl
from warp_lamp.reference import lamp_reference
from warp_lamp.scenes import scene_sphere_specimen


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
