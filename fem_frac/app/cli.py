"""The ``fem-frac`` command: ``run`` a case, ``check`` it without solving, ``study`` a grid
of runs (:mod:`fem_frac.app.study`), ``plot`` a run's history (:mod:`fem_frac.app.plot`).

Exit codes: 0 success; 2 bad input (case file, mesh, options, a body left free to move), with
a one-line message and no traceback; 3 a numerical failure (singular system, non-finite
state), output so far kept. ``study`` exits 1 when any of its runs failed (each named on
stderr; the study's outputs are written), 2 for a bad study file.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import warnings
from pathlib import Path

# numpy's and scipy's OpenBLAS on one thread, unless the environment says otherwise (set
# here, before numpy loads it). The dense work of a run is small (3x3 tensors, the n x m
# blocks of a bordered factor), too small for a second thread to pay, and idle OpenBLAS
# workers busy-wait between calls: on 2 cores they added 15-40 % to a run's CPU time at
# the same wall time (docs/performance.md, "Idle BLAS threads"). PARDISO's threads are MKL's.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from .. import __version__
from ..errors import CaseError, FemFracError, Interrupted, SolverError

EXAMPLES = """examples:
  fem-frac check cases/cantilever.yaml
  fem-frac run cases/cantilever.yaml
  fem-frac run cases/hollow_sphere.yaml -o results/sphere --set mesh.order=2
  fem-frac study studies/elastic.yaml --workers 2
  fem-frac plot out/cantilever
  paraview out/cantilever/cantilever.pvd
"""


DESCRIPTION = (
    "Finite-element solver for elastic, elastoplastic and brittle solids on\n"
    "tetrahedra: static, quasi-static and dynamic analyses, cracks opened by face\n"
    "separation where the smoothed stress exceeds the strength. A YAML case file\n"
    "describes the scene; the output is a VTK time series (.pvd + .vtu) that ParaView\n"
    "opens, with a history.csv of energies, reactions and iterations."
)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="fem-frac",
        description=DESCRIPTION,
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"fem-frac {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    _run_parser(sub)
    _check_parser(sub)
    _study_parser(sub)
    _plot_parser(sub)
    _overlap_parser(sub)
    return p


def _case_arguments(sp: argparse.ArgumentParser) -> None:
    """The case file and its ``--set`` overrides, common to ``run`` and ``check``."""
    sp.add_argument("case", type=Path, help="case file (YAML)")
    sp.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY.PATH=VALUE",
        help="override a case value, e.g. --set material.youngs_modulus=7e10 or "
        "--set boundary_conditions[1].pressure=2e6 (repeatable; VALUE is YAML; missing "
        "sections are created)",
    )
    sp.add_argument(
        "--allow-large", action="store_true",
        help="lift the bounds on the work a case may imply (tets, dofs, steps, output "
        "frames, smoothing neighbourhood; see docs/input.md), which refuse it before meshing",
    )


def _run_parser(sub) -> None:
    run = sub.add_parser(
        "run",
        help="mesh, solve and write the output of a case",
        description="Mesh, solve and write out/<case>/<case>.pvd + .vtu files, summary.json "
        "(wall time per stage, counts, max displacement, strain energy, reactions) and "
        "case.resolved.yaml (the case with every default filled in).",
    )
    _case_arguments(run)
    run.add_argument("-o", "--output", metavar="DIR", help="output directory "
                     "(default: output.directory of the case, else out/<case name>)")
    run.add_argument("--overwrite", action="store_true",
                     help="replace the results of an earlier run in the output directory")
    run.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")


def _check_parser(sub) -> None:
    check = sub.add_parser(
        "check",
        help="validate a case and mesh it; print mesh statistics, boundary groups and plan",
        description="Validate the case, build the mesh, and print its statistics, element "
        "quality, named boundary groups and the plan of stages that would run. No solve.",
    )
    _case_arguments(check)


def _study_parser(sub) -> None:
    study = sub.add_parser(
        "study",
        help="sweep a case over a grid of settings: error against wall time, CSV and plot",
        description="Run every combination of the grid of a study file (each in a process of "
        "its own, as `fem-frac run` with --set overrides), then write study.csv (wall time, "
        "peak memory, error per run), study.json (convergence rates, Pareto front) and "
        "study.png (error against wall time, log-log; needs matplotlib). Runs whose "
        "summary.json says completed are kept, so an interrupted study resumes (failed runs are "
        "run again). Exits 1 when any run failed, naming each. See docs/studies.md.",
    )
    study.add_argument("study", type=Path, help="study file (YAML)")
    study.add_argument("-o", "--output", metavar="DIR",
                       help="output directory (default: out/<study file name>)")
    study.add_argument("--workers", type=int, metavar="N",
                       help="runs in parallel (default: workers of the study file, else the "
                       "number of cores)")
    study.add_argument("--scheduler", metavar="ADDRESS",
                       help="run on a Dask distributed cluster: the scheduler's address "
                       "(tcp://HOST:PORT), or 'local' for a local cluster of --workers "
                       "processes; workers need fem-frac installed, no shared filesystem "
                       "(pip install 'fem-frac[cluster]'; docs/studies.md, On a cluster)")
    study.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")


def _plot_parser(sub) -> None:
    plot = sub.add_parser(
        "plot",
        help="draw a run's history: energies, reactions, cracks, solver cost (PNG)",
        description="Read history.csv (and summary.json) of a run's output directory and "
        "write plot_energy.png (energies, energy balance error), plot_reactions.png "
        "(support reactions, largest displacement), plot_fracture.png (crack faces and "
        "area, fragments, sites opened; with fracture or fragments) and plot_solver.png "
        "(iterations or substeps, residual, wall time per step) beside them; prints the "
        "paths. No other file is touched. Needs matplotlib: pip install 'fem-frac[study]'.",
    )
    plot.add_argument("directory", type=Path, metavar="OUT_DIR",
                      help="output directory of `fem-frac run`")


def _overlap_parser(sub) -> None:
    overlap = sub.add_parser(
        "overlap",
        help="how deep the bodies of a run's output lie in each other, frame by frame",
        description="Read every frame of a run's series (and its ground planes) and print "
        "the deepest overlap of each frame where bodies (pieces of the finite-element "
        "part, rigid fragments, ground planes) lie in each other: the largest depth of a "
        "surface point of one body inside another, against the smaller body's size "
        "(V^(1/3)). Exit 0 when every frame is within 1 %% of it, 1 when one is not, 2 "
        "when the directory holds no series. Needs pyvista.",
    )
    overlap.add_argument("directory", type=Path, metavar="OUT_DIR",
                         help="output directory of `fem-frac run`")


def _overlap(args) -> int:
    from .overlap import TOLERANCE, OverlapError, report, run_overlaps

    try:
        overlaps = run_overlaps(args.directory)
    except (OverlapError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(report(overlaps))
    return 0 if max(o.fraction for o in overlaps) <= TOLERANCE else 1


def _plot(args) -> int:
    from .plot import PlotError, plot_run

    try:
        paths = plot_run(args.directory)
    except PlotError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for path in paths:
        print(path)
    return 0


def console() -> None:
    """The ``fem-frac`` command (and ``python -m fem_frac``): :func:`main`; ``run`` and
    ``check`` skip what they do not use (:mod:`fem_frac.app.startup`: numpy's unread
    submodules, pydantic's plugin search, the collector's passes over the imports, the
    interpreter's teardown). ``--help`` imports neither numpy nor scipy; ``study`` (its
    workers, a dask cluster) and ``plot`` leave the usual way."""
    from .startup import import_for_run, leave

    if sys.argv[1:2] not in (["run"], ["check"]):
        sys.exit(main())
    if not {"-h", "--help"} & set(sys.argv):
        try:
            import_for_run()
        except KeyboardInterrupt:  # as main() answers one, before any output
            print("interrupted", file=sys.stderr)
            sys.exit(130)
        except ImportError:  # a broken installation: main() imports again and says so
            pass
    leave(main())


def main(argv: list[str] | None = None) -> int:
    """The command line; under ``mpiexec -n N`` rank 0 runs it and the other ranks serve
    its PETSc solves (fem_frac/solve/ranks.py)."""
    from ..solve.ranks import main as on_ranks

    return on_ranks(_main, argv)


def _main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    if args.command == "study":
        return _study(args)
    if args.command == "plot":
        return _plot(args)
    if args.command == "overlap":
        return _overlap(args)
    from ..config import CaseErrors, load_case

    source = None
    try:
        case, source = load_case(args.case, args.overrides)
        _warn_units(case, source)
        _refuse_before_meshing(case, args)
        with _overflow_stops():
            if args.command == "check":
                from .report import check_report

                print(check_report(case, source))
            else:
                _run(case, source, args)
        return 0
    except CaseErrors as exc:
        _error(exc.line())
        return 2
    except CaseError as exc:
        _error(source.format(exc) if source is not None else f"{args.case}: {exc.message}")
        return 2
    except SolverError as exc:
        _error(f"{args.case}: {_stage_of(exc)}{exc}")
        return 3
    except FemFracError as exc:
        _error(str(exc))
        return 2
    except Interrupted as exc:
        where = f" in {exc.directory}" if exc.directory is not None else ""
        print(f"interrupted at step {exc.step} of {exc.steps}; output so far kept{where}",
              file=sys.stderr)
        return 128 + int(exc.signum)
    except KeyboardInterrupt:
        print("interrupted; output written so far is kept", file=sys.stderr)
        return 130
    except Exception as exc:  # the last resort: one line, never a traceback
        return _unexpected(exc, args)


def _error(text: str) -> None:
    """``error: text`` on one line of stderr, whatever the text holds (newlines, control
    characters, bytes that were not UTF-8 in the arguments: escaped)."""
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in " ".join(str(text).split()))
    text = text.encode("utf-8", "backslashreplace").decode("utf-8")
    print(f"error: {text}", file=sys.stderr)


def _refuse_before_meshing(case, args) -> None:
    """The checks that need no mesh: the work the case implies (unless --allow-large) and
    the fit of its reference."""
    from .budget import BOUNDS, check_budget
    from .reference import check_reference

    check_budget(case, args.case.parent, None if args.allow_large else BOUNDS)
    check_reference(case)


@contextlib.contextmanager
def _overflow_stops():
    """numpy's "overflow encountered" warning raised as an error where it happens: a
    state that overflowed is a numerical failure (exit 3, naming the step and stage), not a
    run that ends well with infinite energies."""
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message="overflow encountered",
                                category=RuntimeWarning)
        yield


def _stage_of(exc: BaseException) -> str:
    """``step n, stage s: `` of the step loop's frame ``exc`` passed through, unless the
    message says so already (a numerical failure deep in shared code knows neither)."""
    from .status import stage_of

    return stage_of(exc)


def _unexpected(exc: Exception, args) -> int:
    """An exception no check foresaw: a numerical one (overflow, LAPACK) is exit 3 like a
    SolverError; anything else exit 1, reported as an internal error in one line."""
    from .status import NUMERICAL, failure_message

    if isinstance(exc, NUMERICAL):
        _error(f"{args.case}: {failure_message(exc)}")
        return 3
    text = f"{type(exc).__name__}: {exc}"
    _error(f"{args.case}: internal error ({text}); please report it with the case file")
    return 1


def _warn_units(case, source) -> None:
    from ..config.units import magnitude_warnings

    for path, message in magnitude_warnings(case):
        print(f"warning: {source.format(CaseError(path, message))}", file=sys.stderr)


def _log(quiet: bool):
    """The messages of a command, on stderr (``quiet``: none); a run's progress bar is
    drawn there too when stderr is a terminal."""
    from .output import Console

    return Console(sys.stderr, quiet)


def _run(case, source, args) -> None:
    from .budget import BOUNDS
    from .driver import output_location, run_case
    from .report import resolved_case, resolved_yaml

    out_dir, name = output_location(case, args.case, args.output)
    _check_output_directory(case, args, out_dir, name)
    log = _log(args.quiet)
    log(f"case       {args.case}")
    try:
        summary = run_case(
            case,
            args.case,
            out_dir,
            name,
            overwrite=args.overwrite,
            log=log,
            resolved_yaml=resolved_yaml(resolved_case(case, source, out_dir, name), source),
            bounds=None if args.allow_large else BOUNDS,
        )
    finally:
        log.close()  # a run stopped early leaves its progress bar: end that line
    t = summary["wall_time_s"]
    a = summary["analysis"]
    extra = ""
    if a["steps"] > 1 or case.plasticity is not None:
        # an explicit step counts one iteration per substep of central difference
        counts = ("substeps" if getattr(case.analysis, "integrator", None)
                  == "central_difference" else "iterations")
        extra = (f", {a['steps']} steps, {a['iterations']} {counts}, energy balance error "
                 f"{a['energy_error_relative']:.1e} (relative)")
    if case.plasticity is not None:
        extra += f", plastic dissipation = {summary['plastic_dissipation']:.6g}"
    log(f"done       max |u| = {summary['max_displacement']:.6g}, "
        f"strain energy = {summary['strain_energy']:.6g}{extra}, {t['total']:.2f} s")


def _check_output_directory(case, args, out_dir: Path, name: str) -> None:
    """An output directory that cannot hold the run, refused before any work; located at
    ``output.directory`` when the case chose it."""
    from ..writers.directory import check_directory

    try:
        check_directory(out_dir, name, args.overwrite)
    except FemFracError as exc:
        if args.output is None and case.output.directory is not None:
            raise CaseError(("output", "directory"), str(exc)) from None
        raise


def _study_options(args) -> str | None:
    """Why the options of ``study`` cannot be taken (``None`` when they can)."""
    if args.workers is not None and args.workers < 1:
        return f"--workers {args.workers}: must be >= 1"
    if args.scheduler is None:
        return None
    if args.workers is not None and args.scheduler != "local":
        return (f"--workers {args.workers}: the runs in parallel on a cluster are its "
                "workers' threads (start its workers with --nthreads 1); --workers goes with "
                "--scheduler local or with no --scheduler")
    from .study.cluster import require_distributed

    try:
        require_distributed()
    except FemFracError as exc:
        return str(exc)
    return None


def _study(args) -> int:
    from ..config import CaseErrors
    from .study import StudyErrors, failure_line, load_study, run_study, write_outputs

    problem = _study_options(args)
    if problem is not None:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    log = _log(args.quiet)
    try:
        study = load_study(args.study)
    except (StudyErrors, CaseErrors) as exc:
        for line in exc.lines():
            print(f"error: {line}", file=sys.stderr)
        return 2
    except FemFracError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out_dir = Path(args.output) if args.output else Path("out") / study.name
    log(f"study      {args.study}: {len(study.runs)} runs of {study.case_path} -> {out_dir}")
    try:
        results = run_study(study, out_dir, args.workers, log, args.scheduler)
        outcome = write_outputs(study, results, out_dir)
    except KeyboardInterrupt:
        print("interrupted; finished runs are kept (run the study again to resume)",
              file=sys.stderr)
        return 130
    except FemFracError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for w in outcome.warnings:
        print(f"warning: {w}", file=sys.stderr)
    failed = [r for r in results if not r.ok]
    log(f"done       {len(results) - len(failed)}/{len(results)} runs ok"
        + (f", {len(failed)} failed (see study.csv)" if failed else "")
        + f"; {outcome.csv}" + (f", {outcome.png}" if outcome.png else ""))
    for r in failed:  # even with -q: a study with failed runs exits 1 and says which
        _error(failure_line(r))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
