"""The area criterion's (cell, lamp) pairs by the path the cell pass takes (reference, sub-points D4 with the deep
gather, 4 cells per diameter): one seed holding the whole cell (no points to resolve), decided with several seeds
or partial cover (the sub-point rows), undecided (the per-point depths; the work list on CUDA).

    PYTHONPATH=$PWD python bench/experiments/area_cell_classes.py
"""

import numpy as np

import warp_lamp as wl
from warp_lamp.reference import area as A
from warp_lamp.scenes import scene_lattice_ball, scene_sphere_specimen

STATS = []
orig = A._resolve


def hooked(seeds, full, cells, q, r, a, cu, cv, hu, hv, nu, side, resolver, subpoints, unit):
    ox, oy, oz, rr, ok = A._geometry(seeds, cells, q, r, a, cu, cv, hu, hv, nu, side)
    _order, undecided = A._surface_order(A._pair_relations(ox, oy, oz, rr, ok, hu, hv), ok)
    count = ok.sum(axis=1)
    STATS.append(np.stack([count, full, undecided.astype(int)], axis=1))
    return orig(seeds, full, cells, q, r, a, cu, cv, hu, hv, nu, side, resolver, subpoints, unit)


A._resolve = hooked
for name, sc in (("specimen", scene_sphere_specimen()), ("lattice ball", scene_lattice_ball(diameter=0.05))):
    STATS.clear()
    grid = wl.LampGrid.enclosing(sc.centers, sc.radii, cells_per_diameter=4)
    A.area_estimate_reference(
        sc.centers,
        sc.radii,
        grid,
        depth_slots=4,
        resolver="subpoints",
        subpoints=8,
        _cell_seeds="both",
        _hidden_rounds=2,
    )
    s = np.concatenate(STATS)
    s = s[s[:, 0] > 0]
    n = len(s)
    one = (s[:, 0] == 1) & (s[:, 1] == 0)
    fullfirst = (s[:, 1] == 0) & (s[:, 2] == 0) & ~one
    und = s[:, 2] == 1
    rest = ~one & ~fullfirst & ~und
    print(
        f"{name}: {n} (cell, lamp) with seeds; one seed holding the cell {one.mean():.1%}; first seed holds it, "
        f"decided, more seeds {fullfirst.mean():.1%}; decided, partial {rest.mean():.1%}; undecided {und.mean():.1%};"
        f" seeds per cell mean {s[:, 0].mean():.2f}, undecided cells' mean {s[und, 0].mean() if und.any() else 0:.2f}"
    )
