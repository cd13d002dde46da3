#!/usr/bin/env bash
# Issue 32: the wetted surface before (4149365, carried as .base/: git archive 4149365 warp_lamp | tar -x -C .base)
# and after (this tree) on one card in one run: graph replay per stage (SphereTest specimen, slot block, 1M lattice
# at cell 0.25; rho = r-bar), bitwise hashes of fluid maps, rays and counts on the bench and test scenes; after
# only: the classify stage with parts of the exact test skipped (where its time goes), the CUDA wetted and walls
# tests; before and after: the rock cut's slab on its lamp grid, stage by stage. Into $OUT/wetted32.json and $OUT/wetted32.log; the
# table last; last of all (after only, cut at 100 s): the rock cut's DEM cycle with and without the lamp, its share.
# About 7-8 minutes on an H100 (each step is cut at its timeout; the after bench's includes the three modules'
# compile), plus the DEM modules' compile for the share if no earlier part compiled them. To shorten: drop the
# tests (run bench/gpu/parts/wetted_cuda_tests.sh elsewhere) or the share: WETTED32_SKIP="profile tests".
LOG="$OUT/wetted32.log"
: >"$LOG"
T=/tmp/wetted32
mkdir -p $T
NOW="/root/site:$PWD"
BASE=""
if [ -d .base/warp_lamp ]; then
  BASE="$PWD/.base:/root/site"
else
  echo "no .base/warp_lamp: before rows skipped" | tee -a "$LOG"
fi
run() { # label, pythonpath, timeout [s], command...
  local label=$1 pp=$2 limit=$3
  shift 3
  local t0=$SECONDS
  echo "== $label ==" >>"$LOG"
  PYTHONPATH="$pp" timeout "$limit" "$@" >>"$LOG" 2>&1
  echo "   $label: rc $? in $((SECONDS - t0)) s" | tee -a "$LOG"
}
if [ -n "$BASE" ]; then
  run "before: bench" "$BASE" 150 python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters 0.5 \
    --repeats 20 --out $T/before_bench.json
  run "before: hashes" "$BASE" 45 python3 bench/experiments/wetted32.py hashes --device cuda:0 --out $T/before_hashes.json
  run "before: rock cut slab, stages" "$BASE" 40 python3 bench/experiments/rockcut_wetted_profile.py --device cuda:0 \
    --out $T/before_rockcut.json
fi
run "after: bench" "$NOW" 240 python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters 0.5 \
  --repeats 20 --out $T/after_bench.json
run "after: hashes" "$NOW" 45 python3 bench/experiments/wetted32.py hashes --device cuda:0 --out $T/after_hashes.json
skip() { case " ${WETTED32_SKIP:-} " in *" $1 "*) return 0 ;; esac; return 1; }
skip profile || run "after: exact test's parts" "$NOW" 40 python3 bench/experiments/wetted32.py profile --device cuda:0 --repeats 20 \
  --out $T/profile.json
run "after: rock cut slab, stages" "$NOW" 40 python3 bench/experiments/rockcut_wetted_profile.py --device cuda:0 \
  --out $T/rockcut.json
skip tests || run "after: CUDA wetted and walls tests" "$NOW" 100 python3 -m pytest -q -x -p no:cacheprovider -rfEs -k cuda \
  tests/test_wetted.py tests/test_walls.py
run "after: rock cut cycle, the lamp's share" "$NOW" 80 python3 bench/experiments/rockcut_share.py --device cuda:0 \
  --out $T/rockcut_share.json
PYTHONPATH="$NOW" python3 bench/experiments/wetted32.py combine --before-bench $T/before_bench.json \
  --after-bench $T/after_bench.json --before-hashes $T/before_hashes.json --after-hashes $T/after_hashes.json \
  --profile $T/profile.json --before-rockcut $T/before_rockcut.json --rockcut $T/rockcut.json --share $T/rockcut_share.json --out "$OUT/wetted32.json" 2>&1 | tee -a "$LOG"
