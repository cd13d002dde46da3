"""The lamp inside Warp simulators: the memo's SphereTest in a minimal DEM, and Newton's particle solver."""

import numpy as np
import pytest
from helpers import load_example


def test_sphere_test_reaches_equilibrium_at_the_applied_pressure(device):
    """Reduced SphereTest (2 cells per diameter, 2,500 cycles; captured CUDA graphs on a GPU): the unbalanced force
    ratio is below 5e-3, the measurement sphere's stress is isotropic to 1.5% of P, and its mean is 0.95 to 0.975 P.

    Why that band: the loads act at the surface particles' centres, inside the body, so the stress in the 90 mm
    measurement sphere settles a few percent below P (the memo: 9.6 MPa under 10 MPa). Measured at 2 cells per
    diameter: 0.9625 P on the CPU (the same from 4,000 to 6,000 cycles; 0.9628 at 2,500, 0.960 to 0.964 from 500
    on) and 0.961 P on the H200 after 40,000 cycles; 0.967 to 0.970 P at 4 to 16 cells per diameter. The band is
    0.9625 P +- 1.3%: it holds every converged resolution and the transient from 2,500 cycles, and fails a load
    2% off P (about 0.982 P or 0.943 P). Measured isotropy at 2,500 cycles: diagonal spread 0.73% of P, largest
    shear 0.31% of P; ratio 2.4e-3."""
    st = load_example("sphere_test")
    test = st.SphereTest(2, device=device)
    info = test.run(2500, tol=0.0)  # tol 0: run all 2,500 cycles, do not stop at the first ratio below a bound
    assert 2500 <= info["cycles"] <= 2502, info  # a GPU run replays pairs of cycles after two eager ones
    assert info["ratio"] < 5e-3, info
    sigma = test.measure()
    mean = np.trace(sigma) / 3
    assert 0.95 * 10e6 < mean < 0.975 * 10e6, mean / 10e6
    assert np.abs(sigma - np.diag(np.diag(sigma))).max() < 0.008 * 10e6
    assert np.ptp(np.diag(sigma)) < 0.015 * 10e6


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
