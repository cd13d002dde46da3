"""The exact sphere-box volume in float32 against float64 (an experiment): per-cell error as r/h grows.

python bench/experiments/exact_float32.py
"""

import numpy as np

from warp_lamp import reference as ref


def main():
    rng = np.random.default_rng(0)
    print("| r/h | boundary cells | float32 max error / cell volume | float32 RMS error / cell volume |")
    print("| --- | --- | --- | --- |")
    for ratio in (0.5, 1, 3, 10, 50):
        r = float(ratio)
        lo = rng.uniform(-r - 1, r, (20000, 3))
        hi = lo + 1.0
        # Keep the cells the surface cuts: those are the ones the formula really works for.
        near = np.linalg.norm(np.maximum(np.maximum(lo, -hi), 0), axis=1) < r
        far = np.linalg.norm(np.maximum(np.abs(lo), np.abs(hi)), axis=1) > r
        lo, hi = lo[near & far], hi[near & far]
        v64 = ref.sphere_box_volume(lo, hi, np.full(len(lo), r))
        v32 = ref.sphere_box_volume(lo, hi, np.full(len(lo), r), dtype=np.float32)
        assert v32.dtype == np.float32
        err = np.abs(v32.astype(np.float64) - v64)
        print(f"| {ratio} | {len(lo)} | {err.max():.2e} | {np.sqrt(np.mean(err**2)):.2e} |")


if __name__ == "__main__":
    main()
