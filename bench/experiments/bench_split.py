"""``warp-lamp bench`` in two halves that run at once on two GPUs of one host, then merged into the CLI's JSON: the
speed, sweep and error sections (``--part lamp``) and the four mode sections (``--part modes``), each on the GPU it
sees as cuda:0. The merged file is what ``warp-lamp bench --json`` writes (plot it with ``--from-json``).

    python bench/experiments/bench_split.py --part lamp --out lamp.json      # on GPU 0
    python bench/experiments/bench_split.py --part modes --out modes.json    # on GPU 1
    python bench/experiments/bench_split.py --merge lamp.json modes.json --out bench.json
"""

import argparse
import json
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=("lamp", "modes"))
    ap.add_argument("--merge", nargs=2, metavar=("LAMP", "MODES"))
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    if args.merge:
        lamp, modes = (json.loads(Path(p).read_text()) for p in args.merge)
        lamp.update({k: modes[k] for k in ("small_body", "area", "wetted", "frames")})
        Path(args.out).write_text(json.dumps(lamp, indent=1, allow_nan=False))
        return
    import warp as wp

    from warp_lamp.bench import modes, speed

    wp.init()
    if args.part == "lamp":
        result = speed.bench_lamp([args.device], progress=False, modes=False)
    else:
        result = modes.bench_modes([args.device], progress=False)
    Path(args.out).write_text(json.dumps(result, indent=1, allow_nan=False))


if __name__ == "__main__":
    main()
