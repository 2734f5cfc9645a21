"""``linear_solver: petsc``: the same displacements as PARDISO on the shipped elastic and
plastic cases, on one MPI rank and on two; the errors when PETSc is absent or misused.

The solves need petsc4py (and mpiexec with mpi4py for two ranks): they are skipped, with
the reason, where it is not installed (install: scripts/petsc-env.sh; CI runs this file in
that environment, .ci/run). The checks of the errors and of the system PETSc is given run
everywhere.
"""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest
import scipy.sparse as sp

from fem_frac.app.cli import main
from fem_frac.config import CaseErrors, load_case
from fem_frac.config.schema import analysis as analysis_schema
from fem_frac.solve import ranks
from fem_frac.solve.petsc import eliminated, row_ranges

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "cases"
AGREE = 1e-8  # relative l2 difference of the final displacement field, PETSc vs PARDISO

PETSC_MISSING = importlib.util.find_spec("petsc4py") is None
needs_petsc = pytest.mark.skipif(
    PETSC_MISSING, reason="petsc4py is not installed (scripts/petsc-env.sh installs it)")
needs_mpi = pytest.mark.skipif(
    PETSC_MISSING or importlib.util.find_spec("mpi4py") is None or not shutil.which("mpiexec"),
    reason="two ranks need petsc4py, mpi4py and mpiexec (scripts/petsc-env.sh installs them)")

# The shipped cases: an elastic static one (P2, clamped) and two plastic quasi-static ones
# (a beam loaded past yield and unloaded; Hill's sphere on symmetry planes, whose supports
# hold single components of a node). ``--set``s each run takes.
SHIPPED = {
    "cantilever": ["--set", "analysis.type=static"],
    "beam_yield_unload": [],
    "hollow_sphere_plastic": [],
}


# ---------------------------------------------------------------- everywhere

def test_petsc_missing_is_a_one_line_error(tmp_path, monkeypatch, capsys):
    """Without petsc4py, ``linear_solver: petsc`` is refused at check: exit 2, one line
    naming the key and the install script, no traceback."""
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "petsc4py" else real(name, *a))
    code = main(["check", str(CASES / "cantilever.yaml"), "--set", "analysis.type=static",
                 "--set", "analysis.linear_solver=petsc"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "analysis.linear_solver" in err and "petsc4py is not installed" in err
    assert "scripts/petsc-env.sh" in err


@pytest.mark.parametrize("method,package", [("cholmod", "sksparse"), ("pardiso", "pypardiso")])
def test_a_solver_whose_package_is_missing_is_a_one_line_error(method, package, monkeypatch,
                                                               capsys):
    """A solver asked for by name whose package is not installed is refused at check (it
    was an internal error at run, exit 1): exit 2, one line naming the key and the
    package."""
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == package else real(name, *a))
    code = main(["check", str(CASES / "cantilever.yaml"), "--set", "analysis.type=static",
                 "--set", f"analysis.linear_solver={method}"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "analysis.linear_solver" in err and f"needs {package}, which is not installed" in err


def test_several_ranks_refuse_a_one_rank_solver(monkeypatch):
    """Under ``mpiexec -n 2`` a direct solver that runs on one rank is refused at the key."""
    monkeypatch.setenv("OMPI_COMM_WORLD_SIZE", "2")
    with pytest.raises(CaseErrors) as info:
        load_case(CASES / "cantilever.yaml", ["analysis.type=static",
                                              "analysis.linear_solver=pardiso"])
    line = info.value.line()
    assert "analysis.linear_solver" in line and "2 MPI ranks" in line
    monkeypatch.delenv("OMPI_COMM_WORLD_SIZE")
    load_case(CASES / "cantilever.yaml", ["analysis.type=static",
                                          "analysis.linear_solver=pardiso"])


def test_petsc_options_are_checked():
    with pytest.raises(CaseErrors, match="one multigrid cycle"):
        load_case(CASES / "cantilever.yaml", ["analysis.type=static",
                                              "analysis.petsc.ksp=preonly"])
    with pytest.raises(CaseErrors, match="not a PETSc option name"):
        load_case(CASES / "cantilever.yaml", ["analysis.type=static",
                                              "analysis.petsc.options={-pc_type: lu}"])


def test_the_launcher_variables_agree():
    """config reads the MPI launcher's environment on its own (it cannot import solve)."""
    assert analysis_schema.MPI_SIZE_VARIABLES == ranks.MPI_SIZE_VARIABLES


def test_the_eliminated_system_has_the_condensed_solution():
    """The full-size system PETSc is given (constrained rows and columns replaced by the
    identity) solves to the condensed system's solution on the free dofs, and is still
    symmetric; each rank's rows are whole nodes."""
    rng = np.random.default_rng(3)
    n = 30
    m = sp.random(n, n, density=0.3, random_state=4)
    a = (m @ m.T + n * sp.eye(n)).tocsr()
    free = np.sort(rng.choice(n, 20, replace=False))
    full = eliminated(a, free)
    assert abs(full - full.T).max() == 0
    b = rng.standard_normal(len(free))
    rhs = np.zeros(n)
    rhs[free] = b
    x = sp.linalg.spsolve(full.tocsc(), rhs)
    condensed = sp.linalg.spsolve(a[free][:, free].tocsc(), b)
    assert np.allclose(x[free], condensed, rtol=1e-12, atol=0)
    assert np.all(x[np.setdiff1d(np.arange(n), free)] == 0)
    assert list(row_ranges(30, 4, 3)) == [0, 9, 18, 24, 30]


# ---------------------------------------------------------------- with PETSc

def _run(case: str, out: Path, extra: list[str], ranks_: int = 1) -> np.ndarray:
    """Run a shipped case (under mpiexec for several ranks); the last frame's displacement."""
    command = [sys.executable, "-m", "fem_frac", "run", str(CASES / f"{case}.yaml"), "-o",
               str(out), "-q", *SHIPPED[case], *extra]
    if ranks_ > 1:
        command = ["mpiexec", "--allow-run-as-root", "--oversubscribe", "-n", str(ranks_),
                   *command]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert not list(out.parent.glob("*.vtu")), "a rank wrote outside its output directory"
    frames = sorted(out.glob("*.vtu"))
    return meshio.read(frames[-1]).point_data["displacement"]


def _difference(u: np.ndarray, reference: np.ndarray) -> float:
    return float(np.linalg.norm(u - reference) / np.linalg.norm(reference))


@pytest.fixture(scope="module")
def pardiso(tmp_path_factory):
    """The PARDISO displacements of each shipped case, computed once."""
    out = tmp_path_factory.mktemp("pardiso")
    return {case: _run(case, out / case, ["--set", "analysis.linear_solver=pardiso"])
            for case in SHIPPED}


@needs_petsc
@pytest.mark.parametrize("case", list(SHIPPED))
def test_one_rank_matches_pardiso(case, pardiso, tmp_path):
    u = _run(case, tmp_path / case, ["--set", "analysis.linear_solver=petsc"])
    assert _difference(u, pardiso[case]) < AGREE


@needs_mpi
@pytest.mark.parametrize("case", list(SHIPPED))
def test_two_ranks_match_pardiso(case, pardiso, tmp_path):
    u = _run(case, tmp_path / case, ["--set", "analysis.linear_solver=petsc"], ranks_=2)
    assert _difference(u, pardiso[case]) < AGREE
    summary = (tmp_path / case / "summary.json").read_text()
    assert "2 MPI ranks" in summary


@needs_petsc
def test_mumps_matches_pardiso(pardiso, tmp_path):
    """The direct option: MUMPS's Cholesky factorization."""
    u = _run("cantilever", tmp_path / "c", ["--set", "analysis.linear_solver=petsc",
                                            "--set", "analysis.petsc.pc=mumps"])
    assert _difference(u, pardiso["cantilever"]) < AGREE


@needs_petsc
def test_a_loose_solve_is_seen(pardiso, tmp_path):
    """The comparison can fail: one inexact solve (single_pass, rtol 1e-2, no equilibrium
    iteration to correct it) differs from PARDISO by more than AGREE (measured: 5e-7 at
    rtol 1e-3)."""
    u = _run("cantilever", tmp_path / "c", ["--set", "analysis.linear_solver=petsc",
                                            "--set", "analysis.petsc.rtol=1e-2",
                                            "--set", "analysis.equilibrium.method=single_pass"])
    assert _difference(u, pardiso["cantilever"]) > 10 * AGREE


@needs_petsc
def test_no_convergence_is_a_numerical_failure(tmp_path):
    """A Krylov solve that runs out of iterations stops the run (exit 3) and says why."""
    command = [sys.executable, "-m", "fem_frac", "run", str(CASES / "cantilever.yaml"), "-o",
               str(tmp_path / "c"), "-q", *SHIPPED["cantilever"],
               "--set", "analysis.linear_solver=petsc", "--set", "analysis.petsc.max_iterations=2"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert done.returncode == 3
    assert "did not converge" in done.stderr and "max_iterations" in done.stderr
