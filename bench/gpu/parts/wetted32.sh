#!/usr/bin/env bash
# Issue 32: the wetted surface before (4149365, carried as .base/: git archive 4149365 warp_lamp | tar -x -C .base)
# and after (this tree) on one card in one run: graph replay per stage (SphereTest specimen, slot block, 1M lattice
# at cell 0.25; rho = r-bar), bitwise hashes of fluid maps, rays and counts on the bench and test scenes, then the
# CUDA wetted and walls tests. Everything into $OUT/wetted32.json and $OUT/wetted32.log; the table last.
LOG="$OUT/wetted32.log"
: >"$LOG"
T=/tmp/wetted32
mkdir -p $T
NOW="/root/site:$PWD"
if [ -d .base/warp_lamp ]; then
  BASE="$PWD/.base:/root/site"
else
  echo "no .base/warp_lamp: before rows skipped" | tee -a "$LOG"
  BASE=""
fi
run() {  # label, pythonpath, timeout, command...
  local label=$1 pp=$2 limit=$3
  shift 3
  echo "== $label ==" >>"$LOG"
  PYTHONPATH="$pp" timeout "$limit" "$@" >>"$LOG" 2>&1
  echo "   $label: rc $?" | tee -a "$LOG"
}
if [ -n "$BASE" ]; then
  run "before: bench" "$BASE" 170 python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters 0.5 \
    --repeats 30 --out $T/before_bench.json
  run "before: hashes" "$BASE" 60 python3 bench/experiments/wetted32.py hashes --device cuda:0 --out $T/before_hashes.json
fi
run "after: bench" "$NOW" 170 python3 bench/experiments/wetted_bench.py --device cuda:0 --rho-diameters 0.5 \
  --repeats 30 --out $T/after_bench.json
run "after: hashes" "$NOW" 60 python3 bench/experiments/wetted32.py hashes --device cuda:0 --out $T/after_hashes.json
run "after: CUDA wetted and walls tests" "$NOW" 120 python3 -m pytest -q -x -p no:cacheprovider -rfEs -k cuda \
  tests/test_wetted.py tests/test_walls.py
tail -3 "$LOG" | sed 's/^/   /'
PYTHONPATH="$NOW" python3 bench/experiments/wetted32.py combine --before-bench $T/before_bench.json \
  --after-bench $T/after_bench.json --before-hashes $T/before_hashes.json --after-hashes $T/after_hashes.json \
  --out "$OUT/wetted32.json" 2>&1 | tee -a "$LOG"
