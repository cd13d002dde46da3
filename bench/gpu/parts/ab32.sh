#!/usr/bin/env bash
# Issue 32: wetted_bench's stages A/B(/C) in one run on one GPU: the trees in AB_TREES ("tag:dir ...", dir "." this
# tree, else a carried `git archive <commit> warp_lamp | tar -x -C <dir>`), specimen, slot block and 1M lattice
# (rho = r-bar), then the small scenes again in the same order; the table last.
T=/tmp/ab32-${CUDA_VISIBLE_DEVICES:-0}
mkdir -p $T
bench() { # tag, dir, extra args...
  local tag=$1 dir=$2; shift 2
  local pp="/root/site:$PWD"
  [ "$dir" != "." ] && pp="$PWD/$dir:/root/site"
  PYTHONPATH="$pp" timeout 300 python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters 0.5 \
    --repeats 20 "$@" --out $T/$tag.json > $T/$tag.log 2>&1
  echo "$tag rc=$?"
}
for t in ${AB_TREES:-before:.base3 after:.}; do bench "${t%%:*}-1" "${t#*:}"; done
for t in ${AB_TREES:-before:.base3 after:.}; do bench "${t%%:*}-2" "${t#*:}" --only specimen slot; done
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
