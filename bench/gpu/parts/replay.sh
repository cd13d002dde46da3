#!/usr/bin/env bash
# Issue 21's "speed unchanged": graph replays of the code before the rebuild (a7331c6, carried in .before/) and
# of today's, in one run, through the same script (public API only).
if [ -d .before/warp_lamp ]; then
  PYTHONPATH="/root/site:$PWD/.before" python3 bench/experiments/replay.py --label before --json "$OUT/replay_before.json" | tail -12
fi
python3 bench/experiments/replay.py --label after --json "$OUT/replay_after.json" | tail -14
[ -f "$OUT/replay_before.json" ] && python3 bench/experiments/replay.py --compare "$OUT/replay_before.json" "$OUT/replay_after.json"
