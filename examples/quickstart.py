"""Quick start: lamp forces and porosity on a ball of spheres, then a ShiningLamp in a simulator's step loop.

The same code as the README's "Quick start" (tests/test_examples.py runs it and checks that the two agree).
device="cpu" works on every machine; "cuda:0" runs it on a GPU. The first run compiles the kernels (about 10 s,
cached in ~/.cache/warp); later runs start in about a second. It takes no options.
"""

import argparse

if __name__ == "__main__":  # --help prints the text above instead of running
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.lamp import pressure_area
from warp_lamp.scenes import scene_lattice_ball

device = "cpu"
ball = scene_lattice_ball(diameter=0.05, particle_diameter=0.005)  # SI units throughout: metres, pascals, newtons
centers, radii = ball.centers, ball.radii  # shapes (N, 3) and (N,), float64
P = 1e6  # fluid pressure [Pa], a plain float (or three: Px, Py, Pz)

# 1. Forces on the body, from host arrays: shape (N, 3), float64 [N]; they sum to exactly zero.
forces = wl.lamp_forces(centers, radii, P, cells_per_diameter=4, device=device)
loaded = np.count_nonzero(np.abs(forces).sum(axis=1))
print(f"{len(radii)} particles, {loaded} on the surface; sum of forces {forces.sum(axis=0).tolist()} N")

# 2. Porosity on a 5 x 5 x 5 CFD grid over the ball's bounding box (voxel: sub-cells in any sphere, counted once).
lower, upper = ball.center - ball.radius, ball.center + ball.radius
eps = wl.porosity(centers, radii, lower, upper, (5, 5, 5), method="voxel", subdivisions=8, device=device)
print(f"porosity: centre cell {eps[2, 2, 2]:.3f}, corner cell {eps[0, 0, 0]:.3f}")

# 3. In a simulator: arrays on the device, world positions, the lamp's forces added after each force clear.
grid = wl.LampGrid.enclosing(centers, radii, cells_per_diameter=4)
lamp = wl.ShiningLamp(grid, device=device)
positions = wp.array(centers.astype(np.float32), dtype=wp.vec3, device=device)
particle_radius = wp.array(radii.astype(np.float32), dtype=wp.float32, device=device)
particle_force = wp.zeros(len(radii), dtype=wp.vec3, device=device)
pressure = wp.array([P], dtype=wp.float32, device=device)  # read on the device: change it to ramp the load
for _step in range(3):
    particle_force.zero_()  # the simulator clears its forces
    lamp.update(positions, particle_radius)  # who is lit (every step, or every few steps)
    lamp.add_forces(particle_force, pressure)  # forces += P A count, float32
    # ... contact forces and the integrator would follow here

exact = lamp.counts_numpy() * pressure_area(P, grid)  # the exact float64 forces behind the float32 ones
print(f"float32 forces within {np.abs(particle_force.numpy() - exact).max():.2g} N of the exact ones")
d = lamp.diagnostics(centers, P)
print(f"resultant {d.force.tolist()} N; skipped: invalid {d.invalid}, outside the grid {d.outside}")
assert forces.sum(axis=0).tolist() == [0.0, 0.0, 0.0] and 0 < loaded < len(radii)  # balanced, surface only
assert 0.0 < eps[2, 2, 2] < eps[0, 0, 0] <= 1.0  # denser at the ball's centre than in a corner
assert np.abs(particle_force.numpy() - exact).max() < 1e-5 and d.invalid == d.outside == 0
