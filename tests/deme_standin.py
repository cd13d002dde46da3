"""A CPU stand-in for DEME 3's solver and tracker, with the call names and argument orders of the 3.0.19 bindings.

Its ``*ToDevice`` / ``*FromDevice`` calls read and write the memory behind an integer address, as DEME's do, so a
Warp array on the CPU exercises the adapter's device path (real DEME refuses host memory there). Positions and
quaternions go out as float32, as DEME's ``float3`` / ``float4``. The solver's step integrates the queued
accelerations (explicit Euler, no contacts) and then drops them, as DEME does after one step.
"""

from __future__ import annotations

import ctypes

import numpy as np


def _view(ptr: int, count: int) -> np.ndarray:
    return np.ctypeslib.as_array((ctypes.c_float * count).from_address(int(ptr)))


class StandInTracker:
    """DEME's ``Tracker`` for K owners: positions, (x, y, z, w) quaternions, masses, principal moments."""

    __module__ = "deme_standin"

    def __init__(self, positions, *, quats=None, masses=None, mois=None, first_id: int = 7):
        self.pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3).copy()
        k = len(self.pos)
        self.quat = np.tile([0.0, 0.0, 0.0, 1.0], (k, 1)) if quats is None else np.asarray(quats, float).copy()
        self.mass = np.ones(k) if masses is None else np.asarray(masses, dtype=np.float64)
        self.moi = np.ones((k, 3)) if mois is None else np.asarray(mois, dtype=np.float64).reshape(k, 3)
        self.ids = list(range(first_id, first_id + k))
        self.acc = None  # the queued next-step accelerations
        self.ang_acc = None
        self.calls = {}

    def _count(self, name: str) -> None:
        self.calls[name] = self.calls.get(name, 0) + 1

    def GetOwnerIDs(self):
        return list(self.ids)

    def Positions(self):
        self._count("Positions")
        return self.pos.astype(np.float32).astype(float).tolist()

    def OrientationQuaternions(self):
        self._count("OrientationQuaternions")
        return self.quat.astype(np.float32).astype(float).tolist()

    def Masses(self):
        return self.mass.tolist()

    def MOIs(self):
        return self.moi.tolist()

    def PositionsToDevice(self, pointer, capacity, device, validate=True):
        self._count("PositionsToDevice")
        k = len(self.pos)
        if capacity < k:
            raise ValueError("capacity too small")
        _view(pointer, 3 * k)[:] = self.pos.astype(np.float32).ravel()

    def OrientationQuaternionsToDevice(self, pointer, capacity, device, validate=True):
        self._count("OrientationQuaternionsToDevice")
        k = len(self.quat)
        if capacity < k:
            raise ValueError("capacity too small")
        _view(pointer, 4 * k)[:] = self.quat.astype(np.float32).ravel()

    def AddAcc(self, acc):
        self._count("AddAcc")
        self.acc = np.asarray(acc, dtype=np.float32).astype(np.float64).reshape(-1, 3)

    def AddAngAcc(self, ang):
        self._count("AddAngAcc")
        self.ang_acc = np.asarray(ang, dtype=np.float32).astype(np.float64).reshape(-1, 3)

    def AddAccFromDevice(self, source, source_device, validate=True):
        self._count("AddAccFromDevice")
        self.acc = _view(source, 3 * len(self.pos)).astype(np.float64).reshape(-1, 3).copy()

    def AddAngAccFromDevice(self, source, source_device, validate=True):
        self._count("AddAngAccFromDevice")
        self.ang_acc = _view(source, 3 * len(self.pos)).astype(np.float64).reshape(-1, 3).copy()


class StandInSolver:
    """DEME's ``DEMSolver``: ``DoStepDynamics`` moves each owner by its queued acceleration, then drops it."""

    __module__ = "deme_standin"

    def __init__(self, tracker: StandInTracker, dt: float = 1e-3):
        self.tracker, self.dt = tracker, dt
        self.vel = np.zeros_like(tracker.pos)
        self.applied = []  # the acceleration each step saw (None where nothing was queued)

    def DoStepDynamics(self):
        t = self.tracker
        self.applied.append(None if t.acc is None else t.acc.copy())
        if t.acc is not None:
            self.vel += t.acc * self.dt
        t.pos += self.vel * self.dt
        t.acc = t.ang_acc = None
