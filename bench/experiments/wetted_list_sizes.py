"""How full the exact test's local lists get (reference, 4 cells per diameter): per tested voxel, the spheres the
gather keeps (centre within (r + 2 rho + diagonal)(1 + slack): ``GATHER`` = 128 holds them, else the bins are walked
per candidate) and the exposed near ones before pruning (``NEAR_LIST`` = 64, else a second walk after the deep
balls' pruning). The lists' capacities set the exact test's frame; this says what smaller ones would cost.

    PYTHONPATH=$PWD python bench/experiments/wetted_list_sizes.py --scene specimen
"""

import numpy as np
from wetted_study import near_exposed, percentiles, study_main

from warp_lamp.reference import wetted as R

gathered, near = [], []


def hook(exact, x):
    far, ids = near_exposed(exact, x)
    v = x - exact.c[far]
    lim = (exact.r[far] + 2.0 * exact.rho + exact.diag) * (1.0 + R.SLACK)
    gathered.append(int((R._dot(v, v) <= lim * lim).sum()))
    near.append(len(ids))


args, sc, rho, secs = study_main(hook)
g, n = np.array(gathered), np.array(near)
print(f"{sc.name}: rho {rho:.4g}, {len(g)} tests, {secs:.0f} s")
for name, v, over in (("gathered", g, (64, 96)), ("near", n, (16, 32))):
    counts = ", ".join(f"over {k}: {int((v > k).sum())}" for k in over)
    print(f"{name:9s} median/p90/p99/p99.9/max: {percentiles(v)}  {counts}")
