"""Hostile input: bad inputs made from the shipped cases, each refused in one line.

Every input below is run through ``fem_frac.app.cli.main`` in this process and must end
with exit code 2 (bad input) or, where the input is valid but numerically impossible, 3;
with exactly one ``error:`` line on stderr (``warning:`` lines aside) that names the case
file, and its line where the input has one (the line of the key at fault, or of a section
holding it); with no traceback; without creating a file outside the test's output
directory, and within a few seconds.

The inputs, by category (``CATEGORIES``):

- ``misspelt``: every key of every shipped case misspelt (the line of that key);
- ``type``: every value given a value of the wrong type (quoted numbers, numbers for text,
  ``yes`` for ``true``, mappings for numbers, numbers for sections, short and long vectors);
- ``nonfinite``: every number made ``.inf``, ``-.inf``, ``.nan``, ``1e400``;
- ``range``: every positive number made 0 and negative, counts fractional or huge;
- ``empty``: required values made ``null``;
- ``digits``: a 5000-digit integer;
- ``work``: inputs that imply hours of work or more memory than there is (tiny element
  sizes, huge step counts, smoothing neighbourhoods of the whole body);
- ``yaml``: broken YAML, duplicate keys, non-UTF-8, control characters, deep nesting,
  aliases that expand or refer to themselves, dates, tags, keys that are not names, a file
  too big, paths that are no regular file;
- ``mesh``: broken mesh files (non-finite or huge coordinates, indices out of range,
  truncated, garbage, empty, no tets, too big);
- ``set``: ``--set`` abuse (scalars indexed, sections created half, malformed YAML, items
  out of range);
- ``escape``: output paths that leave the output directory;
- ``numeric``: valid inputs no arithmetic survives (exit 3).

Most run ``check``; the ``work``, ``escape`` and ``numeric`` ones (a small share) run
``run``, and must be refused before any heavy work. The default run takes a deterministic
sample of each category (``SAMPLE``); ``-m slow`` runs every input.
"""

from __future__ import annotations

import contextlib
import os
import random
import re
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from fem_frac.app.cli import main

ROOT = Path(__file__).resolve().parents[1]
CASES = sorted((ROOT / "cases").glob("*.yaml"))
MESH = ROOT / "meshes" / "block_with_hole.msh"
BLOCK = ROOT / "cases" / "block_with_hole.yaml"
SECONDS = 10  # the most any one input may take (a refusal takes milliseconds)

# values that must be > 0 (counts among them), and >= 0; by key name (a vector's items take
# its name)
POSITIVE = {"youngs_modulus", "density", "element_size", "yield_stress", "lengths", "radius",
            "height", "inner_radius", "outer_radius", "t_end", "dt", "steps", "output_every",
            "tensile_strength", "length", "batch_size", "passes", "max_insertions_per_step",
            "contact_substeps", "vibration_tolerance", "max_volume", "tolerance",
            "max_iterations", "angle"}
NON_NEGATIVE = {"hardening", "kinematic_hardening", "t_start", "friction", "restitution",
                "rings", "cutbacks", "seed"}
COUNTS = {"steps", "output_every", "batch_size", "passes", "max_insertions_per_step",
          "contact_substeps", "max_iterations", "seed"}
REQUIRED = {"youngs_modulus", "poissons_ratio", "lengths", "radius", "height", "inner_radius",
            "outer_radius", "type", "boundary", "traction", "pressure", "tensile_strength",
            "yield_stress", "points", "solution", "gravity", "angle", "mesh", "material",
            "smoothing"}
VECTORS = {"lengths", "origin", "traction", "gravity", "uniform", "angular_velocity", "center",
           "point", "normal", "min", "max"}
# ``[name]`` keys whose children are names the case chooses, not keys of the schema
NAMED = {"load_curves"}

DIGITS = "9" * 5000


@dataclass(frozen=True)
class Bad:
    """One bad input: the case file's text (``None``: ``make`` writes what the case path
    is), the arguments after the case path, what is expected."""

    id: str
    category: str
    text: str | bytes | None
    args: tuple[str, ...] = ()
    command: str = "check"
    codes: frozenset = frozenset({2})
    lines: frozenset | None = None  # the lines the message may name (empty: any line)
    words: str = ""  # text the message must hold
    make: Callable[[Path], None] | None = None  # writes files the input needs into tmp


# --- YAML nodes of the shipped cases -------------------------------------------------------


@dataclass(frozen=True)
class Entry:
    path: tuple
    key: object  # the key's node (None for a list item)
    value: object  # the value's node
    lines: frozenset  # 1-based lines of the key and of every section holding it


def _entries(text: str) -> list[Entry]:
    from ruamel.yaml import YAML

    out: list[Entry] = []

    def walk(node, path: tuple, lines: frozenset) -> None:
        kind = type(node).__name__
        if kind == "MappingNode":
            for k, v in node.value:
                here = lines | {k.start_mark.line + 1, v.start_mark.line + 1}
                out.append(Entry(path + (k.value,), k, v, here))
                walk(v, path + (k.value,), here)
        elif kind == "SequenceNode":
            for i, v in enumerate(node.value):
                here = lines | {v.start_mark.line + 1}
                out.append(Entry(path + (i,), None, v, here))
                walk(v, path + (i,), here)

    walk(YAML(typ="rt").compose(text), (), frozenset())
    return out


def _name(path: tuple) -> str:
    return next(p for p in reversed(path) if isinstance(p, str))


def _replace(text: str, node, new: str) -> str:
    """``text`` with ``node`` written as ``new`` (a block node's text runs to the next
    line's start: the line break is kept)."""
    old = text[node.start_mark.index: node.end_mark.index]
    return (text[: node.start_mark.index] + new + ("\n" if old.endswith("\n") else "")
            + text[node.end_mark.index:])


def _misspell(word: str, rng: random.Random) -> str:
    if len(word) < 3:
        return word + "q"
    i = rng.randrange(len(word) - 1)
    swapped = word[:i] + word[i + 1] + word[i] + word[i + 2:]
    return swapped if swapped != word else word[:i] + word[i + 1:]


def _line_of(text: str, needle: str) -> int:
    return text[: text.index(needle)].count("\n") + 1


def _case_text(path: Path) -> str:
    """A shipped case with its mesh file paths absolute (the line numbers unchanged)."""
    return path.read_text().replace("../meshes/", f"{ROOT / 'meshes'}/")


# --- the inputs ----------------------------------------------------------------------------


def _key_inputs(case: Path) -> list[Bad]:
    """misspelt, type, nonfinite, range, empty, digits: every key of one case."""
    text, stem = _case_text(case), case.stem
    rng = random.Random(stem)
    out: list[Bad] = []
    for e in _entries(text):
        name, where = _name(e.path), ".".join(str(p) for p in e.path)
        named_child = len(e.path) >= 2 and e.path[-2] in NAMED
        if e.key is not None and not named_child:
            wrong = _misspell(e.key.value, rng)
            out.append(Bad(f"{stem}:{where}:misspelt", "misspelt", _replace(text, e.key, wrong),
                           lines=frozenset({e.key.start_mark.line + 1}), words="unknown key"))

        def bad(kind: str, category: str, value: str, e=e, where=where) -> None:
            out.append(Bad(f"{stem}:{where}:{kind}", category, _replace(text, e.value, value),
                           lines=e.lines))

        node_kind = type(e.value).__name__
        if node_kind != "ScalarNode":
            if e.path[-1] != "load_curves" or node_kind == "SequenceNode":
                bad("number-for-section", "type", "5")
            if node_kind == "SequenceNode" and name in VECTORS and e.key is not None:
                bad("short", "type", "[1, 2]")
                bad("long", "type", "[1, 2, 3, 4]")
            continue
        tag = e.value.tag.rsplit(":", 1)[-1]
        if tag in ("int", "float"):
            bad("quoted", "type", f"'{e.value.value}'")
            bad("mapping", "type", "{a: 1}")
            bad("true", "type", "true")
            for v, label in ((".inf", "inf"), ("-.inf", "-inf"), (".nan", "nan"),
                             ("1e400", "1e400")):
                bad(label, "nonfinite", v)
            bad("digits", "digits", DIGITS)
            if name in POSITIVE | NON_NEGATIVE:
                bad("negative", "range", "-1")
            if name in POSITIVE:
                bad("zero", "range", "0")
            if name in COUNTS:
                bad("fraction", "range", "2.5")
                bad("huge", "range", str(10**12) if name != "seed" else str(2**70))
        elif tag == "bool":
            bad("yes", "type", "yes")
            bad("one", "type", "1")
        elif tag == "str":
            bad("number", "type", "12")
            bad("list", "type", "[a]")
        if name in REQUIRED:
            bad("null", "empty", "null")
    return out


def _work_inputs() -> list[Bad]:
    """Cases that imply too much work: refused before meshing, with ``check`` and ``run``."""
    out: list[Bad] = []
    for case in CASES:
        text, stem = _case_text(case), case.stem
        entries = {e.path: e for e in _entries(text)}
        size = entries.get(("mesh", "element_size"))
        if size is not None:
            for command in ("check", "run"):
                out.append(Bad(f"{stem}:element_size:tiny:{command}", "work",
                               _replace(text, size.value, "1e-5"), command=command,
                               lines=size.lines, words="--allow-large"))
        steps = entries.get(("analysis", "steps"))
        if steps is not None:
            out.append(Bad(f"{stem}:steps:1e8", "work", _replace(text, steps.value, "100000000"),
                           command="run", lines=steps.lines, words="--allow-large"))
            every = entries.get(("analysis", "output_every"))
            frames = entries[("analysis",)].lines | {steps.key.start_mark.line + 1} | (
                every.lines if every is not None else frozenset())
            out.append(Bad(f"{stem}:steps:frames", "work", _replace(text, steps.value, "5000000"),
                           lines=frames, words="--allow-large"))
        length = entries.get(("fracture", "smoothing", "length"))
        lengths = entries.get(("mesh", "geometry", "lengths"))
        if length is not None and lengths is not None:
            # a box of about 5e4 tets (under the bounds), every one in every neighbourhood
            volume = 1.0
            for item in lengths.value.value:
                volume *= float(item.value)
            h = (5.0 * volume / 5e4) ** (1 / 3)
            changed = _replace(_replace(text, length.value, "1e3"), size.value, f"{h:.6g}")
            out.append(Bad(f"{stem}:smoothing:whole-body", "work", changed, command="run",
                           lines=length.lines, words="neighbourhood"))
    big_mesh = Bad("mesh-file:200MB", "work", None, make=_sparse_mesh, command="run",
                   lines=_mesh_file_line(), words="--allow-large")
    return out + [big_mesh]


def _mesh_file_line() -> frozenset:
    text = BLOCK.read_text()
    return frozenset({_line_of(text, "mesh:"), _line_of(text, "  file:")})


def _sparse_mesh(tmp: Path) -> None:
    with open(tmp / "big.msh", "wb") as f:
        f.truncate(200 * 10**6)  # sparse: no disk used
    (tmp / "case.yaml").write_text(_case_text(BLOCK).replace(
        str(MESH), str(tmp / "big.msh")))


def _yaml_inputs() -> list[Bad]:
    """Broken YAML text, encodings, nesting, aliases, odd values, odd paths."""
    base = _case_text(ROOT / "cases" / "cantilever.yaml")
    n = base.count("\n")
    any_line = frozenset()
    title = frozenset({_line_of(base, "title:")})
    units = frozenset({_line_of(base, "units:")})
    modulus = frozenset({_line_of(base, "material:"), _line_of(base, "youngs_modulus:")})
    texts = {
        "unclosed-flow": (base + "extra: [1, 2\n", any_line),
        "tab-indent": (base + "extra:\n\tx: 1\n", any_line),
        "unclosed-quote": (base + 'extra: "abc\n', any_line),
        "duplicate-key": (base + "mesh: {}\n", frozenset({n + 1})),
        "stray-brace": (base + "}\n", any_line),
        "nul": (base.replace("title:", "title: \x00", 1), any_line),
        "bell": (base.replace("title: ", "title: '\x07", 1).replace(
            "end shear load", "end shear load'", 1), any_line),
        "empty": ("", frozenset({1})),
        "comment-only": ("# nothing\n", frozenset({1})),
        "a-list": ("- mesh\n- material\n", frozenset({1})),
        "a-scalar": ("hello\n", frozenset({1})),
        "two-documents": (base + "---\nmesh: {}\n", any_line),
        "flow-depth-60": (base + "extra: " + "[" * 60 + "]" * 60 + "\n", any_line),
        "flow-depth-100000": (base + "extra: " + "[" * 100000 + "]" * 100000 + "\n",
                              any_line),
        "block-depth-1000": (base + "".join(" " * i + f"k{i}:\n" for i in range(1000)),
                             any_line),
        "sequence-depth-1000": (base + "extra: " + "- " * 1000 + "x\n", any_line),
        "alias-bomb": (base + "a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n" + "".join(
            f"{c}: &{c} [{', '.join([f'*{p}'] * 10)}]\n"
            for p, c in zip("abcdefgh", "bcdefghi", strict=True)), any_line),
        "alias-loop": (base + "loop: &x [*x]\n", frozenset({n + 1})),
        "alias-loop-map": (base + "loop: &x {again: *x}\n", frozenset({n + 1})),
        "date": (base.replace("title: cantilever beam, end shear load", "title: 2001-01-01"),
                 title),
        "timestamp": (base.replace("units: SI", "units: 2001-12-14t21:59:43.10-05:00"),
                      units),
        "bad-date": (base.replace("title: cantilever beam, end shear load", "title: 2001-13-45"),
                     title),
        "int-tag": (base.replace("youngs_modulus: 210e9", "youngs_modulus: !!int 3.5"),
                    modulus),
        "str-tag": (base.replace("youngs_modulus: 210e9", "youngs_modulus: !!str 210e9"),
                    modulus),
        "unknown-tag": (base.replace("youngs_modulus: 210e9", "youngs_modulus: !steel 210e9"),
                        modulus),
        "binary": (base.replace("title: cantilever beam, end shear load", "title: !!binary aGk="),
                   title),
        "set": (base.replace("title: cantilever beam, end shear load", "title: !!set {a, b}"),
                title),
        "int-key": (base + "1: one\n", frozenset({n + 1})),
        "bool-key": (base + "true: yes\n", frozenset({n + 1})),
        "null-key": (base + "~: nothing\n", frozenset({n + 1})),
        "complex-key": (base + "? [a, b]\n: c\n", frozenset({n + 1})),
        "digits-in-file": (base.replace("youngs_modulus: 210e9", f"youngs_modulus: {DIGITS}"),
                           modulus),
    }
    out = [Bad(f"yaml:{k}", "yaml", t, lines=lines) for k, (t, lines) in texts.items()]
    raw = base.encode()
    first_comment = raw.index(b"#") + 2
    out += [
        Bad("yaml:not-utf8", "yaml", raw[:first_comment] + b"\xff\xfe" + raw[first_comment:],
            lines=frozenset({1}), words="UTF-8"),
        Bad("yaml:latin-1", "yaml", base.replace("uniform", "unifôrm", 1).encode("latin-1"),
            lines=frozenset(), words="UTF-8"),
        Bad("yaml:utf-16", "yaml", base.encode("utf-16"), lines=frozenset({1}),
            words="UTF-8"),
        Bad("yaml:too-big", "yaml", base + "#" * (11 * 2**20) + "\n", words="MB"),
        Bad("path:missing", "yaml", None, make=lambda tmp: None, words="no such file"),
        Bad("path:directory", "yaml", None, make=lambda tmp: (tmp / "case.yaml").mkdir(),
            words="not a regular file"),
        Bad("path:fifo", "yaml", None, make=lambda tmp: os.mkfifo(tmp / "case.yaml"),
            words="not a regular file"),
        Bad("path:symlink-loop", "yaml", None,
            make=lambda tmp: (tmp / "case.yaml").symlink_to(tmp / "case.yaml")),
    ]
    return out


def _mesh_inputs() -> list[Bad]:
    """The block-with-hole case on broken copies of its mesh file."""
    kinds = ["nan", "inf", "huge", "index-high", "index-negative", "truncated", "garbage",
             "empty", "no-tets", "directory", "text-as-vtu"]
    return [Bad(f"mesh:{k}", "mesh", None, make=_broken_mesh(k),
                lines=_mesh_file_line())
            for k in kinds]


def _broken_mesh(kind: str) -> Callable[[Path], None]:
    def make(tmp: Path) -> None:
        import meshio
        import numpy as np

        suffix = ".vtu" if kind in ("nan", "inf", "huge", "index-high", "index-negative",
                                    "no-tets", "text-as-vtu") else ".msh"
        target = tmp / f"broken{suffix}"
        m = meshio.read(MESH)
        points = np.array(m.points, dtype=float)
        tets = np.array(next(c.data for c in m.cells if c.type == "tetra"))
        if kind in ("nan", "inf", "huge"):
            points[7] = {"nan": np.nan, "inf": np.inf, "huge": 1e200}[kind]
        if kind == "index-high":
            tets[3, 2] = 10**6
        if kind == "index-negative":
            tets[3, 2] = -5
        cells = [("triangle", tets[:, :3])] if kind == "no-tets" else [("tetra", tets)]
        if suffix == ".vtu" and kind != "text-as-vtu":
            meshio.write(target, meshio.Mesh(points, cells))
        elif kind == "text-as-vtu":
            target.write_text("mesh: not really\n")
        elif kind == "truncated":
            target.write_bytes(MESH.read_bytes()[: MESH.stat().st_size // 2])
        elif kind == "garbage":
            target.write_bytes(bytes(random.Random(1).randrange(256) for _ in range(4096)))
        elif kind == "empty":
            target.write_bytes(b"")
        elif kind == "directory":
            target.mkdir()
        (tmp / "case.yaml").write_text(_case_text(BLOCK)
                                       .replace(str(MESH), str(target)))

    return make


def _set_inputs() -> list[Bad]:
    """``--set`` abuse, on every shipped case."""
    sets = {
        "scalar-indexed": "material.youngs_modulus.x=3",
        "item-of-scalar": "material.youngs_modulus.0=3",
        "malformed": "material=[1",
        "malformed-map": "material={a: 1",
        "no-value": "material.youngs_modulus",
        "no-key": "=3",
        "empty-part": "material..youngs_modulus=3",
        "digits": f"material.youngs_modulus={DIGITS}",
        "nan": "material.youngs_modulus=.nan",
        "inf-dt": "analysis.dt=.inf",
        "item-out-of-range": "boundary_conditions.99.type=fixed",
        "name-on-list": "boundary_conditions.first=1",
        "half-fracture": "fracture.tensile_strength=1",
        "half-plasticity": "plasticity.hardening=1e6",
        "half-fragments": "fragments.ground.0.normal=[0, 0, .nan]",
        "type-less-analysis": "analysis={steps: 10}",
        "unknown-section": "mehs.order=2",
        "alias-loop": "material=&a [*a]",
        "binary": "title=!!binary aGk=",
        "date": "title=2001-01-01",
        "surrogate": "title=\udcff",
        "maybe": "fragments.whole_body=maybe",
        "yes": "output.crack_surface=yes",
        "deep": "a" + ".a" * 60 + "=1",
        "deep-value": "extra=" + "[" * 100 + "]" * 100,
        "tiny-dt": "analysis={type: dynamic, dt: 1e-320, steps: 2}",
        "overflowing-steps": "analysis={type: quasi_static, t_end: 1e300, dt: 1e-300}",
    }
    out = []
    for case in CASES:
        for k, s in sets.items():
            section = s.split(".")[0].split("=")[0]
            if k.startswith("half-") and re.search(rf"^{section}:", case.read_text(), re.M):
                continue  # the case has the section: the override is valid
            out.append(Bad(f"{case.stem}:set:{k}", "set", _case_text(case), args=("--set", s),
                           words="--set"))
    return out


def _escape_inputs() -> list[Bad]:
    """Output paths that would leave the output directory (``run``)."""
    from test_cli_errors import BASE

    small = BASE.replace("element_size: 0.5", "element_size: 1.0")

    def file_as_directory(tmp: Path) -> None:
        (tmp / "afile").write_text("not a directory\n")
        (tmp / "case.yaml").write_text(small + f"output:\n  directory: {tmp / 'afile' / 'sub'}\n")

    return [
        Bad("escape:name-parent", "escape", small + "output:\n  name: ../escaped\n",
            command="run", words="output.name"),
        Bad("escape:name-absolute", "escape", None, command="run", words="output.name",
            make=lambda tmp: (tmp / "case.yaml").write_text(
                small + f"output:\n  name: {tmp / 'elsewhere' / 'x'}\n")),
        Bad("escape:name-nested", "escape", small + "output:\n  name: a/b\n", command="run",
            words="output.name"),
        Bad("escape:directory-under-a-file", "escape", None, command="run", args=("--no-o",),
            make=file_as_directory, words="output.directory"),
    ]


def _numeric_inputs() -> list[Bad]:
    """Valid cases no arithmetic survives (``run``): exit 3, naming the step and stage."""
    from test_cli_errors import BASE

    three = frozenset({3})
    soft = BASE.replace("210e9", "1e-100").replace("-1e5", "-1e100")
    moving = ("analysis:\n  type: dynamic\n  dt: 1.0e-4\n  steps: 2\n  initial_velocity:\n"
              "    uniform: [1e100, 0, 0]\n")
    return [
        Bad("numeric:soft-and-loaded", "numeric", soft, command="run", codes=three,
            words="stage"),
        Bad("numeric:soft-plastic", "numeric", soft + "plasticity:\n  yield_stress: 1e-100\n",
            command="run", codes=three, words="stage"),
        Bad("numeric:heavy-and-fast", "numeric", BASE.replace("7850", "1e100") + moving,
            command="run", codes=three, words="stage"),
        Bad("numeric:rigid-heavy-and-fast", "numeric", BASE.replace("7850", "1e100").replace(
            "1.0e-4", "1e100") + moving.replace("1.0e-4", "1e100")
            + "fragments:\n  whole_body: true\n  ground: [{}]\n", command="run",
            codes=three, words="stage"),
        Bad("numeric:tiny-modulus", "numeric", BASE.replace("210e9", "1e-300"),
            command="run", codes=three),
        Bad("numeric:traction-1e300", "numeric", BASE.replace("-1e5", "-1e300"),
            command="run", codes=three, words="stage"),
        Bad("numeric:traction-1e300-fracture", "numeric", BASE.replace("-1e5", "-1e300")
            + "fracture:\n  tensile_strength: 1.0\n  smoothing: {rings: 1}\n", command="run",
            codes=three, words="stage"),
    ]


def inputs() -> list[Bad]:
    out = [b for case in CASES for b in _key_inputs(case)]
    return (out + _work_inputs() + _yaml_inputs() + _mesh_inputs() + _set_inputs()
            + _escape_inputs() + _numeric_inputs())


CATEGORIES = ("misspelt", "type", "nonfinite", "range", "empty", "digits", "work", "yaml",
              "mesh", "set", "escape", "numeric")
# the share of each category the default run takes (the rest: -m slow)
SAMPLE = {"misspelt": 150, "type": 150, "nonfinite": 100, "range": 100, "empty": 50,
          "digits": 20, "set": 100}
ALL = inputs()


def _sample() -> tuple[list[Bad], list[Bad]]:
    rng = random.Random(14)
    fast, slow = [], []
    for category in CATEGORIES:
        members = [b for b in ALL if b.category == category]
        keep = set(rng.sample(range(len(members)), min(SAMPLE.get(category, len(members)),
                                                      len(members))))
        for i, b in enumerate(members):
            (fast if i in keep else slow).append(b)
    return fast, slow


FAST, SLOW = _sample()
# inputs refused, but not yet in the form this file asks for (the owner and the reason)
XFAIL: dict[str, str] = {}  # id -> reason, for an input whose fix is known to be pending


def _params(bads: list[Bad]) -> list:
    return [pytest.param(b, id=b.id, marks=[pytest.mark.xfail(strict=True, reason=XFAIL[b.id])]
                         if b.id in XFAIL else []) for b in bads]


# --- running one ---------------------------------------------------------------------------


class TooSlow(BaseException):  # not an Exception: the CLI's last-resort guard lets it pass
    pass


@contextlib.contextmanager
def _time_limit(seconds: int):
    def alarm(signum, frame):
        raise TooSlow(f"over {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def check_refused(bad: Bad, tmp: Path, capsys) -> None:
    case, out = tmp / "case.yaml", tmp / "out"
    if bad.text is not None:
        (case.write_bytes if isinstance(bad.text, bytes) else case.write_text)(bad.text)
    if bad.make is not None:
        bad.make(tmp)
    args = [a for a in bad.args if a != "--no-o"]
    if bad.command == "run" and "--no-o" not in bad.args:
        args += ["-o", str(out)]
    args += ["-q"] if bad.command == "run" else []
    before = _tree(tmp)
    start = time.perf_counter()
    with _time_limit(SECONDS):
        code = main([bad.command, str(case), *args])
    seconds = time.perf_counter() - start
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    errors = [line for line in lines if line.startswith("error: ")]
    assert code in bad.codes, err
    assert "Traceback" not in err, err
    assert len(errors) == 1, err
    assert all(line.startswith(("error: ", "warning: ")) for line in lines), err
    message = errors[0]
    assert str(case) in message, message
    if bad.lines is not None:
        found = re.search(re.escape(str(case)) + r":(\d+):\d+: ", message)
        assert found, message
        assert not bad.lines or int(found.group(1)) in bad.lines, (sorted(bad.lines), message)
    assert bad.words in message, message
    created = {p for p in _tree(tmp) - before if not p.startswith("out")}
    assert not created, created
    assert seconds < SECONDS, seconds


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """A directory of the input's own; the working directory inside it, so that anything a
    relative path would write lands in the snapshot."""
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    return tmp_path


@pytest.mark.parametrize("bad", _params(FAST))
def test_bad_input_is_refused_in_one_line(bad, workdir, capsys):
    check_refused(bad, workdir, capsys)


@pytest.mark.slow
@pytest.mark.parametrize("bad", _params(SLOW))
def test_every_bad_input_is_refused_in_one_line(bad, workdir, capsys):
    check_refused(bad, workdir, capsys)


def test_the_fuzzer_covers_every_category_and_key():
    counts = {c: sum(b.category == c for b in ALL) for c in CATEGORIES}
    assert all(counts.values()), counts
    assert len(FAST) >= 300, len(FAST)
    misspelt = {b.id.split(":")[0] for b in ALL if b.category == "misspelt"}
    assert misspelt == {c.stem for c in CASES}
