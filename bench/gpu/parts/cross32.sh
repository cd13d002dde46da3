#!/usr/bin/env bash
# Issue 32: the crossings' second search, A/B in one run: .base2/ (the code before it: git archive f68958f warp_lamp)
# against this tree, wetted_bench's stages on the specimen, slot block and 1M lattice (rho = r-bar), alternated twice.
T=/tmp/cross32
mkdir -p $T
for round in 1 2; do
  only=""; [ $round = 2 ] && only="--only specimen slot"
  for side in before after; do
    pp="/root/site:$PWD"; [ "$side" = before ] && pp="$PWD/.base2:/root/site"
    PYTHONPATH="$pp" timeout 200 python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters 0.5 \
      --repeats 20 $only --out $T/$side-$round.json > $T/$side-$round.log 2>&1
    echo "$side $round rc=$?"
  done
done
cp $T/*.json "$OUT/" 2>/dev/null
python3 - $T <<'PY'
import glob, json, sys
rows = {}
for f in sorted(glob.glob(sys.argv[1] + "/*.json")):
    tag = f.rsplit("/", 1)[1][:-5]
    for r in json.load(open(f))["rows"]:
        rows.setdefault(r["scene"][:16], []).append((tag, r))
print("| scene | run | cross ms | thin ms | classify ms | update ms | counts hash |")
print("| --- | --- | --- | --- | --- | --- | --- |")
for scene, rs in rows.items():
    for tag, r in rs:
        h = r.get("counts_hash", r.get("fluid_hash", ""))[:10]
        print(f"| {scene} | {tag} | {r['all_cross_s']*1e3:.3f} | {r['all_thin_s']*1e3:.3f} | "
              f"{r['all_classify_s']*1e3:.3f} | {r['all_replay_s']*1e3:.3f} | {h} |")
PY
