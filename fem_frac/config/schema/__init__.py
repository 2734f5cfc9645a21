"""The case file as typed, validated, immutable models (pydantic v2).

A section that is absent switches its stage off. Every model forbids unknown keys, so a
misspelt key is an error, never silently ignored. Units are the case's consistent system
(``units``); the descriptions give SI units.

One module per part of the case: :mod:`.base` (common types, the box selection),
:mod:`.geometry` (``mesh``), :mod:`.material` (``material``, ``regions``, ``plasticity``),
:mod:`.loads` (``load_curves``, ``boundary_conditions``, ``body_force``), :mod:`.analysis`,
:mod:`.fracture` (``fracture``, ``fragments``), :mod:`.obstacles` (``obstacles``),
:mod:`.probes` (``probes``) and :mod:`.case`
(``output``, ``reference``, the whole :class:`Case`). Every name is importable from here.
"""

from .analysis import (
    NEWMARK_BETA,
    NEWMARK_GAMMA,
    Analysis,
    DynamicAnalysis,
    Equilibrium,
    InitialVelocity,
    LinearSolver,
    QuasiStaticAnalysis,
    RayleighDamping,
    StaticAnalysis,
)
from .base import (
    BoxSelection,
    FiniteFloat,
    NonNegativeFloat,
    PositiveFloat,
    PositiveInt,
    PositiveVector3,
    Section,
    Vector3,
)
from .case import UNIT_SYSTEMS, Case, Output, Reference
from .fracture import Cohesive, Fracture, Fragments, Ground, Perturbation, Protect, Smoothing
from .geometry import (
    BoxGeometry,
    CylinderGeometry,
    Geometry,
    HollowCylinderGeometry,
    HollowSphereGeometry,
    MeshSection,
    SphereGeometry,
)
from .loads import (
    BUILTIN_CURVES,
    BodyForce,
    BoundaryCondition,
    ConstantCurve,
    CurveName,
    Displacement,
    Fixed,
    LoadCurve,
    Pressure,
    RampCurve,
    Symmetry,
    TableCurve,
    Traction,
)
from .material import Material, Plasticity, Region
from .obstacles import (
    MAX_OBSTACLES,
    BoxObstacle,
    CylinderObstacle,
    MeshObstacle,
    Obstacle,
    Orientation,
    PlaneObstacle,
    SphereObstacle,
)
from .probes import PROBE_FIELDS, Probe

__all__ = [
    "BUILTIN_CURVES",
    "MAX_OBSTACLES",
    "NEWMARK_BETA",
    "NEWMARK_GAMMA",
    "PROBE_FIELDS",
    "UNIT_SYSTEMS",
    "Analysis",
    "BodyForce",
    "BoundaryCondition",
    "BoxGeometry",
    "BoxObstacle",
    "BoxSelection",
    "Case",
    "ConstantCurve",
    "CurveName",
    "CylinderGeometry",
    "CylinderObstacle",
    "Displacement",
    "DynamicAnalysis",
    "Equilibrium",
    "FiniteFloat",
    "Fixed",
    "Cohesive",
    "Fracture",
    "Fragments",
    "Geometry",
    "Ground",
    "HollowCylinderGeometry",
    "HollowSphereGeometry",
    "InitialVelocity",
    "LinearSolver",
    "LoadCurve",
    "Material",
    "MeshObstacle",
    "MeshSection",
    "NonNegativeFloat",
    "Obstacle",
    "Orientation",
    "Output",
    "Perturbation",
    "PlaneObstacle",
    "Plasticity",
    "PositiveFloat",
    "PositiveInt",
    "PositiveVector3",
    "Pressure",
    "Probe",
    "Protect",
    "QuasiStaticAnalysis",
    "RampCurve",
    "RayleighDamping",
    "Reference",
    "Region",
    "Section",
    "Smoothing",
    "SphereGeometry",
    "SphereObstacle",
    "StaticAnalysis",
    "Symmetry",
    "TableCurve",
    "Traction",
    "Vector3",
]
