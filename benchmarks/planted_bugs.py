"""Plant known bugs in a copy of the package and show that the tests catch each one.

    python benchmarks/planted_bugs.py [--keep]

Each plant replaces one piece of production code (which must occur exactly once) in a copy of
the tracked files, then runs the named test modules on that copy; the plant is caught when
pytest fails. Prints one line per plant and exits 1 if any plant went unnoticed. Takes a few
minutes (the fracture tests run the solver).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Plant:
    name: str
    path: str
    original: str
    planted: str
    tests: tuple[str, ...]


PLANTS = (
    Plant("the fracture criterion skips the smoothing", "fem_frac/fracture/stage.py",
          "principal_stress(smooth(topo.smoothing, mean))", "principal_stress(mean)",
          ("tests/test_fracture.py",)),
    Plant("Voigt shear (x 1 instead of 1/sqrt 2) in the production strain operator",
          "fem_frac/fem/operators.py",
          "    (3, ((0, 1), (1, 0)), 1.0 / SQRT2),", "    (3, ((0, 1), (1, 0)), 1.0),",
          ("tests/test_elasticity.py", "tests/test_operators.py")),
    Plant("plain shear strain (x 1/2) in the production strain operator",
          "fem_frac/fem/operators.py",
          "    (4, ((1, 2), (2, 1)), 1.0 / SQRT2),", "    (4, ((1, 2), (2, 1)), 0.5),",
          ("tests/test_elasticity.py", "tests/test_operators.py")),
    Plant("the quaternion is not renormalized over a long spin", "fem_frac/rigid/motion.py",
          "    return q / np.linalg.norm(q)", "    return q",
          ("tests/test_rigid_motion.py",)),
)


def copy_tree(to: Path) -> None:
    """The tracked files of the working tree (with their current edits) into ``to``."""
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, check=True, capture_output=True,
                           text=True).stdout.split()
    for name in files:
        source = ROOT / name
        if source.is_file():
            target = to / name
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target)


def plant(tree: Path, p: Plant) -> None:
    path = tree / p.path
    text = path.read_text()
    count = text.count(p.original)
    if count != 1:
        raise SystemExit(f"{p.path}: {p.original!r} occurs {count} times (expected once): "
                         "update the plant")
    path.write_text(text.replace(p.original, p.planted))


def caught(tree: Path, p: Plant) -> tuple[bool, str]:
    """Run the plant's tests on ``tree`` (its package first on the path)."""
    result = subprocess.run(
        [sys.executable, "-c", "import fem_frac, sys; "
         f"assert fem_frac.__file__.startswith({str(tree)!r}), fem_frac.__file__; "
         "import pytest; sys.exit(pytest.main(['-q', '-x', '-p', 'no:cacheprovider', "
         f"*{list(p.tests)!r}]))"],
        cwd=tree, capture_output=True, text=True)
    lines = [x for x in result.stdout.splitlines() if x.startswith("FAILED")]
    if "AssertionError: " in result.stderr and "fem_frac" in result.stderr:
        raise SystemExit(f"the copy's package was not the one imported:\n{result.stderr}")
    return result.returncode == 1, lines[0] if lines else result.stdout.strip()[-200:]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", action="store_true", help="keep the copies (printed)")
    args = parser.parse_args()
    missed = 0
    for p in PLANTS:
        tree = Path(tempfile.mkdtemp(prefix="planted-"))
        copy_tree(tree)
        plant(tree, p)
        t0 = time.perf_counter()
        ok, detail = caught(tree, p)
        missed += not ok
        print(f"{'caught' if ok else 'MISSED':7} {p.name} ({time.perf_counter() - t0:.0f} s): "
              f"{detail}")
        if args.keep:
            print(f"        copy kept in {tree}")
        else:
            shutil.rmtree(tree)
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
