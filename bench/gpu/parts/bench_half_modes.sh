#!/usr/bin/env bash
# The modes half of warp-lamp bench (bench_lamp_half.sh).
BENCH_PART=modes source "$(dirname "${BASH_SOURCE[0]}")/bench_lamp_half.sh"
