"""Linear solves across MPI ranks: ``mpiexec -n N fem-frac run CASE``.

Rank 0 runs the whole command (meshing, assembly, the return map, fracture, rigid bodies,
all output); the other ranks only take part in PETSc's solves. Rank 0 sends each rank its
rows of the system (whole nodes: blocks of 3 rows) when a matrix is set up and the
right-hand side's rows at every solve, and gathers the solution. The ranks wait in
:func:`serve` for the next command and never write a file.

mpi4py is imported only when the process was started by ``mpiexec`` with more than one
rank (read from the launcher's environment before anything imports MPI).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable

# What MPI launchers (Open MPI's mpiexec, MPICH's Hydra) tell each process of the job's
# size; read before anything imports MPI (fem_frac.config.schema.analysis reads the same).
MPI_SIZE_VARIABLES = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE")
_ACTIVE = None  # rank 0's Ranks while a command runs under mpiexec
COMMAND_TAG = 7
# A rank waiting for rank 0's next command polls at this interval and sleeps between: a
# blocking MPI receive spins and takes a core from rank 0's own work (assembly, return map)
# when there are no more cores than ranks (measured in docs/performance.md).
IDLE_POLL_S = 0.001


def launched_ranks() -> int:
    """The number of MPI ranks this process was started among (1 outside ``mpiexec``)."""
    for name in MPI_SIZE_VARIABLES:
        value = os.environ.get(name, "")
        if value.isdigit():
            return int(value)
    return 1


def active():
    """Rank 0's :class:`Ranks` under ``mpiexec -n N`` (N > 1), else None."""
    return _ACTIVE


class Ranks:
    """Rank 0's end: sets up systems on every rank, solves them, releases them."""

    def __init__(self, comm):
        self.comm = comm
        self.size = comm.size
        self.busy = False  # inside a collective operation (an error here must abort all)
        self._next = 0
        self._systems: dict = {}
        self._pending: list[int] = []
        self._bs: dict[int, int] = {}

    def _command(self, command: dict) -> None:
        pending, self._pending = self._pending, []
        command["free"] = pending
        for r in range(1, self.size):  # point to point: a waiting rank sleeps (see serve)
            self.comm.send(command, dest=r, tag=COMMAND_TAG)
        for key in pending:  # destroying is collective: every rank, in the same order
            self._systems.pop(key).destroy()
            self._bs.pop(key)

    def setup(self, a, points, settings) -> int:
        """Rows of ``a`` (and of ``points``, one per block of 3) to every rank; a KSP set up
        on each; returns the key of the system."""
        from .petsc import LocalSystem, petsc, row_block, row_ranges

        n, bs = a.shape[0], (1 if points is None else 3)
        ranges = row_ranges(n, self.size, bs)
        self.busy = True
        self._next += 1
        key = self._next
        self._command({"op": "setup", "id": key, "n": n, "bs": bs, "settings": settings})
        for r in range(1, self.size):
            lo, hi = ranges[r], ranges[r + 1]
            _send_arrays(self.comm, r, [*row_block(a, lo, hi),
                                        *([] if points is None else [points[lo // 3: hi // 3]])])
        self._systems[key] = LocalSystem(
            petsc().COMM_WORLD, n, (0, ranges[1]), row_block(a, 0, ranges[1]),
            None if points is None else points[: ranges[1] // 3], settings)
        self._bs[key] = bs
        self.busy = False
        return key

    def solve(self, key: int, b):
        import numpy as np
        from mpi4py import MPI

        from .petsc import row_ranges

        ranges = row_ranges(len(b), self.size, self._bs[key])
        counts = np.diff(ranges)
        self.busy = True
        self._command({"op": "solve", "id": key})
        local = np.empty(counts[0])
        self.comm.Scatterv([b, counts, ranges[:-1], MPI.DOUBLE], local, root=0)
        x_local, its, reason, residual = self._systems[key].solve(local)
        x = np.empty_like(b)
        self.comm.Gatherv(x_local, [x, counts, ranges[:-1], MPI.DOUBLE], root=0)
        self.busy = False
        return x, its, reason, residual

    def release(self, key: int) -> None:
        """Free a system at the next command (never now: this may run inside another)."""
        self._pending.append(key)

    def stop(self) -> None:
        self._pending.extend(k for k in self._systems if k not in self._pending)
        self._command({"op": "stop"})


def serve(comm) -> int:
    """The loop of ranks 1..N-1: set up, solve, free, until rank 0 says stop (these ranks
    run no other code of the command, so they never write a file)."""
    from .petsc import LocalSystem, petsc, row_ranges

    systems: dict[int, LocalSystem] = {}
    try:
        while True:
            while not comm.Iprobe(source=0, tag=COMMAND_TAG):
                time.sleep(IDLE_POLL_S)
            command = comm.recv(source=0, tag=COMMAND_TAG)
            for key in command["free"]:
                systems.pop(key).destroy()
            op = command["op"]
            if op == "stop":
                return 0
            if op == "setup":
                n = command["n"]
                lo, hi = row_ranges(n, comm.size, command["bs"])[comm.rank: comm.rank + 2]
                arrays = _recv_arrays(comm, 0)
                points = arrays[3] if len(arrays) > 3 else None
                systems[command["id"]] = LocalSystem(petsc().COMM_WORLD, n, (lo, hi),
                                                     tuple(arrays[:3]), points,
                                                     command["settings"])
            elif op == "solve":
                _solve_part(comm, systems[command["id"]])
    except Exception as exc:  # noqa: BLE001 (a rank that fails must stop every rank)
        print(f"error: MPI rank {comm.rank}: {type(exc).__name__}: {exc}", file=sys.stderr)
        comm.Abort(3)
        return 3


def _solve_part(comm, system) -> None:
    import numpy as np

    lo, hi = system.matrix.getOwnershipRange()
    local = np.empty(hi - lo)
    comm.Scatterv(None, local, root=0)
    x_local = system.solve(local)[0]
    comm.Gatherv(x_local, None, root=0)


def _send_arrays(comm, dest: int, arrays: list) -> None:
    import numpy as np

    arrays = [np.ascontiguousarray(a) for a in arrays]
    comm.send([(a.dtype.str, a.shape) for a in arrays], dest=dest, tag=1)
    for a in arrays:
        comm.Send(a, dest=dest, tag=2)


def _recv_arrays(comm, source: int) -> list:
    import numpy as np

    out = []
    for dtype, shape in comm.recv(source=source, tag=1):
        a = np.empty(shape, dtype=np.dtype(dtype))
        comm.Recv(a, source=source, tag=2)
        out.append(a)
    return out


def main(command: Callable[[list[str] | None], int], argv: list[str] | None) -> int:
    """Run ``command(argv)`` as the program: directly on one rank; under ``mpiexec -n N``
    on rank 0, with ranks 1..N-1 serving its linear solves until it returns."""
    global _ACTIVE
    if launched_ranks() <= 1:
        return command(argv)
    # Open MPI: a rank waiting inside a collective operation yields its core rather than
    # spinning on it, which keeps N ranks on N busy cores from stalling one another
    # (measured in docs/performance.md); an explicit setting in the environment wins
    os.environ.setdefault("OMPI_MCA_mpi_yield_when_idle", "1")
    try:
        from mpi4py import MPI
    except ImportError:
        print("error: started on several MPI ranks, but mpi4py is not installed; install it "
              "with scripts/petsc-env.sh (docs/solvers.md, 'PETSc')", file=sys.stderr)
        return 2
    comm = MPI.COMM_WORLD
    from ..errors import FemFracError
    from .petsc import petsc

    try:
        petsc()  # PETSc's initialization is collective: every rank, before anything else
    except FemFracError as exc:
        if comm.rank == 0:
            print(f"error: started on {comm.size} MPI ranks: {exc}", file=sys.stderr)
        return 2
    if comm.rank != 0:
        return serve(comm)
    _ACTIVE = Ranks(comm)
    try:
        code = command(argv)
    except BaseException:
        if _ACTIVE.busy:
            comm.Abort(1)
        _ACTIVE.stop()
        raise
    if _ACTIVE.busy:  # failed inside a collective operation: the others wait in it
        comm.Abort(code or 1)
    _ACTIVE.stop()
    _ACTIVE = None
    return code

