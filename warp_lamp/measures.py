"""Error and load measures that the benchmark, the CLI and the tests report, each defined once."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_lamp.grid import LampGrid
from warp_lamp.lamp import LAMPS, ShiningLamp

__all__ = ["envelope_stress", "lone_sphere_error", "stress_summary"]


def lone_sphere_error(criterion: int, cells_per_diameter: float, device, *, samples: int = 256, seed: int = 7) -> float:
    """E_area: RMS, over random sub-cell offsets of a lone sphere and over the six lamps, of F_lamp / (P pi r^2) - 1.

    Args:
        criterion: The lamp's criterion (0 or 1).
        cells_per_diameter: Cells per sphere diameter.
        device: Warp device.
        samples: Random offsets of the sphere within a cell.
        seed: Seed of the offsets.
    """
    r = 0.5
    h = 2 * r / cells_per_diameter
    grid = LampGrid([-1.0] * 3, [1.0] * 3, h)
    lamp = ShiningLamp(grid, criterion=criterion, device=device)
    offsets = np.random.default_rng(seed).uniform(0.0, h, (samples, 3))
    rad = wp.array([r], dtype=wp.float32, device=device)
    errs = []
    for off in offsets:
        lamp.update(wp.array([off], dtype=wp.vec3, device=device), rad)
        lit = lamp.diagnostics().lit
        errs.extend(lit[name] * h * h / (np.pi * r * r) - 1.0 for name in LAMPS)
    return float(np.sqrt(np.mean(np.square(errs))))


def envelope_stress(centers, forces, center, volume: float) -> np.ndarray:
    """Average stress that external point loads imply on a body: sigma = (1/V) sum_i (x_i - x_c) (x) F_i.

    Tension positive: a body under fluid pressure P has sigma close to -P I, so its mean pressure is
    -trace(sigma)/3 (see :func:`stress_summary`).

    Args:
        centers: Load points (particle centres) [m], shape (N, 3).
        forces: Loads [N], shape (N, 3).
        center: Reference point [m], shape (3,) (the moment of balanced loads does not depend on it).
        volume: Volume to average over [m^3] (the body's envelope).

    Returns:
        sigma [Pa], shape (3, 3).
    """
    x = np.asarray(centers, dtype=np.float64) - np.asarray(center, dtype=np.float64)
    return np.einsum("ni,nj->ij", x, np.asarray(forces, dtype=np.float64)) / float(volume)


def stress_summary(sigma: np.ndarray, pressure: float) -> dict:
    """Mean pressure -tr(sigma)/3 and the deviatoric (Frobenius) norm of sigma, both over ``pressure``."""
    mean = -np.trace(sigma) / 3.0
    deviator = sigma + mean * np.eye(3)
    return {
        "mean_pressure_over_P": float(mean / pressure),
        "deviatoric_over_P": float(np.linalg.norm(deviator) / pressure),
    }
