"""``fracture`` (cracks by face separation) and ``fragments`` (pieces that become rigid)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from .base import BoxSelection, NonNegativeFloat, PositiveFloat, PositiveInt, Section, Vector3


class Smoothing(Section):
    """How element stresses are smoothed before the strength check. ``neighbours``: the
    volume-weighted mean over the elements reachable through shared faces whose centroids lie
    within ``length`` (or ``rings`` face-steps); ``nodal``: projection to the vertices
    (volume-weighted) and back. Smoothing never reaches across a crack."""

    method: Literal["neighbours", "nodal"] = "neighbours"
    length: PositiveFloat | None = Field(
        default=None, description="smoothing radius in the case's length unit (physical: "
        "set it from the material, e.g. a few grain sizes or the process-zone size)")
    rings: Annotated[int, Field(ge=0, le=10)] | None = Field(
        default=None, description="or: neighbour rings through shared faces (0: none)")

    @model_validator(mode="after")
    def _one_size(self):
        if (self.length is None) == (self.rings is None):
            raise ValueError("give exactly one of 'length' or 'rings'")
        return self


class Perturbation(Section):
    """Seeded random tilt of every crack normal, uniform on the cap of half-angle
    ``angle`` (degrees) around the principal direction; the same seed gives the same run."""

    angle: Annotated[float, Field(gt=0.0, lt=90.0)]
    seed: Annotated[int, Field(ge=0, le=2**64 - 1)] = 0


class Protect(Section):
    """Where no crack may open: the vertices of a named boundary, of a mesh volume group
    (``subdomain``) or of the elements whose centroid lies in ``box``, or the vertices that
    lie in the box ``vertices`` (bounds included; unlike ``box`` it protects nothing
    outside it, so a mesh surface just outside it stays free to open)."""

    boundary: str | None = None
    subdomain: str | None = None
    box: BoxSelection | None = None
    vertices: BoxSelection | None = None

    @model_validator(mode="after")
    def _one(self):
        given = (self.boundary, self.subdomain, self.box, self.vertices)
        if sum(x is not None for x in given) != 1:
            raise ValueError("give exactly one of 'boundary', 'subdomain', 'box' or 'vertices'")
        return self


class CrackPlane(Section):
    """A plane through ``point`` with ``normal`` in which cracks may open
    (:mod:`fem_frac.fracture.planes`)."""

    point: Vector3
    normal: Vector3

    @model_validator(mode="after")
    def _normal(self):
        square = sum(c * c for c in self.normal)
        if not 1e-200 < square < 1e200:
            raise ValueError("normal must be non-zero and of moderate length (a unit vector "
                             "is best)")
        return self


class Cohesive(Section):
    """The traction-separation law of crack faces that carry a fracture energy.

    ``law``: how the effective traction softens with the effective opening after its peak
    (``linear`` to zero at ``2 G_c / tensile_strength``, or ``exponential``, truncated where
    it reaches zero); ``shear_weight`` (beta): the weight of the sliding in the effective
    opening ``sqrt(<d_n>^2 + beta^2 |d_s|^2)`` (Ortiz & Pandolfi 1999); ``penalty``: the
    initial stiffness of a new face, ``penalty x E / h`` (h its mean edge length), which
    also keeps closed faces from passing through each other; ``quadrature``: the points of
    a linear (P1) face, its corners (``vertices``: no traction oscillations on stiff faces)
    or three points inside it (``gauss``: every point of a crack that ends at a line held
    shut can still open; :mod:`fem_frac.cohesive.interface`). Quadratic faces always use six
    Gauss points. ``front_stress``: the stress the elements at a crack's front are checked
    against, the smoothed one like everywhere else (``smoothed``), or each element's own
    (``element``): a front element then splits as soon as its own stress reaches the
    strength, so the new faces take on at most the traction the law allows and the insertion
    releases next to no energy; with the path free, unsmoothed stresses at the front let
    cracks branch into a band, so ``element`` goes with ``planes``
    (docs/fracture/cohesive_convergence.md measures both)."""

    law: Literal["linear", "exponential"] = "linear"
    shear_weight: Annotated[float, Field(gt=0.0, le=100.0)] = 1.0
    penalty: Annotated[float, Field(ge=1.0, le=1e4)] = 20.0
    quadrature: Literal["vertices", "gauss"] = "vertices"
    front_stress: Literal["smoothed", "element"] = "smoothed"


class Fracture(Section):
    """Cracks open where the smoothed largest principal stress exceeds ``tensile_strength``,
    perpendicular to its direction, by separating the mesh along faces (vertices duplicated).

    Within a step, up to ``passes`` batches are inserted; each batch holds at most
    ``batch_size`` sites (no two within one smoothing neighbourhood) and is followed by a
    re-solve of the step on the new mesh; a step inserts at most
    ``max_insertions_per_step`` sites in all. With ``planes`` cracks open only in those
    planes, where the smoothed normal stress on them exceeds the strength."""

    tensile_strength: PositiveFloat
    smoothing: Smoothing
    batch_size: PositiveInt = 4
    passes: Annotated[int, Field(ge=1, le=1000)] = 8
    max_insertions_per_step: PositiveInt = 64
    perturbation: Perturbation | None = None
    protect: list[Protect] = []
    planes: list[CrackPlane] = Field(
        default=[], description="a prescribed crack path: cracks open only in these planes, "
        "where they are mesh surfaces (no element crosses them), against the smoothed normal "
        "stress on the plane; empty: anywhere, against the largest principal stress")
    fracture_energy: PositiveFloat | None = Field(
        default=None, description="G_c, energy per unit crack area (J/m^2): new crack faces "
        "carry a cohesive traction that dissipates it; absent: faces open traction-free")
    cohesive: Cohesive | None = None

    @model_validator(mode="after")
    def _cohesive(self):
        if self.cohesive is not None and self.fracture_energy is None:
            raise ValueError("'cohesive' goes with 'fracture_energy' (the law's G_c)")
        if self.planes and self.perturbation is not None:
            raise ValueError("'perturbation' tilts crack normals; with 'planes' a crack's "
                             "normal is its plane's: give one or the other")
        return self

    @property
    def cohesive_law(self) -> Cohesive | None:
        """The law of the crack faces (defaults filled in), ``None`` when brittle."""
        if self.fracture_energy is None:
            return None
        return self.cohesive if self.cohesive is not None else Cohesive()


class Ground(Section):
    """A ground plane through ``point`` with upward ``normal``; rigid fragments bounce off it
    with ``restitution`` (0: no bounce, 1: elastic) and slide with Coulomb ``friction``."""

    point: Vector3 = (0.0, 0.0, 0.0)
    normal: Vector3 = (0.0, 0.0, 1.0)
    restitution: Annotated[float, Field(ge=0.0, le=1.0)] = 0.5
    friction: NonNegativeFloat = 0.5

    @model_validator(mode="after")
    def _normal(self):
        square = sum(c * c for c in self.normal)
        if square == 0.0:
            raise ValueError("normal must not be zero")
        if not 1e-200 < square < 1e200:
            raise ValueError("normal must be of moderate length (a unit vector is best)")
        return self


class BodyContact(Section):
    """Contact between two rigid bodies: they bounce with ``restitution`` (0: no bounce, 1:
    elastic) and slide with Coulomb ``friction``. No bounce by default: pieces are born
    touching along their crack, and what their faces did in the finite elements just before
    (closing at a hinge) is no impact to bounce off."""

    restitution: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0
    friction: NonNegativeFloat = 0.5


class Fragments(Section):
    """Pieces that break free (no support left) become rigid bodies: ``all`` of them,
    those no larger than ``max_volume`` (``small``), or each once its vibration has decayed
    (``settled``: strain plus vibrational kinetic energy below ``vibration_tolerance`` of
    its rigid kinetic energy); ``never`` keeps them deformable. ``whole_body`` makes the
    whole body one rigid body from the start (no finite elements: ``analysis`` gives the time
    steps and the initial velocity). ``gravity`` (default: ``body_force.gravity``) acts on
    rigid bodies; ``ground`` planes stop them; ``body_contact``: between two of them;
    ``finite_element_contact``: rigid bodies and the finite elements touch (its friction is
    ``body_contact``'s for a fragment, an obstacle's own)."""

    become_rigid: Literal["all", "small", "settled", "never"] = "all"
    max_volume: PositiveFloat | None = None
    vibration_tolerance: PositiveFloat = 1e-3
    whole_body: bool = False
    gravity: Vector3 | None = None
    ground: list[Ground] = []
    body_contact: BodyContact = BodyContact()
    contact_substeps: PositiveInt = Field(
        default=1, description="rigid-body steps per analysis step (finer contact resolution)")
    finite_element_contact: bool = Field(
        default=False, description="rigid bodies touch the finite elements (impulses through "
        "the lumped mass: needs analysis.mass lumped)")

    @model_validator(mode="after")
    def _small(self):
        if (self.become_rigid == "small") != (self.max_volume is not None):
            raise ValueError("become_rigid 'small' goes with max_volume (and only it)")
        return self
