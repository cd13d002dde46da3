#!/usr/bin/env bash
# Issue 32: the last wetted change, A/B in one run: .base3/ (the code before it: git archive <commit> warp_lamp | tar -x
# -C .base3) against this tree; wetted_bench's stages on the specimen, slot block and 1M lattice (rho = r-bar), the
# small scenes twice. wetted_bench's --cross-list 0 and --sparse-block 256 time the crossing list's and the block
# size's variants of this tree (measured 2026-11-28, bench/NOTES.md).
T=/tmp/cross32
mkdir -p $T
bench() { # tag, pythonpath, extra args...
  local tag=$1 pp=$2; shift 2
  PYTHONPATH="$pp" timeout 200 python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters 0.5 \
    --repeats 20 "$@" --out $T/$tag.json > $T/$tag.log 2>&1
  echo "$tag rc=$?"
}
NOW="/root/site:$PWD"
bench before-1 "$PWD/.base3:/root/site"
bench shipped-1 "$NOW"
bench before-2 "$PWD/.base3:/root/site" --only specimen slot
bench shipped-2 "$NOW" --only specimen slot
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
