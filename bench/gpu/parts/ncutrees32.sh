#!/usr/bin/env bash
# Issue 32: wetted_ncu_mem on the 1M lattice for the trees before, scratch rows and this one (.base3, .tS, .).
NCU_TREES="${NCU_TREES:-before:.base3 scr:.tS here:.}" NCU_SCENES="${NCU_SCENES:-lattice}" \
  source bench/gpu/parts/wetted_ncu_mem.sh
