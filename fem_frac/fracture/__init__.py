"""Fracture: cracks open where the smoothed largest principal stress exceeds the strength,
by separating the mesh along faces (DESIGN §2).

- :mod:`.topology`: face adjacency, fragments, vertex splits, the :class:`Transfer` map;
- :mod:`.smoothing`: the stress smoothing operator and principal stresses;
- :mod:`.sites`: which vertices split, along which planes;
- :mod:`.remap`: nodal and element state onto a new mesh;
- :mod:`.stage`: the stage the step loop runs after each step.
"""

from .topology import (
    CRACK,
    Transfer,
    face_adjacency,
    fragments,
    identity_transfer,
    open_crack,
    separate_nonmanifold,
    split_vertex,
)

__all__ = [
    "CRACK",
    "Transfer",
    "face_adjacency",
    "fragments",
    "identity_transfer",
    "open_crack",
    "separate_nonmanifold",
    "split_vertex",
]
