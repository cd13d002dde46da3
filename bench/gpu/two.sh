#!/usr/bin/env bash
# Two lists of parts at once on a 2-GPU machine (multi.sh with two lists):
#   LEASE_SECONDS=500 bash bench/gpu/two.sh "cuda_tests" "speed_ab replay dumps"
exec bash "$(dirname "${BASH_SOURCE[0]}")/multi.sh" "$1" "$2"
