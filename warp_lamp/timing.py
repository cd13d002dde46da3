"""Timing primitives and the run header shared by the benchmarks, the ``bench/`` scripts and the examples.

Every figure is a median of repeats after a warm-up, with the device synchronised (host clock) or timed between
CUDA events (device time, without host overhead).
"""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

__all__ = ["Progress", "run_header", "time_median", "time_median_events"]


def time_median(fn, device, *, repeats: int, warmup: int = 2) -> float:
    """Median seconds of ``fn()`` with the device synchronised around each call, after ``warmup`` calls."""
    device = wp.get_device(device)
    for _ in range(warmup):
        fn()
    wp.synchronize_device(device)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def time_median_events(fn, device, *, repeats: int, warmup: int = 3) -> float:
    """Median seconds between CUDA events around ``fn()``, after a warm-up: device time, without host overhead.
    On the CPU, :func:`time_median`."""
    device = wp.get_device(device)
    if not device.is_cuda:
        return time_median(fn, device, repeats=repeats, warmup=warmup)
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        e0 = wp.Event(device, enable_timing=True)
        e1 = wp.Event(device, enable_timing=True)
        wp.record_event(e0)
        fn()
        wp.record_event(e1)
        wp.synchronize_event(e1)
        times.append(wp.get_event_elapsed_time(e0, e1) / 1e3)
    return float(np.median(times))


def _git_commit() -> str:
    if os.environ.get("WARP_LAMP_COMMIT"):  # the device machine gets a copy of the tree without .git
        return os.environ["WARP_LAMP_COMMIT"]
    try:
        root = Path(__file__).resolve().parent.parent
        return subprocess.check_output(
            ["git", "rev-parse", "HEAD"], cwd=root, text=True, stderr=subprocess.DEVNULL
        ).strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def run_header(devices=()) -> dict:
    """What a result file needs to say where it came from: UTC date, Warp version, git commit (or the
    ``WARP_LAMP_COMMIT`` environment variable where there is no checkout), host, and each device's name."""
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "warp_version": wp.__version__,
        "git_commit": _git_commit(),
        "host": platform.node(),
        "device_names": {wp.get_device(d).alias: wp.get_device(d).name for d in devices},
    }


class Progress:
    """A progress bar on stderr: tqdm when installed (the ``progress`` extra), else a one-line counter."""

    def __init__(self, total: int, desc: str, *, enabled: bool = True):
        self.bar = None
        self.total, self.done, self.enabled, self.desc = total, 0, enabled, desc
        if enabled:
            try:
                from tqdm import tqdm

                self.bar = tqdm(total=total, desc=desc, file=sys.stderr, leave=False)
            except ImportError:
                pass

    def step(self, what: str) -> None:
        """One unit of work done; ``what`` names it."""
        self.done += 1
        if self.bar is not None:
            self.bar.set_postfix_str(what)
            self.bar.update(1)
        elif self.enabled:
            print(f"\r{self.desc} {self.done}/{self.total} {what:<40}", end="", file=sys.stderr, flush=True)

    def close(self) -> None:
        """End the bar's line."""
        if self.bar is not None:
            self.bar.close()
        elif self.enabled:
            print(file=sys.stderr)
