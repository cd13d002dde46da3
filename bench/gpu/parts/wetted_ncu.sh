#!/usr/bin/env bash
# Nsight Compute source counters on the wetted surface's queued exact tests (area_ncu.sh with the wetted probe).
NCU_MODE=wetted NCU_KERNEL=wet_classify_queued source "$(dirname "${BASH_SOURCE[0]}")/area_ncu.sh"
