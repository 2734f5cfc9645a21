"""The command's process: scipy imported without numpy's unread submodules, and an exit
that skips the interpreter's teardown but keeps the output, the exit code and the exit
functions (fem_frac/app/startup.py). Each check runs in a fresh interpreter."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CASE = ROOT / "cases" / "cantilever.yaml"


def python(code: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          cwd=ROOT, timeout=300)


def test_lean_import_leaves_numpy_as_it_was():
    code = """
import sys
import numpy
listed, public = numpy.__dir__, list(numpy.__all__)
from fem_frac.app.startup import UNREAD_SUBMODULES, import_scipy_lean
import_scipy_lean()
loaded = sorted(m for m in UNREAD_SUBMODULES if f"numpy.{m}" in sys.modules)
assert numpy.__dir__ is listed and numpy.__all__ == public, "numpy not put back"
assert {"testing", "f2py"} <= set(dir(numpy)), "numpy's listing lost a submodule"
import scipy.sparse, scipy.sparse.linalg
a = scipy.sparse.eye(3, format="csr") * 2.0
assert abs(scipy.sparse.linalg.spsolve(a, numpy.ones(3)) - 0.5).max() == 0.0
import numpy.testing  # still imported on demand
print(loaded)
"""
    done = python(code)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]", "scipy's import still loads numpy's unread submodules"


def test_lean_import_without_numpys_lists_is_a_no_op():
    # a numpy without module-level __dir__ (before lazy submodules): nothing is replaced
    code = """
import numpy
del numpy.__dir__
from fem_frac.app.startup import import_scipy_lean
import_scipy_lean()
import scipy.sparse
assert "__dir__" not in vars(numpy)
"""
    done = python(code)
    assert done.returncode == 0, done.stderr


def test_lean_import_where_scipy_has_no_array_api_layer():
    # an older or different scipy: the import fails, numpy is put back, nothing is raised
    code = """
import sys
import numpy
listed = numpy.__dir__
class NoLayer:  # its import raises ImportError, as where scipy has no such module
    def find_spec(self, name, path=None, target=None):
        if name == "scipy._lib._array_api":
            raise ImportError(name)
sys.meta_path.insert(0, NoLayer())
from fem_frac.app.startup import import_scipy_lean
import_scipy_lean()
assert numpy.__dir__ is listed and "testing" in numpy.__all__
assert "scipy._lib._array_api" not in sys.modules
"""
    done = python(code)
    assert done.returncode == 0, done.stderr


def test_imports_for_a_run_are_frozen_and_the_collector_back_on():
    code = """
import gc, os
from fem_frac.app.startup import import_for_run
import_for_run()
assert os.environ["PYDANTIC_DISABLE_PLUGINS"] == "__all__"
from pydantic.plugin._loader import get_plugins
assert list(get_plugins()) == []
import fem_frac.app.driver, numpy, scipy.sparse, skfem
assert gc.isenabled(), "the collector left off"
assert gc.get_freeze_count() > 10000, gc.get_freeze_count()
class Cycle:
    pass
a = Cycle(); a.me = a
del a
assert gc.collect() >= 1, "a cycle made after the imports not collected"
"""
    done = python(code)
    assert done.returncode == 0, done.stderr


def test_the_command_keeps_its_output_code_and_exit_functions():
    # `check` prints its report through a pipe; an exit function registered before the
    # run still runs; the code is main()'s
    code = """
import atexit, sys
atexit.register(print, "exit function ran")
sys.argv = ["fem-frac", "check", sys.argv[1]]
from fem_frac.app.cli import console
console()
"""
    done = python(code, str(CASE))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[-1] == "exit function ran"
    assert len(lines) > 5 and "cantilever" in done.stdout

    bad = python(code, str(ROOT / "no_such_case.yaml"))
    assert bad.returncode == 2
    assert bad.stdout.strip() == "exit function ran"
    assert len(bad.stderr.strip().splitlines()) == 1 and "no_such_case.yaml" in bad.stderr


def test_module_run_writes_a_complete_series(tmp_path):
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "fem_frac", "run", str(CASE), "-o", str(out),
                           "-q"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert done.returncode == 0, done.stderr
    pvd = (out / "cantilever.pvd").read_text()
    assert pvd.rstrip().endswith("</VTKFile>")
    assert (out / "summary.json").read_text().rstrip().endswith("}")


def test_an_interrupt_during_the_imports_is_one_line():
    code = """
import sys
import fem_frac.app.startup as startup
def interrupted():
    raise KeyboardInterrupt
startup.import_for_run = interrupted
sys.argv = ["fem-frac", "run", sys.argv[1]]
from fem_frac.app.cli import console
console()
"""
    done = python(code, str(CASE))
    assert done.returncode == 130
    assert done.stderr.strip() == "interrupted"


def test_an_import_that_fails_before_the_run_is_left_to_main():
    # main() imports the same modules again, inside its own error handling
    code = """
import sys
import fem_frac.app.startup as startup
def broken():
    raise ImportError("no module named skfem")
startup.import_for_run = broken
sys.argv = ["fem-frac", "check", sys.argv[1]]
from fem_frac.app.cli import console
console()
"""
    done = python(code, str(CASE))
    assert done.returncode == 0, done.stderr
    assert "cantilever" in done.stdout
