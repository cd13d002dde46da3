#!/usr/bin/env bash
# Issue 32: the crossings' and sparse launches' changes, A/B in one run: .base2/ (the code before them: git archive
# f68958f warp_lamp) against this tree as shipped (crossings listed, blocks of 64), without the list, and with blocks
# of 256; wetted_bench's stages on the specimen, slot block and 1M lattice (rho = r-bar); the small scenes twice.
T=/tmp/cross32
mkdir -p $T
bench() { # tag, pythonpath, extra args...
  local tag=$1 pp=$2; shift 2
  PYTHONPATH="$pp" timeout 200 python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters 0.5 \
    --repeats 20 "$@" --out $T/$tag.json > $T/$tag.log 2>&1
  echo "$tag rc=$?"
}
NOW="/root/site:$PWD"
bench before-1 "$PWD/.base2:/root/site"
bench shipped-1 "$NOW"
bench nolist-1 "$NOW" --cross-list 0
bench block256-1 "$NOW" --sparse-block 256
bench before-2 "$PWD/.base2:/root/site" --only specimen slot
bench shipped-2 "$NOW" --only specimen slot
bench nolist-2 "$NOW" --cross-list 0 --only specimen slot
bench block256-2 "$NOW" --sparse-block 256 --only specimen slot
cp $T/*.json "$OUT/" 2>/dev/null
python3 - $T <<'PY'
import glob, json, sys
rows = {}
for f in sorted(glob.glob(sys.argv[1] + "/*.json")):
    tag = f.rsplit("/", 1)[1][:-5]
    for r in json.load(open(f))["rows"]:
        rows.setdefault(r["scene"][:16], []).append((tag, r))
print("| scene | run | classify ms | cross ms | thin ms | update ms | moving ms | hash |")
print("| --- | --- | --- | --- | --- | --- | --- | --- |")
for scene, rs in rows.items():
    for tag, r in rs:
        print(f"| {scene} | {tag} | {r['all_classify_s']*1e3:.3f} | {r['all_cross_s']*1e3:.3f} | "
              f"{r['all_thin_s']*1e3:.3f} | {r['all_replay_s']*1e3:.3f} | {r['all_moving_s']*1e3:.3f} | "
              f"{r['fluid_hash'][:10]} |")
PY
