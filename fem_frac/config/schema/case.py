"""``output``, ``reference`` and the whole :class:`Case`."""

from __future__ import annotations

from typing import ClassVar, Literal

from pydantic import Field, field_validator

from .analysis import Analysis, StaticAnalysis
from .base import Section
from .fracture import Fracture, Fragments
from .geometry import MeshSection
from .loads import BodyForce, BoundaryCondition, LoadCurve
from .material import Material, Plasticity, Region
from .obstacles import MAX_OBSTACLES, Obstacle
from .probes import MAX_PROBES, Probe


class Output(Section):
    directory: str | None = Field(
        default=None, description="default: out/<case name> under the working directory; "
        "the run writes only inside it"
    )
    name: str | None = Field(
        default=None, description="base name of the .pvd and .vtu files, a plain file name "
        "(no '/', not '.' or '..'); default: case")
    crack_surface: bool = Field(
        default=False, description="with fracture: also write the crack faces as a surface "
        "series <name>_crack.pvd (written, empty until the first crack, at every output step)")
    compression: Literal["none", "zlib", "lzma"] = Field(
        default="none", description="compression of the .vtu data arrays: none (fastest to "
        "write), zlib (about half the size, about 6 times the writing time), lzma "
        "(smallest, slowest); docs/performance.md, 'Output'. With format vtkhdf: none or "
        "zlib (HDF5's gzip filter); lzma is refused")
    format: Literal["vtu", "vtkhdf"] = Field(
        default="vtu", description="file format of every series: vtu (a .pvd index and one "
        ".vtu per output step; every ParaView reads it) or vtkhdf (one <name>.vtkhdf per "
        "series, VTKHDF 2.0 with a time axis, appended step by step: faster to write and "
        "read, fewer files; needs h5py, and ParaView 5.12 or later); docs/output.md")

    #: Longest ``name`` (bytes, UTF-8): the files add up to 17 characters to it.
    NAME_MAX_BYTES: ClassVar[int] = 128

    @field_validator("directory")
    @classmethod
    def _a_path(cls, v: str | None) -> str | None:
        """A path the system can take (any path: the run writes only inside it)."""
        if v is not None and "\0" in v:
            raise ValueError("must not contain a NUL character")
        return v

    @field_validator("name")
    @classmethod
    def _plain_name(cls, v: str | None) -> str | None:
        """A plain file name: the files go into the output directory, never elsewhere."""
        if v is None:
            return v
        if not v:
            raise ValueError("must not be empty")
        if v in (".", ".."):
            raise ValueError(f"{v!r} is a directory, not a file name")
        if "/" in v or "\\" in v:
            raise ValueError("must be a plain file name, without '/' or '\\' (the output "
                             "directory is -o DIR or output.directory)")
        if any(ord(c) < 32 or ord(c) == 127 for c in v):
            raise ValueError("must not contain control characters (NUL, newline, ...)")
        if len(v.encode("utf-8", "surrogatepass")) > cls.NAME_MAX_BYTES:
            raise ValueError(f"is longer than {cls.NAME_MAX_BYTES} bytes")
        return v


class Reference(Section):
    """An exact solution the case is compared against; the error is reported in
    summary.json (see fem_frac/verify/reference.py for what each compares)."""

    solution: Literal["cantilever", "lame_sphere", "hill_sphere", "uniaxial_bar",
                      "free_vibration"]


UNIT_SYSTEMS = ("SI", "mm-N-s")


class Case(Section):
    """A whole scene. ``mesh`` and ``material`` are required; everything else has defaults."""

    title: str | None = None
    units: Literal["SI", "mm-N-s"] = "SI"
    mesh: MeshSection
    material: Material
    boundary_conditions: list[BoundaryCondition] = []
    body_force: BodyForce | None = None
    regions: list[Region] = []
    plasticity: Plasticity | None = None
    load_curves: dict[str, LoadCurve] = {}
    analysis: Analysis = StaticAnalysis()
    fracture: Fracture | None = None
    fragments: Fragments | None = None
    obstacles: list[Obstacle] = Field(
        default=[], max_length=MAX_OBSTACLES, description="rigid bodies and planes of the "
        "scene (fixed, or flying from an initial velocity); they need a fragments section")
    reference: Reference | None = None
    output: Output = Output()
    probes: list[Probe] = Field(
        default=[], max_length=MAX_PROBES, description="points and boundaries whose fields "
        "are written at every step to <name>_probes.csv")
