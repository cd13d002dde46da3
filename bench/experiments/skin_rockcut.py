"""The wetted surface's skin in the rock-cutting example: every lamp update of a short cut compared bitwise with a
from-scratch lamp (``skin=False``) fed the same positions, then the DEM cycle with and without the lamp mid-cut
(chips flying), graph replay.

The example's procedure, shortened so that a few hundred lamp updates reach the cut: the pressure ramps over
``--ramp`` cycles, the cutter moves at one mean diameter per ``--cycles-per-d`` cycles (the study's 3,000 would
take ~5,000 cycles to reach the rock), for ``--updates`` lamp updates in all (one every ``update_every`` cycles,
eager: each update is compared on the host). What is compared: the counts of every particle (per axis, the
lamp's integer result), the wall counts, and each update's skin diagnostics (kept dry, witnessed wet, kept owners,
resets).

    PYTHONPATH=$PWD python bench/experiments/skin_rockcut.py --device cpu --tiny --updates 30
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples"))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default=None)
    ap.add_argument("--tiny", action="store_true", help="the example's CPU configuration")
    ap.add_argument("--pressure-mpa", type=float, default=20.0)
    ap.add_argument("--updates", type=int, default=400)
    ap.add_argument("--ramp", type=int, default=200, help="cycles of the pressure ramp")
    ap.add_argument("--cycles-per-d", type=int, default=300, help="cutter speed: cycles per mean diameter")
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    import rock_cutting as rc

    import warp_lamp as wl

    device = wp.get_device(args.device)
    base = rc.TINY if args.tiny else rc.STUDY
    cfg = dataclasses.replace(base, cycles_per_d=args.cycles_per_d, ramp_cycles=args.ramp, settle_cycles=0)
    test = rc.RockCutting(cfg, pressure=args.pressure_mpa * 1e6, surfaces="all", device=device)
    # The skin forced on (the example turns it off), against a lamp without it.
    opts = {k: v for k, v in test.lamp_options().items() if k != "skin"}
    test.lamp = wl.ShiningLamp(test.grid, follow=True, device=device, skin=True, **opts)
    test.lamp.reserve(test.n)
    ref = wl.ShiningLamp(test.grid, follow=True, device=device, skin=False, **opts)
    ref.reserve(test.n)
    skinned = test.lamp.update
    rows = []

    def both(pos, rad, active=None):
        skinned(pos, rad, active)
        ref.update(pos, rad, active)
        a, b = test.lamp.counts_numpy(), ref.counts_numpy()
        d = test.lamp.diagnostics()
        rows.append(
            {
                "cycle": int(test.cycle),
                "equal": bool(np.array_equal(a, b)),
                "differ": int(np.count_nonzero((a != b).any(axis=1))),
                "kept": int(d.skin_kept),
                "witnessed": int(d.skin_witnessed),
                "held": int(getattr(d, "skin_held", 0)),
                "cross_kept": int(d.skin_cross_kept),
                "reset": int(d.skin_reset),
                "uncertain": int(d.uncertain),
                "certified": int(getattr(d, "skin_certified", 0)),
            }
        )

    test.lamp.update = both
    t0 = time.perf_counter()
    test.tool.velocity.assign(np.array([[test.speed, 0.0, 0.0]]))
    ramp = max(args.ramp, 1)
    for _ in range(args.updates):
        start = test.cycle
        frac = min(1.0, (start + test.block) / ramp)
        test.pressure.assign(np.array([test.pressure_value * frac], dtype=np.float32))
        for k in range(cfg.update_every):
            test.step(lamp_update=k == 0)
        test.dem.cycle = start + cfg.update_every if test.cycle == start else test.cycle
    wp.synchronize_device(device)
    run_s = time.perf_counter() - t0
    test.lamp.update = skinned
    # Mid-cut: the cycle with and without the lamp (skin on, as shipped), and with a from-scratch lamp.
    share = {"skin": test.time_cycle(repeats=args.repeats)}
    test.lamp = ref
    test._graph = None
    share["from_scratch"] = test.time_cycle(repeats=args.repeats)
    tip = test.tip()
    out = {
        "device": str(device),
        "name": getattr(device, "name", ""),
        "config": dataclasses.asdict(cfg),
        "pressure_mpa": args.pressure_mpa,
        "particles": int(test.n),
        "updates": len(rows),
        "mismatching_updates": sum(not r["equal"] for r in rows),
        "resets": sum(r["reset"] for r in rows),
        "tip_x_over_d": float(tip[0] / test.d_mean) if np.size(tip) else None,
        "broken_bonds": [int(x) for x in test.rock.bonds.broken_counts()],
        "run_s": run_s,
        "share": share,
        "rows": rows,
    }
    print(
        f"{device}: {out['particles']} particles, {out['updates']} lamp updates, "
        f"{out['mismatching_updates']} mismatching (skin against from scratch), {out['resets']} resets; "
        f"bonds broken {out['broken_bonds']}; tip at {out['tip_x_over_d']:.2f} d"
    )
    kept = [r["kept"] + r["witnessed"] for r in rows[1:]] or [0]
    print(f"decisions kept per update: median {int(np.median(kept))}, min {min(kept)}")
    for name, t in share.items():
        print(
            f"mid-cut, {name}: cycle {t['cycle_s'] * 1e6:.1f} us, without the lamp "
            f"{t['cycle_without_lamp_s'] * 1e6:.1f} us, lamp share {t['lamp_share']:.1%} "
            f"(update every {t['update_every']} cycles)"
        )
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1))
    return 0 if out["mismatching_updates"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
