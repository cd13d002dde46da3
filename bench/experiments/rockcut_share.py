"""The rock cut's cycle with and without the wetted lamp, and the lamp's share (``RockCutting.time_cycle``), on the
slab as packed (pressure applied, no settling, no cut): the cost of the lamp's update against a DEM cycle's.

    PYTHONPATH=$PWD python bench/experiments/rockcut_share.py --device cpu --tiny
"""

import argparse
import json
import sys
from pathlib import Path

import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples"))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--device", default=None)
    ap.add_argument("--tiny", action="store_true")
    ap.add_argument("--pressure-mpa", type=float, default=20.0)
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    import rock_cutting as rc

    device = wp.get_device(args.device)
    out = {"device": str(device), "name": getattr(device, "name", "")}
    for mode in ("first", "all"):
        test = rc.RockCutting(
            rc.TINY if args.tiny else rc.STUDY, pressure=args.pressure_mpa * 1e6, surfaces=mode, device=device
        )
        t = test.time_cycle(repeats=args.repeats)
        out[mode] = t
        print(
            f"{mode}: cycle {t['cycle_s'] * 1e6:.1f} us, without the lamp {t['cycle_without_lamp_s'] * 1e6:.1f} us, "
            f"lamp share {t['lamp_share']:.1%} (update every {t['update_every']} cycles)",
            flush=True,
        )
    if args.out:
        with open(args.out, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
