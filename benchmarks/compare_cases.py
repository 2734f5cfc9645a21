"""Run every shipped case; compare two such runs: fields and history equal to round-off.

    python benchmarks/compare_cases.py run OUTDIR [--cases GLOB ...] [--set KEY=VALUE ...]
    python benchmarks/compare_cases.py compare REF CAND [--rtol 1e-9] [--ignore KEY ...]

``run``: cases/*.yaml, cases/stability/*.yaml (default) in turn as ``sys.executable -m fem_frac
run CASE -o OUTDIR/<stem> -q --overwrite`` (stability__<stem>); exit codes in OUTDIR/runs.json.
Each run starts in the checkout that holds this script, so that it runs that checkout's
fem_frac (``-m`` puts the working directory first on ``sys.path``, before ``PYTHONPATH``):
to run an older commit, run the script of a worktree of it (``git worktree add OLD REV``,
then ``python OLD/benchmarks/compare_cases.py run OUT``); GLOBs are relative to that
checkout.
``compare``: per case of REF, exit codes, files, .pvd, .vtu, history.csv, summary.json (no timing,
paths, versions); exit 1 on a mismatch. Floats: |a - b| <= max(rtol * scale, atol), scale the
array's largest magnitude (history's energies share one; ratios have 1).
"""

from __future__ import annotations

import argparse
import base64
import csv
import fnmatch
import glob
import json
import re
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path
from typing import Any, NamedTuple

import meshio
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_CASES = ["cases/*.yaml", "cases/stability/*.yaml"]
TIMING = re.compile(r"wall|seconds|elapsed|cpu_time|_s$")
SKIPPED = {"case", "output", "python", "fem_frac", "version"}  # summary.json keys
RATIO = re.compile(r"relative|residual")  # round-off residues such as 1e-14: against 1


class Tol(NamedTuple):
    """The tolerance of a comparison and the keys it skips."""
    rtol: float = 1e-9
    atol: float = 1e-300
    ignore: tuple[str, ...] = ()

    def skips(self, path: str) -> bool:
        return any(fnmatch.fnmatchcase(path, p) or fnmatch.fnmatchcase(path, f"*.{p}")
                   for p in self.ignore)


def run_cases(outdir: Path, patterns: list[str], sets: list[str]) -> int:
    outdir.mkdir(parents=True, exist_ok=True)
    runs: dict[str, dict[str, Any]] = {}
    outdir = outdir.resolve()
    print(f"fem_frac of {ROOT}", flush=True)
    for case in [Path(p) for pattern in patterns
                 for p in sorted(glob.glob(pattern, root_dir=ROOT))]:
        name = case.stem if case.parent.name == "cases" else f"{case.parent.name}__{case.stem}"
        cmd = [sys.executable, "-m", "fem_frac", "run", str(case), "-o", str(outdir / name),
               "-q", "--overwrite", *(a for s in sets for a in ("--set", s))]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
        seconds, last = time.perf_counter() - t0, (proc.stderr.strip().splitlines() or [""])[-1]
        runs[name] = {"case": str(case), "exit_code": proc.returncode,
                      "seconds": round(seconds, 3), "stderr": last}
        print(f"{name:34s} exit {proc.returncode:3d} {seconds:7.2f} s  {last[:80]}", flush=True)
    (outdir / "runs.json").write_text(json.dumps(runs, indent=1) + "\n")
    return 0


def compare_arrays(a: Any, b: Any, where: str, tol: Tol, floor: float = 0.0) -> list[str]:
    """Shapes, kinds, values: floats to the tolerance, scale at least ``floor``."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        return [f"{where}: shape {a.shape} != {b.shape}"]
    if a.dtype.kind != b.dtype.kind and not {a.dtype.kind, b.dtype.kind} <= {"f", "i", "u"}:
        return [f"{where}: dtype {a.dtype} != {b.dtype}"]
    if a.dtype.kind not in "fc" and b.dtype.kind not in "fc":  # integers, strings: exactly
        n, what = np.sum(a != b), f"{a.tolist()} != {b.tolist()}" if a.size < 4 else ""
        return [f"{where}: {what or f'{n} of {a.size} values differ'}"] if n else []
    a, b = a.astype(float), b.astype(float)
    if not np.array_equal(np.isnan(a), np.isnan(b)):
        return [f"{where}: NaN at different places"]
    a, b = np.nan_to_num(a, nan=0.0), np.nan_to_num(b, nan=0.0)
    if a.size == 0 or np.array_equal(a, b):
        return []
    scale, diff = max(np.abs(a).max(), np.abs(b).max(), floor), np.abs(a - b).max()
    return [] if diff <= max(tol.rtol * scale, tol.atol) else [
        f"{where}: max|diff| {diff:.3e}, scale {scale:.3e} (relative {diff / scale:.1e})"]


def compare_named(ref: dict, cand: dict, where: str, tol: Tol, compare: Any) -> list[str]:
    """The entries of two name -> value maps, and the names that are only in one of them."""
    out = []
    for key in sorted(set(ref) | set(cand), key=str):
        path = f"{where}.{key}" if where else str(key)
        if not tol.skips(path):
            out += ([f"{path}: only in {'REF' if key in ref else 'CAND'}"] if key not in cand
                    or key not in ref else compare(ref[key], cand[key], path, tol))
    return out


def compare_json(a: Any, b: Any, where: str, tol: Tol) -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        a, b = ({k: v for k, v in d.items() if k not in SKIPPED and not TIMING.search(k)}
                for d in (a, b))
        return compare_named(a, b, where, tol, compare_json)
    x, y = numbers(a), numbers(b)
    if x is not None and y is not None:
        floor = 1.0 if RATIO.search(where.rsplit(".", 1)[-1]) else 0.0
        return compare_arrays(x, y, where, tol, floor)
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [m for i, (x, y) in enumerate(zip(a, b, strict=True))
                for m in compare_json(x, y, f"{where}[{i}]", tol)]
    return [] if a == b and type(a) is type(b) else [f"{where}: {a!r} != {b!r}"]


def numbers(x: Any) -> np.ndarray | None:
    """A number or a (nested, not ragged) list of numbers as one array, else None."""
    try:
        arr = np.array(x)
    except ValueError:  # ragged
        return None
    return arr if arr.dtype.kind in "iuf" and arr.size and not isinstance(x, bool) else None


def compare_pvd(ref: Path, cand: Path, tol: Tol) -> list[str]:
    a, b = ([(d.get("file"), float(d.get("timestep", "nan"))) for d in
             ET.parse(p).getroot().iter("DataSet")] for p in (ref, cand))
    fa, fb = [f for f, _ in a], [f for f, _ in b]
    return ([f"files {fa} != {fb}"] if fa != fb else
            compare_arrays([t for _, t in a], [t for _, t in b], "times", tol))


def vtu_arrays(path: Path) -> dict[str, np.ndarray]:
    """Points, cell blocks, point, cell and field data of a .vtu, by name."""
    try:
        m = meshio.read(path)
    except ValueError:
        return read_raw_vtu(path)
    return {"points": m.points, **{f"cells[{i}].{c.type}": c.data for i, c in enumerate(m.cells)},
            **{f"point_data.{k}": v for k, v in m.point_data.items()},
            **{f"cell_data[{i}].{k}": x for k, v in m.cell_data.items() for i, x in enumerate(v)},
            **{f"field_data.{k}": np.asarray(v) for k, v in m.field_data.items()}}


def read_raw_vtu(path: Path) -> dict[str, np.ndarray]:
    """The DataArrays of a zlib-compressed .vtu: meshio fails on empty ones (crack, no face)."""
    root = ET.parse(path).getroot()
    head = np.dtype(root.get("header_type", "UInt32").lower())
    return {f"{sec.tag}.{arr.get('Name')}": np.frombuffer(
        unzip((arr.text or "").strip(), head), arr.get("type", "").lower()).reshape(
        -1, int(arr.get("NumberOfComponents", "1")))
        for sec in root.iter() for arr in sec.findall("DataArray")}


def unzip(text: str, head: np.dtype) -> bytes:
    n = int(np.frombuffer(base64.b64decode(text[:12])[: head.itemsize], head)[0])
    chars = -(-(3 + n) * head.itemsize // 3) * 4  # the header's own base64 block
    sizes = np.frombuffer(base64.b64decode(text[:chars]), head)[3:]
    data, ends = base64.b64decode(text[chars:]), np.cumsum(sizes)
    return b"".join(zlib.decompress(data[e - s:e]) for s, e in zip(sizes, ends, strict=True))


def read_history(path: Path) -> tuple[int, dict[str, np.ndarray]]:
    """Rows, and the columns but timing: integers, floats (blank: NaN) or strings."""
    with path.open(newline="") as f:
        header, *rows = list(csv.reader(f)) or [[]]
    out = {c: np.array([r[i] if i < len(r) else "" for r in rows]) for i, c in enumerate(header)
           if not TIMING.search(c)}
    for c, v in out.items():
        for kind in (int, float):  # else strings
            try:
                out[c] = np.where(v == "", "nan", v).astype(kind)
                break
            except ValueError:
                pass
    return len(rows), out


def scale_group(column: str) -> str:
    """Energies (an energy error is their residue) share a scale, as a reaction's components."""
    m = re.fullmatch(r"(reaction_.+)_[xyz]", column)
    return ("1" if RATIO.search(column) else m[1] if m else
            "energy" if re.search(r"energy|work|dissipation|handed_off", column) else column)


def compare_history(ref: Path, cand: Path, tol: Tol) -> list[str]:
    (rows_a, a), (rows_b, b) = read_history(ref), read_history(cand)
    if rows_a != rows_b:
        return [f"{rows_a} rows != {rows_b}"]
    scales = {"1": 1.0}  # ratios
    for k in (k for k in a.keys() & b.keys() if {a[k].dtype.kind, b[k].dtype.kind} <= set("iuf")):
        top = max(np.nanmax(np.abs(a[k]), initial=0), np.nanmax(np.abs(b[k]), initial=0))
        scales[scale_group(k)] = max(scales.get(scale_group(k), 0.0), top)
    return compare_named(a, b, "", tol, lambda x, y, column, tol: compare_arrays(
        x, y, column, tol, scales.get(scale_group(column), 0.0)))


COMPARERS = {
    ".vtu": lambda a, b, tol: compare_named(vtu_arrays(a), vtu_arrays(b), "", tol, compare_arrays),
    ".json": lambda a, b, tol: compare_json(*(json.loads(p.read_text()) for p in (a, b)), "", tol),
    ".pvd": compare_pvd, ".csv": compare_history}


def compare_case(ref: Path, cand: Path, tol: Tol) -> list[str]:
    if not cand.is_dir():
        return [f"no case folder {cand}"]
    # hidden files (the output manifest) are bookkeeping, not results
    files_a, files_b = ({p.name for p in d.iterdir() if p.is_file()
                         and not p.name.startswith(".")} for d in (ref, cand))
    return [f"{f}: file only in {'REF' if f in files_a else 'CAND'}"
            for f in sorted(files_a ^ files_b)] + [
        f"{f}: {m}" for f in sorted(files_a & files_b) if Path(f).suffix in COMPARERS
        for m in COMPARERS[Path(f).suffix](ref / f, cand / f, tol)]


def compare_dirs(ref: Path, cand: Path, tol: Tol) -> int:
    a, b = ({} if not (d / "runs.json").is_file() else json.loads((d / "runs.json").read_text())
            for d in (ref, cand))
    codes = {name: (run["exit_code"], b.get(name, {}).get("exit_code", "no run"))
             for name, run in a.items()}
    results = {name: [] if x == y else [f"exit code {x} != {y}"] for name, (x, y) in codes.items()}
    for case in sorted(d for d in ref.iterdir() if d.is_dir()):
        results[case.name] = results.get(case.name, []) + compare_case(case, cand / case.name, tol)
    for name, mismatches in sorted(results.items()):
        print(f"{name}: " + (f"{len(mismatches)} mismatch(es)" if mismatches else "OK"))
        print("".join(f"    {m}\n" for m in mismatches), end="")
    for d in sorted(d.name for d in cand.iterdir() if d.is_dir() and d.name not in results):
        print(f"{d}: only in CAND (not compared)")
    bad = sum(bool(m) for m in results.values())
    print(f"{len(results) - bad} of {len(results)} cases OK (rtol {tol.rtol:g}, atol {tol.atol:g})")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run the cases into OUTDIR")
    run.add_argument("outdir", type=Path)
    run.add_argument("--cases", nargs="+", default=DEFAULT_CASES, metavar="GLOB")
    run.add_argument("--set", action="append", default=[], help="for every case (repeatable)")
    cmp = sub.add_parser("compare", help="compare two output folders of `run`")
    cmp.add_argument("ref", type=Path)
    cmp.add_argument("cand", type=Path)
    cmp.add_argument("--rtol", type=float, default=Tol().rtol)
    cmp.add_argument("--atol", type=float, default=Tol().atol, help="absolute floor")
    cmp.add_argument("--ignore", action="append", default=[], help="key to skip (repeatable)")
    args = parser.parse_args(argv)
    return (run_cases(args.outdir, args.cases, args.set) if args.command == "run" else
            compare_dirs(args.ref, args.cand, Tol(args.rtol, args.atol, tuple(args.ignore))))


if __name__ == "__main__":
    sys.exit(main())
