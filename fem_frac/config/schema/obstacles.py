"""``obstacles``: rigid bodies of the scene that are not made of the finite elements.

Each is a primitive (``sphere``, ``box``, ``cylinder``), a closed triangle surface read from
a file (``mesh``) or an infinite ``plane`` (the same thing as a plane of
``fragments.ground``). A body is either ``fixed: true`` (infinite mass: it never moves) or
has a ``density`` or a ``mass`` (exactly one), and then flies under gravity from its
``velocity`` and ``angular_velocity`` (about its centre of mass, world frame, rad/s).
``restitution`` and ``friction`` are those of its contacts. Every value is checked here
(lengths > 0, directions not zero); a mesh file is read and checked when the obstacles are
built (:mod:`fem_frac.rigid.obstacles`), its errors located at its ``file`` key.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import (
    BeforeValidator,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

from .base import (
    FiniteFloat,
    NonNegativeFloat,
    PositiveFloat,
    PositiveVector3,
    Section,
    Vector3,
    _as_tuple,
)

# More obstacles than this is a scene this code is not made for (every one is checked
# against every rigid body).
MAX_OBSTACLES = 1000

Restitution = Annotated[float, Field(ge=0.0, le=1.0, allow_inf_nan=False)]
Numbers = Annotated[tuple[FiniteFloat, ...], BeforeValidator(_as_tuple)]


def direction(v: tuple) -> tuple:
    """A direction: not zero, and of a length whose square neither overflows nor
    underflows (a unit vector is best)."""
    square = sum(c * c for c in v)
    if square == 0.0:
        raise ValueError("must not be zero (it gives a direction)")
    if not 1e-200 < square < 1e200:
        raise ValueError("must be of moderate length (a unit vector is best)")
    return v


class Orientation(Section):
    """A rotation from the obstacle's own axes to the world: ``axis`` and ``angle``
    (degrees, right-handed about the axis), or a ``quaternion`` ``[w, x, y, z]`` (any
    non-zero length; it is normalized)."""

    axis: Vector3 | None = None
    angle: FiniteFloat | None = Field(default=None, description="degrees")
    quaternion: Numbers | None = None

    @field_validator("axis")
    @classmethod
    def _axis(cls, v):
        return v if v is None else direction(v)

    @field_validator("quaternion")
    @classmethod
    def _quaternion(cls, v):
        if v is None:
            return v
        if len(v) != 4:
            raise ValueError(f"must be a list of 4 numbers [w, x, y, z], got {len(v)}")
        return direction(v)

    @model_validator(mode="after")
    def _one(self):
        pair = (self.axis is not None, self.angle is not None)
        if self.quaternion is not None and any(pair):
            raise ValueError("give 'axis' and 'angle', or 'quaternion', not both")
        if self.quaternion is None and not all(pair):
            raise ValueError("give 'axis' and 'angle' (degrees) together, or 'quaternion'")
        return self


class _Body(Section):
    """What every body obstacle has: fixed, or a density or a mass; its initial motion;
    the coefficients of its contacts."""

    fixed: bool = Field(default=False, description="true: infinite mass, never moves")
    density: PositiveFloat | None = None
    mass: PositiveFloat | None = None
    velocity: Vector3 = (0.0, 0.0, 0.0)
    angular_velocity: Vector3 = Field(default=(0.0, 0.0, 0.0),
                                      description="spin about the centre of mass, rad/s")
    restitution: Restitution = 0.5
    friction: NonNegativeFloat = 0.5

    @field_validator("density", "mass", "velocity", "angular_velocity")
    @classmethod
    def _moves(cls, v, info: ValidationInfo):
        """Given on a fixed obstacle, or a mass beside a density: refused at the key."""
        if v is not None and info.data.get("fixed"):
            raise ValueError(f"a fixed obstacle has infinite mass and never moves: drop "
                             f"'{info.field_name}' (or set fixed: false)")
        if info.field_name == "mass" and v is not None and info.data.get("density"):
            raise ValueError("give 'density' or 'mass', not both")
        return v

    @model_validator(mode="after")
    def _mass(self):
        if not self.fixed and self.density is None and self.mass is None:
            raise ValueError("give 'density' or 'mass' (or fixed: true)")
        return self


class SphereObstacle(_Body):
    """A ball of ``radius`` about ``center``."""

    type: Literal["sphere"]
    center: Vector3
    radius: PositiveFloat


class BoxObstacle(_Body):
    """A box of edge lengths ``size`` about ``center``, turned by ``orientation`` (its
    edges along the world axes without one)."""

    type: Literal["box"]
    center: Vector3
    size: PositiveVector3
    orientation: Orientation | None = None


class CylinderObstacle(_Body):
    """A solid cylinder of ``radius`` and ``height`` about ``center`` (the middle of its
    axis), its axis along ``axis``."""

    type: Literal["cylinder"]
    center: Vector3
    axis: Vector3 = (0.0, 0.0, 1.0)
    radius: PositiveFloat
    height: PositiveFloat

    @field_validator("axis")
    @classmethod
    def _axis(cls, v):
        return direction(v)


class MeshObstacle(_Body):
    """A closed triangle surface read from ``file`` (any surface format meshio reads:
    .stl, .obj, .ply, .off, .vtu, .vtk, .msh, ...; relative to the case file), in world
    coordinates."""

    type: Literal["mesh"]
    file: str

    @field_validator("file")
    @classmethod
    def _a_path(cls, v: str) -> str:
        if not v or "\0" in v:
            raise ValueError("must be a file name (not empty, no NUL character)")
        return v


class PlaneObstacle(Section):
    """An infinite fixed plane through ``point``, bodies kept on the side its ``normal``
    points to: the same as a plane of ``fragments.ground``."""

    type: Literal["plane"]
    point: Vector3 = (0.0, 0.0, 0.0)
    normal: Vector3 = (0.0, 0.0, 1.0)
    restitution: Restitution = 0.5
    friction: NonNegativeFloat = 0.5

    @field_validator("normal")
    @classmethod
    def _normal(cls, v):
        return direction(v)


Obstacle = Annotated[
    SphereObstacle | BoxObstacle | CylinderObstacle | MeshObstacle | PlaneObstacle,
    Field(discriminator="type"),
]
