"""A CPU stand-in for DEME 3's solver and tracker, with the call names and argument orders of the 3.0.19 bindings.

Its ``*ToDevice`` / ``*FromDevice`` calls read and write the memory behind an integer address, as DEME's do, so a
Warp array on the CPU exercises the adapter's device path (real DEME refuses host memory there). Positions and
quaternions go out as float32, as DEME's ``float3`` / ``float4``. The solver's step integrates the queued
accelerations (explicit Euler, no contacts) and then drops them, as DEME does after one step.
"""

from __future__ import annotations

import ctypes

import numpy as np

#: The public names of deme 3.0.19's bindings (``dir()`` of the wheel's classes): the stand-in answers only
#: these, so a call the real DEME lacks fails here too.
SOLVER_NAMES = frozenset(
    """
    AddBCPlane AddClumps AddCombinedFromTemplate AddExternalObject AddFamilyPrescribedAcc
    AddFamilyPrescribedAngAcc AddKernelInclude AddMeshFromTemplate AddOwnerNextStepAcc
    AddOwnerNextStepAccFromDevice AddOwnerNextStepAngAcc AddOwnerNextStepAngAccFromDevice AddShellMesh
    AddWavefrontMeshObject AddWavefrontShellObject ChangeClumpFamily ChangeFamily ChangeFamilyWhen ClearCache
    ClearThreadCollaborationStats ClearTimingStats CorrectFamilyAngVel CorrectFamilyLinVel CorrectFamilyPosition
    CorrectFamilyQuaternion CreateInspector DefineContactForceModel DisableAdaptiveBinSize
    DisableAdaptiveUpdateFreq DisableAllMeshWearModels DisableContactBetweenFamilies DisableFamilyOutput
    DisableJitifyClumpTemplates DisableJitifyMassProperties DisableMeshWearModel DisableTrianglePVTracking
    DoDynamics DoDynamicsThenSync DoStepDynamics Duplicate EnableContactBetweenFamilies
    EnableContactWildcardOutput EnableMeshPatchColorOutput EnableMeshWearModel EnableOwnerWildcardOutput
    EnsureKernelErrMsgLineNum FlushMeshWearModels GetAllOwnerWildcardValue GetAvgSphContacts GetBinNum
    GetBinSize GetCachedMesh GetClumpContacts GetClumpPositionsHandover GetCombinedInstanceInfo
    GetContactDetailedInfo GetContactForceModel GetContacts GetCudaDebugSync GetDeviceMemUsageDynamic
    GetDeviceMemUsageKinematic GetFamilyOwnerWildcardValue GetGPUDeviceIDs GetGPUTimersEnabled
    GetHostMemUsageDynamic GetHostMemUsageKinematic GetInitStatus GetJitStringSubs GetJitifyOptions
    GetMeshNodesGlobal GetNumClumps GetNumCombinedInstances GetNumContacts GetNumOwners GetOwnerAcc
    GetOwnerAccToDevice GetOwnerAngAcc GetOwnerAngAccGlobalToDevice GetOwnerAngAccLocalToDevice GetOwnerAngVel
    GetOwnerAngVelGlobalToDevice GetOwnerAngVelLocalToDevice GetOwnerContactClumps GetOwnerContactForces
    GetOwnerContactWrench GetOwnerContactWrenchToDevice GetOwnerFamily GetOwnerFamilyToDevice GetOwnerMOI
    GetOwnerMOIToDevice GetOwnerMass GetOwnerMassToDevice GetOwnerOriQ GetOwnerOriQToDevice GetOwnerPosition
    GetOwnerPositionToDevice GetOwnerVelocity GetOwnerVelocityToDevice GetOwnerWildcardValue
    GetOwnerWildcardValueToDevice GetSimTime GetTimeStepSize GetTrackedOwnerTrianglePV GetUpdateFreq
    GetVisualizationFrame GetVisualizationScene GetWhetherForceCollectInKernel Initialize
    InstructBoxDomainBoundingBC InstructBoxDomainDimension InstructNumOwners LoadClumpType LoadCombinedClumpType
    LoadCombinedMeshType LoadMaterial LoadMeshType LoadSphereType MarkFamilyPersistentContact
    MarkFamilyPersistentContactBoth MarkFamilyPersistentContactEither MarkPersistentContact
    PrintKinematicScratchSpaceUsage PurgeFamily ReadContactForceModel ReleaseFlattenedArrays
    RemoveFamilyPersistentContact RemoveFamilyPersistentContactBoth RemoveFamilyPersistentContactEither
    RemoveKernelInclude RemovePersistentContact RequestContactUpdate SetAdaptiveBinSizeAcc
    SetAdaptiveBinSizeDelaySteps SetAdaptiveBinSizeLowerProactivity SetAdaptiveBinSizeMaxRate
    SetAdaptiveBinSizeUpperProactivity SetAdaptiveTimeStepType SetAllowIntraCombinedOwnerContacts
    SetCDMaxUpdateFreq SetCDNumStepsMaxDriftAheadOfAvg SetCDNumStepsMaxDriftHistorySize
    SetCDNumStepsMaxDriftMultipleOfAvg SetCDUpdateFreq SetCollectAccRightAfterForceCalc SetContactOutputContent
    SetContactOutputFormat SetContactWildcardValue SetContactWildcards SetCudaDebugSync SetDEME2MeshBehavior
    SetErrorOutAngularVelocity SetErrorOutAvgContacts SetErrorOutVelocity SetExpandFactor SetExpandSafetyAdder
    SetExpandSafetyMultiplier SetExpandSafetyType SetFamilyClumpMaterial SetFamilyContactWildcardValue
    SetFamilyContactWildcardValueBoth SetFamilyContactWildcardValueEither SetFamilyExtraMargin SetFamilyFixed
    SetFamilyMeshMaterial SetFamilyOwnerWildcardValue SetFamilyPrescribedAngVel SetFamilyPrescribedAngVelX
    SetFamilyPrescribedAngVelY SetFamilyPrescribedAngVelZ SetFamilyPrescribedLinVel SetFamilyPrescribedLinVelX
    SetFamilyPrescribedLinVelY SetFamilyPrescribedLinVelZ SetFamilyPrescribedPosition
    SetFamilyPrescribedPositionX SetFamilyPrescribedPositionY SetFamilyPrescribedPositionZ
    SetFamilyPrescribedQuaternion SetForceCalcThreadsPerBlock SetGPUTimersEnabled SetGravitationalAcceleration
    SetInitBinNumTarget SetInitBinSize SetInitBinSizeAsMultipleOfSmallestSphere SetInitTimeStep SetIntegrator
    SetJitifyClumpTemplates SetJitifyMassProperties SetJitifyOptions SetKernelInclude SetMaterialPropertyPair
    SetMaxSphereInBin SetMaxTriTriPenetration SetMaxTriangleInBin SetMaxVelocity SetMeshOutputContent
    SetMeshOutputFormat SetMeshParticlesLowPoly SetMeshPatchCenterOffsetAlpha SetMeshPatchCenterOffsetBeta
    SetMeshPatchCenterOffsetGamma SetMeshPatchLocations SetMeshPatchLocationsFromDevice SetMeshUniversalContact
    SetNoForceRecord SetOutputContent SetOutputFormat SetOwnerAngVel SetOwnerAngVelFromDevice
    SetOwnerAngVelGlobalFromDevice SetOwnerFamily SetOwnerOriQ SetOwnerOriQFromDevice SetOwnerPosition
    SetOwnerPositionFromDevice SetOwnerVelocity SetOwnerVelocityFromDevice SetOwnerWildcardValue
    SetOwnerWildcards SetPersistentContact SetSimTime SetSimplePatchCombination SetSortContactPairs
    SetStablePatchIslandIDs SetTimeStepSize SetTriNodeRelPos SetTriNodeRelPosFromDevice
    SetTriTriContactRejectionRatio SetTriTriPenetration SetTrianglePVTrackingOwners SetUseAngularVelocityMargin
    SetVerbosity ShowAnomalies ShowMemStats ShowThreadCollaborationStats ShowTimingStats SyncMemoryTransfer
    Track UpdateClumps UpdateSimParams UpdateStepSize UpdateTriNodeRelPos UpdateTriNodeRelPosFromDevice
    UseAdaptiveBinSize UseAdaptiveUpdateFreq UseAutomaticMeshPatchLocations UseFrictionalHertzianModel
    UseFrictionlessHertzianModel UseHertzConstTimeStep WaitForPendingOutput WriteAnalyticalFile WriteClumpFile
    WriteContactFile WriteContactFileIncludingPotentialPairs WriteMeshFile WriteSphereFile
    """.split()
)
TRACKER_NAMES = frozenset(
    """
    AddAcc AddAccFromDevice AddAngAcc AddAngAccFromDevice AngVelGlobal AngVelLocal AngularVelocitiesGlobal
    AngularVelocitiesGlobalToDevice AngularVelocitiesLocal AngularVelocitiesLocalToDevice ContactAcc
    ContactAccelerations ContactAccelerationsToDevice ContactAngAccGlobal ContactAngAccLocal
    ContactAngularAccelerationsGlobal ContactAngularAccelerationsGlobalToDevice ContactAngularAccelerationsLocal
    ContactAngularAccelerationsLocalToDevice ContactWrenches ContactWrenchesToDevice FamiliesToDevice
    GetContactClumps GetContactForces GetContactForcesAndGlobalTorque GetContactForcesAndGlobalTorqueForAll
    GetContactForcesAndGlobalTorqueForAllToDevice GetContactForcesAndLocalTorque
    GetContactForcesAndLocalTorqueForAll GetContactForcesAndLocalTorqueForAllToDevice GetContactForcesForAll
    GetContactForcesForAllToDevice GetFamilies GetFamily GetMesh GetMeshNodesGlobal GetOwnerID GetOwnerIDs
    GetOwnerWildcardValue GetOwnerWildcardValues MOI MOIs MOIsToDevice Mass Masses MassesToDevice OriQ
    OrientationQuaternions OrientationQuaternionsToDevice OwnerWildcardValuesToDevice Pos Positions
    PositionsToDevice SetAngVel SetAngularVelocitiesFromDevice SetAngularVelocitiesGlobalFromDevice SetFamily
    SetOriQ SetOrientationQuaternionsFromDevice SetOwnerWildcardValue SetOwnerWildcardValues SetPos
    SetPositionsFromDevice SetVel SetVelocitiesFromDevice UpdateMesh UpdateMeshByIncrement
    UpdateMeshByIncrementFromDevice UpdateMeshFromDevice UpdateMeshPatchLocations
    UpdateMeshPatchLocationsFromDevice UseAutomaticMeshPatchLocations Vel Velocities VelocitiesToDevice
    """.split()
)
CONTACT_NAMES = frozenset(
    """
    Get GetAGeo GetAOwner GetAOwnerFamily GetBGeo GetBOwner GetBOwnerFamily GetContactType GetForce GetNormal
    GetPoint GetTorque
    """.split()
)


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


class StandInContacts:
    """DEME's ``ContactInfoContainer``: owner ids A and B of each touching pair and the force on A."""

    def __init__(self, a, b, force):
        self.a, self.b, self.force = a, b, force

    def GetAOwner(self):
        return self.a.tolist()

    def GetBOwner(self):
        return self.b.tolist()

    def GetForce(self):
        return self.force.tolist()


class StandInSolver:
    """DEME's ``DEMSolver``: building calls record what they get; ``DoStepDynamics`` moves each owner by its queued
    acceleration, then drops it; ``GetContactDetailedInfo`` gives linear springs (stiffness ``k``) on the overlaps
    of the tracker's spheres (all pairs: small bodies only)."""

    __module__ = "deme_standin"

    def __init__(self, tracker: StandInTracker | None = None, dt: float = 1e-3, *, k: float = 1e6):
        self.tracker, self.dt, self.k = tracker, dt, k
        self.vel = None if tracker is None else np.zeros_like(tracker.pos)
        self.applied = []  # the acceleration each step saw (None where nothing was queued)
        self.settings = {}
        self.templates = []
        self.initialized = False

    def __getattr__(self, name):
        # Settings (SetVerbosity, InstructBoxDomainDimension, ...) are recorded, not acted on.
        if name in SOLVER_NAMES:
            return lambda *args, **kwargs: self.settings.__setitem__(name, args)
        raise AttributeError(name)

    def LoadMaterial(self, props):
        return dict(props)

    def LoadSphereType(self, mass, radius, material):
        self.templates.append((float(mass), float(radius)))
        return len(self.templates) - 1

    def AddClumps(self, types, xyz):
        return (list(types), np.asarray(xyz, dtype=np.float64))

    def Track(self, batch):
        types, xyz = batch
        mass = np.array([self.templates[t][0] for t in types])
        self.radii = np.array([self.templates[t][1] for t in types])
        moi = 0.4 * mass * self.radii**2
        self.tracker = StandInTracker(xyz, masses=mass, mois=np.repeat(moi[:, None], 3, axis=1))
        self.vel = np.zeros_like(xyz)
        return self.tracker

    def SetInitTimeStep(self, dt):
        self.dt = float(dt)

    def GetTimeStepSize(self):
        return self.dt

    def DoDynamics(self, duration):
        for _ in range(max(1, round(duration / self.dt))):
            self.DoStepDynamics()

    def Initialize(self):
        self.initialized = True

    def DoStepDynamics(self):
        t = self.tracker
        self.applied.append(None if t.acc is None else t.acc.copy())
        if t.acc is not None:
            self.vel += t.acc * self.dt
        t.pos += self.vel * self.dt
        t.acc = t.ang_acc = None

    def GetContactDetailedInfo(self):
        x = self.tracker.pos
        d = x[:, None] - x[None]
        dist = np.linalg.norm(d, axis=2)
        overlap = self.radii[:, None] + self.radii[None] - dist
        i, j = np.nonzero(np.triu(overlap > 0, 1))
        force = self.k * overlap[i, j][:, None] * d[i, j] / dist[i, j][:, None]
        ids = np.asarray(self.tracker.ids)
        return StandInContacts(ids[i], ids[j], force)


class StandInDeme:
    """The ``deme`` module: ``__version__`` and ``DEMSolver``."""

    __version__ = "stand-in"

    @staticmethod
    def DEMSolver(n_gpus=1):
        return StandInSolver()
