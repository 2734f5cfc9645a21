"""The world of a run and the stages that move it.

- :mod:`.state`: :class:`World` (time, the deformable body, rigid bodies, obstacles, the
  energy ledger) and :class:`Body` (a discretization with its state), frozen values that
  stages replace and never edit;
- :mod:`.stage`: the typed stage protocol (``(Step, World) -> (World, event)``) and the one
  step loop;
- :mod:`.equilibrium`: the stage that steps the finite elements in time.

The stages on the world live beside the physics they run: :mod:`fem_frac.fracture.stage`,
:mod:`fem_frac.rigid.stage`, and the output in :mod:`fem_frac.app.output`.
"""

from .stage import Stage, Step, march
from .state import Body, World, body_of

__all__ = ["Body", "Stage", "Step", "World", "body_of", "march"]
