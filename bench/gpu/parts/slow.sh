#!/usr/bin/env bash
# The tests marked slow (deselected by default): the study's two rock cuts on CUDA, about 2 minutes on an H100.
#
#   OUT=/tmp/out bash bench/gpu/parts/slow.sh                   # the slow tests on the CUDA devices
#   SLOW_DEVICES=all OUT=/tmp/out bash bench/gpu/parts/slow.sh  # and on the CPU too (about 6 minutes more)
#   SLOW_DEVICES=cpu OUT=/tmp/out bash bench/gpu/parts/slow.sh  # the CPU alone (the machine has no GPU)
#
# Writes $OUT/slow.log (pytest's output, each test's time) and $OUT/slow.json (rc, outcome per test, seconds);
# prints the outcomes last.
source "$(dirname "${BASH_SOURCE[0]}")/../preamble.sh"
case "${SLOW_DEVICES:-cuda}" in
  all) select=() ;;
  cpu) select=(-k "cpu") ;;
  *) select=(-k "not cpu") ;;
esac
t0=$(date +%s)
python3 -m pytest -m slow -q -p no:cacheprovider -rA --durations=0 "${select[@]}" --junitxml "$OUT/slow.xml" tests \
  > "$OUT/slow.log" 2>&1
rc=$?
python3 - "$OUT" "$rc" "$(( $(date +%s) - t0 ))" <<'PY'
import json, sys, xml.etree.ElementTree as ET
from pathlib import Path
out, rc, seconds = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
tests = []
xml = out / "slow.xml"
if xml.exists():
    for case in ET.parse(xml).iter("testcase"):
        kind = next((c.tag for c in case if c.tag in ("failure", "error", "skipped")), "passed")
        tests.append({"test": f"{case.get('classname')}::{case.get('name')}", "outcome": kind, "s": float(case.get("time", 0))})
    xml.unlink()  # one JSON and one log come back
json.dump({"rc": rc, "seconds": seconds, "tests": tests}, open(out / "slow.json", "w"), indent=1)
print(f"rc={rc}, {seconds} s")
print("| test | outcome | s |")
for t in tests:
    print(f"| {t['test']} | {t['outcome']} | {t['s']:.1f} |")
PY
tail -5 "$OUT/slow.log"
