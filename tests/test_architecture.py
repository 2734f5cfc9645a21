"""The package's layering, as a contract: every module imports only from its own layer or
below, no module below the application sees the whole case, and no module reads another
module's private names (a stage's state is its own).

Layers, bottom to top (docs/architecture.md draws them):

0. ``errors``, ``timing``, ``config``: exceptions, wall clocks, the validated case
1. ``mesh``, ``fem``, ``verify``: meshes, spaces and operators, closed-form solutions
2. ``writers``, ``plasticity``, ``cohesive``: output fields and files, the material laws of
   the bulk and of cohesive crack faces
3. ``solve``: supports and loads, steppers, the energy ledger, discretizations
4. ``fracture`` and ``rigid`` (their physics: topology, smoothing, sites, rigid motion)
5. ``world``: the World, the stage protocol and the step loop, carrying state over
6. ``fracture.stage``, ``rigid.stage``: stages on the world
7. ``app``: the command line, the run of a case, its output and summary
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "fem_frac"

LAYERS = [
    ("errors", 0), ("timing", 0), ("threads", 0), ("config", 0),
    ("mesh", 1), ("fem", 1), ("verify", 1),
    ("writers", 2), ("plasticity", 2), ("cohesive", 2),
    ("solve", 3),
    ("fracture", 4), ("rigid", 4),
    ("world", 5),
    ("fracture.stage", 6), ("rigid.stage", 6),
    ("app", 7), ("__main__", 7), ("__init__", 0),
]
# third-party private attributes the code must reach (with the reason)
ALLOWED_PRIVATE = {
    "_mkl_pardiso",  # pypardiso exposes the MKL handle only as a private attribute
    "_exit",  # os._exit: public, documented (the command's exit, fem_frac/app/startup.py)
    "_run_exitfuncs",  # atexit's one way to run the exit functions before os._exit
}


def modules() -> dict[str, Path]:
    return {".".join(p.relative_to(PACKAGE).with_suffix("").parts): p
            for p in PACKAGE.rglob("*.py")}


def layer(module: str) -> int:
    module = module.removesuffix(".__init__") or "__init__"
    best = max((prefix for prefix, _ in LAYERS
                if module == prefix or module.startswith(prefix + ".")),
               key=len, default=None)
    assert best is not None, f"fem_frac.{module} is in no layer: add it to LAYERS"
    return dict(LAYERS)[best]


def imports(module: str, path: Path) -> list[tuple[str, list[str], int]]:
    """``(imported module, names, line)`` of every import of fem_frac in ``module``."""
    package = module.split(".")[:-1] if not path.name == "__init__.py" else \
        module.split(".")[:-1]
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            names = [a.name for a in node.names]
            if node.level:
                base = package[: len(package) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            elif node.module and node.module.startswith("fem_frac"):
                target = node.module.removeprefix("fem_frac").lstrip(".")
            else:
                continue
            out.append((target, names, node.lineno))
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("fem_frac."):
                    out.append((a.name.removeprefix("fem_frac."), [], node.lineno))
    return out


def resolve(target: str, names: list[str], known: dict) -> list[str]:
    """The modules an import reaches (``from pkg import module`` reaches the module)."""
    reached = [f"{target}.{n}" for n in names if f"{target}.{n}" in known]
    return reached or [target]


def test_every_module_imports_only_from_its_layer_or_below():
    known = modules()
    upward = []
    for module, path in known.items():
        for target, names, line in imports(module, path):
            for reached in resolve(target, names, known):
                if layer(reached) > layer(module):
                    upward.append(f"fem_frac/{path.relative_to(PACKAGE)}:{line} "
                                  f"({layer(module)}) imports {reached} ({layer(reached)})")
    assert not upward, "\n".join(upward)


def test_no_case_below_the_application():
    """Stages and numerics get their own sub-configuration, never the whole case."""
    found = []
    for module, path in modules().items():
        if layer(module) == 7 or module.startswith("config"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            named = (isinstance(node, ast.Name) and node.id == "Case") or (
                isinstance(node, ast.Attribute) and node.attr == "Case") or (
                isinstance(node, ast.alias) and node.name == "Case")
            if named:
                found.append(f"fem_frac/{path.relative_to(PACKAGE)}:{node.lineno}")
    assert not found, "the whole Case below fem_frac.app: " + ", ".join(found)


def test_no_module_reads_another_modules_private_names():
    """``obj._name`` only on ``self``/``cls``; ``from x import _name`` only inside x's own
    package."""
    found = []
    for module, path in modules().items():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and node.attr.startswith("_")
                    and not node.attr.startswith("__") and node.attr not in ALLOWED_PRIVATE
                    and not (isinstance(node.value, ast.Name)
                             and node.value.id in ("self", "cls"))):
                found.append(f"fem_frac/{path.relative_to(PACKAGE)}:{node.lineno} "
                             f"{ast.unparse(node)}")
        for target, names, line in imports(module, path):
            if target.split(".")[0] == module.split(".")[0]:
                continue
            for n in names:
                if n.startswith("_") and not n.startswith("__"):
                    found.append(f"fem_frac/{path.relative_to(PACKAGE)}:{line} imports "
                                 f"{n} from {target}")
    assert not found, "\n".join(found)


def test_the_contract_sees_an_upward_import(tmp_path, monkeypatch):
    """The layering check fails on a planted upward import (the test can fail)."""
    planted = tmp_path / "fem_frac"
    (planted / "solve").mkdir(parents=True)
    (planted / "solve" / "bad.py").write_text("from ..app.driver import prepare\n")
    (planted / "app").mkdir()
    (planted / "app" / "driver.py").write_text("")
    monkeypatch.setattr(__import__(__name__), "PACKAGE", planted)
    try:
        test_every_module_imports_only_from_its_layer_or_below()
    except AssertionError as exc:
        assert "solve/bad.py:1 (3) imports app.driver (7)" in str(exc)
    else:
        raise AssertionError("an upward import went unnoticed")


# Longer functions, each with the reason it stays whole (none today).
LONG_FUNCTIONS: dict[str, str] = {}
MAX_FUNCTION_LINES = 60
MAX_MODULE_LINES = 500


def test_functions_and_modules_stay_short():
    """No function above 60 lines without a stated reason, no module above 500 lines."""
    long = []
    for module, path in modules().items():
        text = path.read_text()
        if text.count("\n") > MAX_MODULE_LINES:
            long.append(f"fem_frac/{path.relative_to(PACKAGE)}: {text.count(chr(10))} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                name = f"{module}.{node.name}"
                if lines > MAX_FUNCTION_LINES and name not in LONG_FUNCTIONS:
                    long.append(f"fem_frac/{path.relative_to(PACKAGE)}:{node.lineno} "
                                f"{node.name}: {lines} lines")
    assert not long, "\n".join(long)
