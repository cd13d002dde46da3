#!/usr/bin/env bash
# Two lists of parts at once on a 2-GPU machine, one list per GPU (each sees its GPU as cuda:0), under one deadline,
# every output kept in one tarball under $OUT that is refreshed every 20 s (the device tool brings back few files,
# and what a killed command left under $OUT still comes back):
#   LEASE_SECONDS=500 bash bench/gpu/two.sh "cuda_tests" "speed_ab replay dumps"
# A list "-" leaves that GPU idle. lease.sh gives each part the time left before the deadline, at most PART_TIMEOUT.
set -u
OUT="${OUT:-/tmp/out}"
WORK="${LEASE_WORK:-/tmp/lease}"
tag="$(date +%H%M%S)"
mkdir -p "$OUT" "$WORK/g0" "$WORK/g1"
here="$(dirname "${BASH_SOURCE[0]}")"
export LEASE_END=$(( $(date +%s) + ${LEASE_SECONDS:-540} ))
snap() { tar czf "$OUT/.lease.tgz" -C "$WORK" . 2>/dev/null && mv "$OUT/.lease.tgz" "$OUT/lease-$tag.tgz"; }
( while sleep 20; do snap; done ) >/dev/null 2>&1 & ticker=$!
pids=()
if [ "$1" != "-" ]; then (CUDA_VISIBLE_DEVICES=0 OUT="$WORK/g0" bash "$here/lease.sh" $1 > "$WORK/g0.log" 2>&1) & pids+=($!); fi
if [ "$2" != "-" ]; then (CUDA_VISIBLE_DEVICES=1 OUT="$WORK/g1" bash "$here/lease.sh" $2 > "$WORK/g1.log" 2>&1) & pids+=($!); fi
wait "${pids[@]}"
kill "$ticker" 2>/dev/null
snap
[ "$1" != "-" ] && { echo "== GPU 0: $1 =="; tail -40 "$WORK/g0.log"; }
[ "$2" != "-" ] && { echo "== GPU 1: $2 =="; tail -40 "$WORK/g1.log"; }
exit 0
