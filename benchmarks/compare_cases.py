"""Run every shipped case, and compare two such runs: fields and history equal to round-off.

Meant for refactors: run the cases with the code before, again with the code after, compare.

    python benchmarks/compare_cases.py run OUTDIR [--cases GLOB ...] [--set KEY=VALUE ...]
    python benchmarks/compare_cases.py compare REF CAND [--rtol 1e-9] [--atol 1e-300]
                                               [--ignore KEY ...]

``run`` runs each case (default: cases/*.yaml and cases/stability/*.yaml, relative to the
working directory) with ``sys.executable -m fem_frac run CASE -o OUTDIR/<name> -q
--overwrite``, one after the other, prints exit code and seconds per case and records them in
OUTDIR/runs.json (<name> is the file's stem, prefixed ``<folder>__`` outside cases/).

``compare`` checks, for every case directory of REF: the exit codes of runs.json, the files,
the .pvd's (file, time) list, every .vtu (points, cell blocks, field/point/cell data),
history.csv (columns and rows; timing columns skipped) and summary.json (recursively; timing,
paths and versions skipped). Floats agree when |a - b| <= max(rtol * scale, atol) with scale
the largest magnitude over the array (a history column, a summary list, a single number);
integers and strings must be equal. ``--ignore`` skips keys, columns or arrays by name, dotted
summary path or glob. Prints OK or each mismatch per case; exits 1 on any mismatch.
"""

from __future__ import annotations

import argparse
import csv
import fnmatch
import glob
import json
import re
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import meshio
import numpy as np

DEFAULT_CASES = ["cases/*.yaml", "cases/stability/*.yaml"]
TIMING = re.compile(r"wall|seconds|elapsed|cpu_time|_s$")
SKIPPED_SUMMARY_KEYS = {"case", "output", "python", "fem_frac", "version"}


class Tol:
    """The tolerance of a comparison and the keys it skips."""

    def __init__(self, rtol: float, atol: float, ignore: list[str]) -> None:
        self.rtol, self.atol, self.ignore = rtol, atol, ignore

    def skips(self, name: str, path: str = "") -> bool:
        return any(fnmatch.fnmatchcase(name, p) or fnmatch.fnmatchcase(path, p)
                   for p in self.ignore)


# --- run ------------------------------------------------------------------------------------

def case_name(case: Path) -> str:
    return case.stem if case.parent.name == "cases" else f"{case.parent.name}__{case.stem}"


def run_cases(outdir: Path, patterns: list[str], sets: list[str]) -> int:
    cases = [Path(p) for pattern in patterns for p in sorted(glob.glob(pattern))]
    outdir.mkdir(parents=True, exist_ok=True)
    runs: dict[str, dict[str, Any]] = {}
    for case in cases:
        name = case_name(case)
        cmd = [sys.executable, "-m", "fem_frac", "run", str(case), "-o", str(outdir / name),
               "-q", "--overwrite"] + [a for s in sets for a in ("--set", s)]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        seconds = time.perf_counter() - t0
        last = (proc.stderr.strip().splitlines() or [""])[-1]
        runs[name] = {"case": str(case), "exit_code": proc.returncode,
                      "seconds": round(seconds, 3), "stderr": last}
        print(f"{name:40s} exit {proc.returncode:3d} {seconds:8.2f} s  {last[:80]}", flush=True)
    (outdir / "runs.json").write_text(json.dumps(runs, indent=1) + "\n")
    return 0


# --- comparison of values -------------------------------------------------------------------

def compare_arrays(a: np.ndarray, b: np.ndarray, where: str, tol: Tol) -> list[str]:
    """Mismatches of two arrays: shape, kind, then values (integers and strings exactly)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        return [f"{where}: shape {a.shape} != {b.shape}"]
    if a.dtype.kind != b.dtype.kind and not {a.dtype.kind, b.dtype.kind} <= {"f", "i", "u"}:
        return [f"{where}: dtype {a.dtype} != {b.dtype}"]
    if a.dtype.kind not in "fc" and b.dtype.kind not in "fc":
        if np.array_equal(a, b):
            return []
        return [f"{where}: {np.count_nonzero(a != b)} of {a.size} values differ (exact)"]
    a, b = a.astype(float), b.astype(float)
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    if not np.array_equal(nan_a, nan_b):
        return [f"{where}: NaN at different places"]
    a, b = np.where(nan_a, 0.0, a), np.where(nan_b, 0.0, b)
    if a.size == 0 or np.array_equal(a, b):
        return []
    scale = max(np.abs(a).max(), np.abs(b).max())
    diff = np.abs(a - b).max()
    if diff <= max(tol.rtol * scale, tol.atol):
        return []
    return [f"{where}: max|diff| {diff:.3e}, scale {scale:.3e} (relative {diff / scale:.1e})"]


def compare_named(ref: dict[str, Any], cand: dict[str, Any], where: str, tol: Tol,
                  compare: Any) -> list[str]:
    """Compare the entries of two name -> value maps; report names only in one of them."""
    out = []
    for key in sorted(set(ref) | set(cand), key=str):
        path = f"{where}.{key}"
        if tol.skips(str(key), re.sub(r"^[^:]*:\s*\.?", "", path)):
            continue
        if key not in cand:
            out.append(f"{where}: '{key}' only in REF")
        elif key not in ref:
            out.append(f"{where}: '{key}' only in CAND")
        else:
            out += compare(ref[key], cand[key], path, tol)
    return out


def compare_json(a: Any, b: Any, where: str, tol: Tol) -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        a = {k: v for k, v in a.items() if k not in SKIPPED_SUMMARY_KEYS and not TIMING.search(k)}
        b = {k: v for k, v in b.items() if k not in SKIPPED_SUMMARY_KEYS and not TIMING.search(k)}
        return compare_named(a, b, where, tol, compare_json)
    if is_numbers(a) and is_numbers(b):
        try:
            return compare_arrays(np.array(a), np.array(b), where, tol)
        except ValueError:  # ragged lists
            pass
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [m for i, (x, y) in enumerate(zip(a, b, strict=True)) for m in
                compare_json(x, y, f"{where}[{i}]", tol)]
    return [] if a == b and type(a) is type(b) else [f"{where}: {a!r} != {b!r}"]


def is_numbers(x: Any) -> bool:
    """A number, or a (nested) list of numbers: compared as one array."""
    if isinstance(x, list):
        return bool(x) and all(is_numbers(v) for v in x)
    return isinstance(x, int | float) and not isinstance(x, bool)


# --- comparison of files --------------------------------------------------------------------

def pvd_entries(path: Path) -> tuple[list[str], np.ndarray]:
    sets = ET.parse(path).getroot().iter("DataSet")
    entries = [(d.get("file", ""), float(d.get("timestep", "nan"))) for d in sets]
    return [f for f, _ in entries], np.array([t for _, t in entries])


def compare_pvd(ref: Path, cand: Path, tol: Tol) -> list[str]:
    (fa, ta), (fb, tb) = pvd_entries(ref), pvd_entries(cand)
    if fa != fb:
        return [f"{ref.name}: files {fa} != {fb}"]
    return compare_arrays(ta, tb, f"{ref.name}: times", tol)


def compare_vtu(ref: Path, cand: Path, tol: Tol) -> list[str]:
    a, b, name = meshio.read(ref), meshio.read(cand), ref.name
    out = compare_arrays(a.points, b.points, f"{name}: points", tol)
    types_a, types_b = [c.type for c in a.cells], [c.type for c in b.cells]
    if types_a != types_b:
        return out + [f"{name}: cell blocks {types_a} != {types_b}"]
    for i, (ca, cb) in enumerate(zip(a.cells, b.cells, strict=True)):
        out += compare_arrays(ca.data, cb.data, f"{name}: cells[{i}] {ca.type}", tol)
    out += compare_named(a.point_data, b.point_data, f"{name}: point_data", tol, compare_arrays)
    out += compare_named(a.field_data, b.field_data, f"{name}: field_data", tol, compare_arrays)
    return out + compare_named(a.cell_data, b.cell_data, f"{name}: cell_data", tol, compare_blocks)


def compare_blocks(a: list[np.ndarray], b: list[np.ndarray], where: str, tol: Tol) -> list[str]:
    if len(a) != len(b):
        return [f"{where}: {len(a)} blocks != {len(b)}"]
    return [m for i, (x, y) in enumerate(zip(a, b, strict=True)) for m in
            compare_arrays(x, y, f"{where}[{i}]", tol)]


def read_csv(path: Path) -> dict[str, list[str]]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    header, body = (rows[0], rows[1:]) if rows else ([], [])
    return {c: [r[i] if i < len(r) else "" for r in body] for i, c in enumerate(header)}


def column(values: list[str]) -> np.ndarray:
    try:
        return np.array([float(v) if v else np.nan for v in values])
    except ValueError:
        return np.array(values)


def compare_history(ref: Path, cand: Path, tol: Tol) -> list[str]:
    a, b = read_csv(ref), read_csv(cand)
    rows_a, rows_b = (len(next(iter(d.values()), [])) for d in (a, b))
    if rows_a != rows_b:
        return [f"{ref.name}: {rows_a} rows != {rows_b}"]
    a = {k: column(v) for k, v in a.items() if not TIMING.search(k)}
    b = {k: column(v) for k, v in b.items() if not TIMING.search(k)}
    return compare_named(a, b, f"{ref.name}: column", tol, compare_arrays)


def compare_summary(ref: Path, cand: Path, tol: Tol) -> list[str]:
    a, b = (json.loads(p.read_text()) for p in (ref, cand))
    return compare_json(a, b, f"{ref.name}:", tol)


COMPARERS = {".vtu": compare_vtu, ".pvd": compare_pvd, ".csv": compare_history,
             ".json": compare_summary}


def compare_case(ref: Path, cand: Path, tol: Tol) -> list[str]:
    if not cand.is_dir():
        return [f"case directory missing in CAND: {cand}"]
    files_a, files_b = ({p.name for p in d.iterdir() if p.is_file()} for d in (ref, cand))
    out = [f"file only in REF: {f}" for f in sorted(files_a - files_b)]
    out += [f"file only in CAND: {f}" for f in sorted(files_b - files_a)]
    for f in sorted(files_a & files_b):
        comparer = COMPARERS.get(Path(f).suffix)
        if comparer is not None:
            out += comparer(ref / f, cand / f, tol)
    return out


def compare_runs(ref: Path, cand: Path) -> dict[str, list[str]]:
    """Exit codes of runs.json, by case (a case missing from CAND's runs.json is reported)."""
    if not (ref / "runs.json").is_file():
        return {}
    a = json.loads((ref / "runs.json").read_text())
    b = json.loads((cand / "runs.json").read_text()) if (cand / "runs.json").is_file() else {}
    return {name: [] if name in b and b[name]["exit_code"] == run["exit_code"] else
            [f"exit code {run['exit_code']} != {b.get(name, {}).get('exit_code', 'no run')}"]
            for name, run in a.items()}


def compare_dirs(ref: Path, cand: Path, tol: Tol) -> int:
    results = compare_runs(ref, cand)
    for case in sorted(d for d in ref.iterdir() if d.is_dir()):
        results[case.name] = results.get(case.name, []) + compare_case(case, cand / case.name, tol)
    extra = sorted(d.name for d in cand.iterdir() if d.is_dir() and not (ref / d.name).is_dir())
    for name, mismatches in sorted(results.items()):
        print(f"{name}: OK" if not mismatches else f"{name}: {len(mismatches)} mismatch(es)")
        for m in mismatches:
            print(f"    {m}")
    for name in extra:
        print(f"{name}: only in CAND (not compared)")
    bad = sum(bool(m) for m in results.values())
    print(f"{len(results) - bad} of {len(results)} cases OK (rtol {tol.rtol:g}, atol {tol.atol:g})")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run the cases into OUTDIR")
    run.add_argument("outdir", type=Path)
    run.add_argument("--cases", nargs="+", default=DEFAULT_CASES, metavar="GLOB")
    run.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     help="passed on to every case (repeatable)")
    cmp = sub.add_parser("compare", help="compare two output folders of `run`")
    cmp.add_argument("ref", type=Path)
    cmp.add_argument("cand", type=Path)
    cmp.add_argument("--rtol", type=float, default=1e-9)
    cmp.add_argument("--atol", type=float, default=1e-300)
    cmp.add_argument("--ignore", action="append", default=[], metavar="KEY")
    args = parser.parse_args(argv)
    if args.command == "run":
        return run_cases(args.outdir, args.cases, args.set)
    return compare_dirs(args.ref, args.cand, Tol(args.rtol, args.atol, args.ignore))


if __name__ == "__main__":
    sys.exit(main())
