"""A granular ball in Newton's particle solver, confined by the shining lamp (pip install ".[newton]").

    python examples/newton_pressure.py                 # with and without pressure, on the default device

The lamp sits where Newton examples put external forces: after ``state.clear_forces()`` and before
``solver.step``, inside the one ``wp.ScopedCapture`` that records the whole step on CUDA. Particles start with
small random velocities and no gravity: without pressure the ball disperses, with it the ball stays compact.
"""

from __future__ import annotations

import argparse

import numpy as np
import warp as wp

import warp_lamp as wl

RADIUS = 0.01  # particle radius [m]
BALL = 0.1  # ball radius [m]
DENSITY = 1000.0


def ball_positions(seed: int = 0) -> np.ndarray:
    """Particle centres of a ball: a jittered cubic lattice of spacing 2 r, cut to the ball."""
    rng = np.random.default_rng(seed)
    k = int(BALL / RADIUS)
    axis = np.arange(-k, k + 1) * 2.0 * RADIUS
    pts = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    pts = pts[np.linalg.norm(pts, axis=1) <= BALL - RADIUS]
    return pts + rng.uniform(-0.02, 0.02, pts.shape) * RADIUS


def lamp_grid(cells_per_diameter: float = 4.0) -> wl.LampGrid:
    """A box grid around the ball with room to move; its corner is a power-of-two fraction, exact in float32, so
    the lamp's float32 frame and lamp_forces' float64 frame agree bitwise."""
    h = 2.0 * RADIUS / cells_per_diameter
    half = 2.0 * BALL
    return wl.LampGrid([-half] * 3, [half] * 3, h)


class GranularBall:
    """Newton model, solver and states for the ball, and the lamp inside its step."""

    def __init__(self, pressure: float, *, device=None, seed: int = 0, speed: float = 0.05):
        import newton

        self.device = wp.get_device(device)
        rng = np.random.default_rng(seed + 1)
        builder = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))
        mass = DENSITY * 4.0 / 3.0 * np.pi * RADIUS**3
        for p in ball_positions(seed):
            builder.add_particle(tuple(p), tuple(rng.normal(scale=speed / np.sqrt(3), size=3)), mass, RADIUS)
        self.model = builder.finalize(device=self.device)
        self.model.particle_ke = 1.0e3
        self.model.particle_kd = 1.0
        self.model.particle_kf = 1.0
        self.model.particle_mu = 0.5
        self.solver = newton.solvers.SolverSemiImplicit(self.model)
        self.state_0 = self.model.state()
        self.state_1 = self.model.state()
        self.control = self.model.control()
        self.lamp = wl.ShiningLamp(lamp_grid(), device=self.device)
        self.lamp.reserve(self.model.particle_count)
        self.pressure = wp.array([pressure], dtype=wp.float32, device=self.device)  # read by the graph each step
        self.dt = 2.0e-4
        self.substeps = 10
        self.graph = None
        if self.device.is_cuda:
            self.simulate()  # load kernels and size everything before recording
            with wp.ScopedCapture(device=self.device) as capture:
                self.simulate()
            self.graph = capture.graph

    def simulate(self) -> None:
        """The usual Newton loop, with the lamp between the force clear and the solver."""
        for _ in range(self.substeps):
            self.state_0.clear_forces()
            self.lamp.apply(self.state_0.particle_q, self.model.particle_radius, self.state_0.particle_f, self.pressure)
            self.solver.step(self.state_0, self.state_1, self.control, None, self.dt)
            self.state_0, self.state_1 = self.state_1, self.state_0

    def step(self) -> None:
        if self.graph is not None:
            wp.capture_launch(self.graph)
        else:
            self.simulate()

    def radius_of_gyration(self) -> float:
        x = self.state_0.particle_q.numpy().astype(np.float64)
        return float(np.sqrt(np.mean(np.sum((x - x.mean(axis=0)) ** 2, axis=1))))


def run(pressure: float, frames: int, *, device=None) -> list:
    ball = GranularBall(pressure, device=device)
    rg = [ball.radius_of_gyration()]
    for _ in range(frames):
        ball.step()
        rg.append(ball.radius_of_gyration())
    return rg


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=200, help="frames of 10 substeps of 0.2 ms")
    parser.add_argument("--pressure", type=float, default=2.0e3, help="confining pressure [Pa]")
    parser.add_argument("--device", default=None)
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    for p in (0.0, args.pressure):
        rg = run(p, args.frames, device=args.device)
        t = args.frames * 10 * 2.0e-4
        print(f"pressure {p:8.0f} Pa: radius of gyration {rg[0] * 1e3:.1f} mm -> {rg[-1] * 1e3:.1f} mm after {t:.2f} s")


if __name__ == "__main__":
    main()
