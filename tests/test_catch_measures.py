"""The benchmark's error and load measures (``warp_lamp.measures``) against values worked out by hand on tiny
scenes, and the README's accuracy figures that they produce."""

import numpy as np
import pytest

from warp_lamp.bench import specimen_stress
from warp_lamp.measures import envelope_stress, lone_sphere_error, stress_summary
from warp_lamp.scenes import scene_sphere_specimen


def test_envelope_stress_by_hand():
    """sigma = (1/V) sum (x_i - x_c) (x) F_i: a squeezed pair gives sigma_xx = -2 a F / V; an off-axis load fills
    [x, y] (position row, force column) and not [y, x]; the reference point is subtracted."""
    a, f, v = 0.5, 3.0, 2.0
    sigma = envelope_stress([[a, 0, 0], [-a, 0, 0]], [[-f, 0, 0], [f, 0, 0]], [0, 0, 0], v)
    want = np.zeros((3, 3))
    want[0, 0] = -2 * a * f / v
    np.testing.assert_allclose(sigma, want, rtol=1e-15, atol=0)
    sigma = envelope_stress([[a, 0, 0]], [[0, f, 0]], [0, 0, 0], v)
    want = np.zeros((3, 3))
    want[0, 1] = a * f / v
    np.testing.assert_allclose(sigma, want, rtol=1e-15, atol=0)
    sigma = envelope_stress([[2.0, 1.0, 0.0]], [[3.0, 0.0, 0.0]], [1.0, 1.0, 0.0], 1.5)
    want = np.zeros((3, 3))
    want[0, 0] = (2.0 - 1.0) * 3.0 / 1.5
    np.testing.assert_allclose(sigma, want, rtol=1e-15, atol=0)


def test_stress_summary_by_hand():
    """Mean pressure -tr(sigma)/3 over P, and the Frobenius norm of sigma + mean I over P: hydrostatic -P I gives
    (1, 0); diag(-1, -2, -3) P with shears tau gives mean 2 and deviator diag(1, 0, -1) P plus the shears,
    norm sqrt(2 + 2 (0.5^2 + 0.25^2)); tension counts negative."""
    p = 4.0e6
    out = stress_summary(-p * np.eye(3), p)
    assert out["mean_pressure_over_P"] == pytest.approx(1.0, rel=1e-15)
    assert out["deviatoric_over_P"] == pytest.approx(0.0, abs=1e-15)
    sigma = p * np.array([[-1.0, 0.5, 0.0], [0.5, -2.0, 0.25], [0.0, 0.25, -3.0]])
    out = stress_summary(sigma, p)
    assert out["mean_pressure_over_P"] == pytest.approx(2.0, rel=1e-15)
    assert out["deviatoric_over_P"] == pytest.approx(np.sqrt(2.0 + 2 * (0.5**2 + 0.25**2)), rel=1e-14)
    assert stress_summary(p * np.eye(3), p)["mean_pressure_over_P"] == pytest.approx(-1.0, rel=1e-15)


def lit_cells(offset, r, h, criterion):
    """Cells of the [-1, 1]^3 grid that each lamp pair lights for a lone sphere, counted in float64 by hand: cell
    centres within r of the projected centre (criterion 1), or cell rectangles within r (criterion 0)."""
    edges = np.arange(-1.0, 1.0 + h / 2, h)
    lo, hi = edges[:-1], edges[1:]
    out = []
    for a in range(3):
        pu, pv = offset[(a + 1) % 3], offset[(a + 2) % 3]
        if criterion == 1:
            du, dv = 0.5 * (lo + hi) - pu, 0.5 * (lo + hi) - pv
        else:
            du = np.maximum(np.maximum(lo - pu, pu - hi), 0.0)
            dv = np.maximum(np.maximum(lo - pv, pv - hi), 0.0)
        out.append(int(np.sum(du[:, None] ** 2 + dv[None, :] ** 2 <= r * r)))
    return out


@pytest.mark.parametrize("criterion", [1, 0])
@pytest.mark.parametrize("cells_per_diameter", [2, 4])
def test_lone_sphere_error_is_the_rms_of_hand_counted_cells(device, criterion, cells_per_diameter):
    """E_area: RMS over the offsets and the six lamps of (lit cells x h^2) / (pi r^2) - 1, with the lit cells
    counted here in float64 (both lamps of an axis light the same cells), at the offsets the measure documents
    (uniform in a cell, seeded)."""
    r, samples, seed = 0.5, 16, 7
    h = 2 * r / cells_per_diameter
    offsets = np.random.default_rng(seed).uniform(0.0, h, (samples, 3))
    errors = []
    for off in offsets:
        for n in lit_cells(off, r, h, criterion):
            errors += [n * h * h / (np.pi * r * r) - 1.0] * 2
    want = np.sqrt(np.mean(np.square(errors)))
    assert abs(np.mean(np.abs(errors)) - want) > 1e-3 * want  # the scene tells RMS from mean |e|
    got = lone_sphere_error(criterion, cells_per_diameter, device, samples=samples, seed=seed)
    assert got == pytest.approx(want, rel=1e-12)


def test_specimen_stress_readme_figures(device):
    """The README's SphereTest-specimen figures (criterion 1): the loads' mean pressure over the 100 mm envelope is
    0.874 P at 2, 4, 8 and 16 cells per diameter (measured 0.87397 to 0.87403), the deviatoric norm below 0.2% of P
    from 4 cells per diameter on (measured 0.07% at most), the moment below 2e-3 P pi R^3 (measured 1.7e-3 at 2),
    the force sum exactly zero."""
    scene = scene_sphere_specimen()
    for k in (2, 4, 8, 16):
        out = specimen_stress(scene, 1, k, device)
        assert round(out["mean_pressure_over_P"], 3) == 0.874, (k, out)
        if k >= 4:
            assert out["deviatoric_over_P"] < 0.002, (k, out)
        assert out["moment_over_PpiR3"] < 2e-3, (k, out)
        assert out["force_sum"] == [0.0, 0.0, 0.0]
