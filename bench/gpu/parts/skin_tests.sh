#!/usr/bin/env bash
# The skin's and the crossings' CUDA tests (tests/test_wetted_skin.py -k cuda), after a change to the crossings' searches.
python3 -m pytest -q -p no:cacheprovider -rfEs -k cuda tests/test_wetted_skin.py 2>&1 | tail -5
