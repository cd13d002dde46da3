"""The lamp inside Warp simulators: the memo's SphereTest in a minimal DEM, and Newton's particle solver."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent


def load_example(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / "examples" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def test_sphere_test_reaches_equilibrium_at_the_applied_pressure(device):
    """Reduced SphereTest (2 cells per diameter, at most 2,500 cycles; captured CUDA graphs on a GPU): the
    unbalanced force ratio falls below 1e-2, and the measurement sphere's stress is isotropic and within 10% of P."""
    st = load_example("sphere_test")
    test = st.SphereTest(2, device=device)
    info = test.run(2500, tol=1e-2)
    assert info["ratio"] < 1e-2, info
    sigma = test.measure()
    mean = np.trace(sigma) / 3
    assert abs(mean - 10e6) < 1e6, mean
    assert np.abs(sigma - np.diag(np.diag(sigma))).max() < 0.02 * 10e6
    assert np.ptp(np.diag(sigma)) < 0.03 * 10e6


def test_newton_ball_disperses_without_pressure_and_stays_compact_with_it(device):
    """In Newton's particle solver, with the lamp in its step: a ball given random velocities spreads without
    pressure and does not with it (radius of gyration); Newton receives exactly lamp_forces' forces."""
    pytest.importorskip("newton")
    import warp_lamp as wl

    nb = load_example("newton_pressure")
    free = nb.run(0.0, 60, device=device)
    held = nb.run(2.0e3, 60, device=device)
    assert free[-1] > 1.05 * free[0], free[::20]
    assert held[-1] < free[0], held[::20]
    ball = nb.GranularBall(2.0e3, device=device)
    ball.step()
    state = ball.state_0
    state.clear_forces()
    ball.lamp.apply(state.particle_q, ball.model.particle_radius, state.particle_f, ball.pressure)
    received = state.particle_f.numpy()
    q = state.particle_q.numpy().astype(np.float64)
    r = ball.model.particle_radius.numpy()
    expected = wl.lamp_forces(q, r, 2.0e3, grid=ball.lamp.grid, device=device).astype(np.float32)
    assert np.count_nonzero(expected) > 100
    assert received.tobytes() == expected.tobytes()
