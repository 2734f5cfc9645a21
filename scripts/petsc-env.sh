#!/usr/bin/env bash
# A virtual environment with PETSc (petsc4py, MPI) for `linear_solver: petsc` (docs/solvers.md).
#
#   scripts/petsc-env.sh [VENV]      (default VENV: .venv-petsc; Debian 12 / Ubuntu, as root
#                                     or with sudo; about 2 minutes on 2 cores)
#
# PETSc has no pip wheel for every Python and a source build takes more than 20 minutes, so
# petsc4py, mpi4py and Open MPI come from the distribution (Debian 12: PETSc 3.18 with MUMPS
# and hypre). They are built for the system Python (/usr/bin/python3) and its numpy 1.x, so
# the environment is made on that Python with the system packages visible, and numpy is held
# below 2 (the version petsc4py was compiled against). fem-frac and its test dependencies are
# installed into it in editable mode. Afterwards:
#
#   . VENV/bin/activate && fem-frac run CASE --set analysis.linear_solver=petsc
#   mpiexec -n 2 fem-frac run CASE --set analysis.linear_solver=petsc
#   (as root: mpiexec --allow-run-as-root -n 2 ...)
set -euo pipefail
cd "$(dirname "$0")/.."
venv=${1:-.venv-petsc}
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -q
# python3-venv for the environment; without recommends the petsc-dev tree (compilers,
# headers) is left out, and so is the /usr/lib/petsc link petsc4py's .pth file reads: the
# .pth written below names the directory instead.
$sudo apt-get install -y -q --no-install-recommends \
    python3-petsc4py-real python3-mpi4py python3-venv openmpi-bin
/usr/bin/python3 -m venv --system-site-packages "$venv"
petsc_site=$(ls -d /usr/lib/petscdir/petsc3.*/x86_64-linux-gnu-real/lib/python3/dist-packages \
    | sort -V | tail -n 1)
site=$("$venv/bin/python" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
echo "$petsc_site" > "$site/petsc4py-debian.pth"
# numpy < 2: the ABI petsc4py and mpi4py were built against (scripts/petsc-constraints.txt).
# coal is left out: every coal release for this Python needs numpy 2 (through cmeel-boost),
# and it is imported only where two rigid bodies may touch, so contact between bodies is
# the one feature this environment lacks. The other dependencies are pyproject.toml's.
deps=$("$venv/bin/python" -c "
import tomllib
project = tomllib.load(open('pyproject.toml', 'rb'))['project']
wanted = project['dependencies'] + project['optional-dependencies']['test']
print('\\n'.join(d for d in wanted if not d.startswith('coal')))")
"$venv/bin/python" -m pip install -q -c scripts/petsc-constraints.txt -e . --no-deps
echo "$deps" | tr '\n' '\0' | xargs -0 "$venv/bin/python" -m pip install -q \
    -c scripts/petsc-constraints.txt
"$venv/bin/python" -c "
from petsc4py import PETSc
import mpi4py, numpy
print('petsc', '.'.join(map(str, PETSc.Sys.getVersion())), 'mpi4py', mpi4py.__version__,
      'numpy', numpy.__version__)"
