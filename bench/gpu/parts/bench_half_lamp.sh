#!/usr/bin/env bash
# The lamp half of warp-lamp bench (bench_lamp_half.sh).
BENCH_PART=lamp source "$(dirname "${BASH_SOURCE[0]}")/bench_lamp_half.sh"
