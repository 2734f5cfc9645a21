"""The ``fem-frac`` command: ``run`` a case, ``check`` it without solving.

Exit codes: 0 success; 2 bad input (case file, mesh, options, a body left free to move), with
a one-line message and no traceback; 3 a numerical failure (singular system, non-finite
state), output so far kept.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import __version__
from .errors import CaseError, FemFracError, SolverError

EXAMPLES = """examples:
  fem-frac check cases/cantilever.yaml
  fem-frac run cases/cantilever.yaml
  fem-frac run cases/hollow_sphere.yaml -o results/sphere --set mesh.order=2
  paraview out/cantilever/cantilever.pvd
"""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="fem-frac",
        description="Finite-element solver for elastic solids on tetrahedra (plasticity and\n"
        "fracture to come). A YAML case file describes the scene; the output is a VTK\n"
        "time series (.pvd + .vtu) that ParaView opens.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"fem-frac {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    def common(sp):
        sp.add_argument("case", type=Path, help="case file (YAML)")
        sp.add_argument(
            "--set",
            dest="overrides",
            action="append",
            default=[],
            metavar="KEY.PATH=VALUE",
            help="override a case value, e.g. --set material.youngs_modulus=7e10 or "
            "--set boundary_conditions[1].pressure=2e6 (repeatable; VALUE is YAML)",
        )

    run = sub.add_parser(
        "run",
        help="mesh, solve and write the output of a case",
        description="Mesh, solve and write out/<case>/<case>.pvd + .vtu files, summary.json "
        "(wall time per stage, counts, max displacement, strain energy, reactions) and "
        "case.resolved.yaml (the case with every default filled in).",
    )
    common(run)
    run.add_argument("-o", "--output", metavar="DIR", help="output directory "
                     "(default: output.directory of the case, else out/<case name>)")
    run.add_argument("--overwrite", action="store_true",
                     help="replace the results of an earlier run in the output directory")
    run.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")

    check = sub.add_parser(
        "check",
        help="validate a case and mesh it; print mesh statistics, boundary groups and plan",
        description="Validate the case, build the mesh, and print its statistics, element "
        "quality, named boundary groups and the plan of stages that would run. No solve.",
    )
    common(check)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    from .config import CaseErrors, load_case

    source = None
    try:
        case, source = load_case(args.case, args.overrides)
        _warn_units(case, source)
        if args.command == "check":
            from .report import check_report

            print(check_report(case, source))
        else:
            _run(case, source, args)
        return 0
    except CaseErrors as exc:
        for line in exc.lines():
            print(f"error: {line}", file=sys.stderr)
        return 2
    except CaseError as exc:
        where = source.format(exc) if source is not None else exc.message
        print(f"error: {where}", file=sys.stderr)
        return 2
    except SolverError as exc:
        print(f"error: {args.case}: {exc}", file=sys.stderr)
        return 3
    except FemFracError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted; output written so far is kept", file=sys.stderr)
        return 130


def _warn_units(case, source) -> None:
    from .config.units import magnitude_warnings

    for path, message in magnitude_warnings(case):
        print(f"warning: {source.format(CaseError(path, message))}", file=sys.stderr)


def _log(quiet: bool):
    if quiet:
        return lambda _msg: None
    return lambda msg: print(msg, file=sys.stderr, flush=True)


def _run(case, source, args) -> None:
    from .driver import output_location, run_case
    from .report import resolved_case, resolved_yaml

    out_dir, name = output_location(case, args.case, args.output)
    log = _log(args.quiet)
    log(f"case       {args.case}")
    summary = run_case(
        case,
        args.case,
        out_dir,
        name,
        overwrite=args.overwrite,
        log=log,
        resolved_yaml=resolved_yaml(resolved_case(case, source, out_dir, name), source),
    )
    t = summary["wall_time_s"]
    log(f"done       max |u| = {summary['max_displacement']:.6g}, "
        f"strain energy = {summary['strain_energy']:.6g}, {t['total']:.2f} s")


if __name__ == "__main__":
    sys.exit(main())
