"""What the ``fem-frac`` process pays before and after a run: scipy's first import, the
search for pydantic plugins, the garbage collector's passes over what the imports made,
and the interpreter's teardown at exit.

Each is measured in docs/performance.md, "Start-up, the collector and exit". They apply to
the command's own process only (:func:`fem_frac.app.cli.console`); a program that imports
fem_frac as a library keeps its interpreter as it is.
"""

from __future__ import annotations

import contextlib
import os
import sys

# numpy's submodules that numpy imports only when they are first read, and that a run never
# reads: scipy's array-API copy of the numpy namespace (scipy._lib.array_api_compat.numpy,
# imported by scipy.sparse) reads every name numpy lists, which imports them (f2py 32 ms,
# with the charset_normalizer it loads, and testing 9 ms of the 116 ms of importing
# scipy.sparse, ``python -X importtime``). scipy reads them from that copy only in its own
# test helpers. (numpy.ma, random, polynomial and ctypeslib are listed too, but a run
# imports them anyway: ``np.unique``, scipy's own modules, scikit-fem, gmsh's API.)
UNREAD_SUBMODULES = frozenset({"f2py", "testing"})


def import_scipy_lean() -> None:
    """Import scipy's array-API layer while numpy lists none of :data:`UNREAD_SUBMODULES`.

    numpy's module-level ``__dir__`` and ``__all__`` (which ``from numpy import *`` reads)
    are replaced for the length of the import and put back after; whatever imports one of
    those submodules later gets it as usual. Nothing is done where scipy is loaded already.
    """
    if "scipy._lib._array_api" in sys.modules:
        return
    import numpy

    listed, public = numpy.__dict__.get("__dir__"), numpy.__dict__.get("__all__")
    if listed is None or public is None:  # a numpy without lazy submodules
        return

    def lean() -> list[str]:
        return [name for name in listed() if name not in UNREAD_SUBMODULES]

    numpy.__dir__ = lean
    numpy.__all__ = [name for name in public if name not in UNREAD_SUBMODULES]
    try:
        import scipy._lib._array_api  # noqa: F401
    except ImportError:  # a scipy without that layer (or a broken one): imported later
        pass
    finally:
        numpy.__dir__, numpy.__all__ = listed, public


def import_for_run() -> None:
    """Import what a run uses (numpy, scipy, scikit-fem, pydantic, the case schema, the
    driver) with the cyclic garbage collector off, then freeze what the imports made.

    The imports make some 90,000 objects, which the collector walked again and again as
    its generations filled: 57-70 ms of a run (about 150-200 passes of the youngest
    generation, 13-19 of the middle one, one full pass of 25-30 ms; ``gc.callbacks``, five
    shipped cases), 4-17 ms once they are frozen. Frozen, they are left out of every later
    pass: module-level objects live as long as the process anyway. The collector works as
    usual on what the run makes."""
    import gc

    # pydantic looks for plugins among the entry points of every installed distribution
    # when it builds the case schema's first model (30-36 ms in a venv of 85); the case
    # schema uses none. Set unless the environment says otherwise.
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    gc.disable()
    try:
        import_scipy_lean()
        import skfem  # noqa: F401  (imported by the first space a run builds)

        from ..config import loader  # noqa: F401
        from . import driver  # noqa: F401
    finally:
        gc.freeze()
        gc.enable()


def leave(code: int) -> None:
    """End the process with ``code`` without the interpreter's teardown.

    Freeing every module and array and unloading MKL took 0.1-0.15 CPU s at the end of a
    run. The exit functions registered with :mod:`atexit` run (logging, weakref finalizers)
    and the standard streams are flushed first; every output file is closed by then (the
    writers open them in ``with`` blocks). Under MPI, whose finalization belongs to the
    interpreter's exit, the process leaves the usual way.
    """
    if "mpi4py" in sys.modules or "petsc4py" in sys.modules:
        sys.exit(code)
    import atexit

    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError, AttributeError):
            stream.flush()
    os._exit(code)
