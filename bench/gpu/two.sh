#!/usr/bin/env bash
# Two lists of parts at once on a 2-GPU machine, one list per GPU (each sees its GPU as cuda:0), then every output
# in one tarball under $OUT (the device tool brings back few files):
#   bash bench/gpu/two.sh "cuda_tests" "speed_ab replay dumps"
set -u
OUT="${OUT:-/tmp/out}"
WORK="${LEASE_WORK:-/tmp/lease}"
mkdir -p "$OUT" "$WORK/g0" "$WORK/g1"
here="$(dirname "${BASH_SOURCE[0]}")"
(CUDA_VISIBLE_DEVICES=0 OUT="$WORK/g0" bash "$here/lease.sh" $1 > "$WORK/g0.log" 2>&1) &
(CUDA_VISIBLE_DEVICES=1 OUT="$WORK/g1" bash "$here/lease.sh" $2 > "$WORK/g1.log" 2>&1) &
wait
echo "== GPU 0: $1 =="; tail -30 "$WORK/g0.log"
echo "== GPU 1: $2 =="; tail -60 "$WORK/g1.log"
tar czf "$OUT/lease-$(date +%H%M%S).tgz" -C "$WORK" .
