#!/usr/bin/env bash
# Issue 32: ab32 over variant trees (AB_VARIANTS, "tag:dir ..."; default the queued kernel's threads per SM at
# 128 and 512 beside this tree), for a knob whose kernels are unchanged.
AB_TREES="${AB_VARIANTS:-t128:.t128 here:. t512:.t512}" source bench/gpu/parts/ab32.sh
