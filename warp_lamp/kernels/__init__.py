"""Warp functions and kernels of warp_lamp (no Python API here)."""
