#!/usr/bin/env bash
# Nsight Compute's SIMT efficiency and scheduler figures on the area criterion's cell pass (wetted_ncu_div.sh's).
NCU_MODE=area NCU_KERNEL=area_sides source "$(dirname "${BASH_SOURCE[0]}")/wetted_ncu_div.sh"
