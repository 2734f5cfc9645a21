"""Errors a user can act on. The CLI prints them in one line and exits with code 2."""

from __future__ import annotations


class FemFracError(Exception):
    """Base class of errors caused by input, reported without a traceback."""


class CaseError(FemFracError):
    """A problem with a case file, located by the key path inside the file.

    ``path`` is the key path (``("material", "youngs_modulus")`` or
    ``("boundary_conditions", 2, "boundary")``); the CLI turns it into ``file:line:col``.
    """

    def __init__(self, path: tuple, message: str):
        super().__init__(message)
        self.path = tuple(path)
        self.message = message


class MeshError(FemFracError):
    """A mesh that cannot be built or read, or is unusable (no tets, inverted elements)."""


class SolverError(FemFracError):
    """A numerical failure the user can act on (singular system, non-finite state)."""


class Interrupted(BaseException):  # noqa: N818 (a signal, like KeyboardInterrupt)
    """A run stopped by a signal (SIGINT, SIGTERM) at ``step``; its output so far is
    kept. A BaseException, like KeyboardInterrupt, so that no handler of errors takes it."""

    def __init__(self, signum: int, step: int = 0, steps: int = 0, directory=None):
        super().__init__(f"interrupted by signal {signum}")
        self.signum, self.step, self.steps, self.directory = signum, step, steps, directory
