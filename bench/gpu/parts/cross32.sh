#!/usr/bin/env bash
# Issue 32: the last wetted change, A/B in one run: .base3/ (the code before it: git archive <commit> warp_lamp | tar -x
# -C .base3) against this tree ("shipped"); ab32.sh's stages and table.
AB_TREES="before:.base3 shipped:." source bench/gpu/parts/ab32.sh
