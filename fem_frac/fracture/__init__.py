"""Fracture: crack insertion by face separation (topology core; not wired into the solver)."""

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
