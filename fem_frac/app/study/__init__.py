"""Parameter studies: ``fem-frac study STUDY.yaml``.

A study sweeps a base case over a grid of settings. Every combination of the grid is one
run: its values are applied as ``--set`` overrides and the run is ``python -m fem_frac run``
(exactly the code path of ``fem-frac run``) in a process of its own, so that its peak
resident memory (``ru_maxrss``) is its own. The study writes

- ``runs/<run id>/``: the output of each run (``summary.json``, ``.pvd``, ...);
- ``study.csv``: one row per run (grid values, method, dofs, wall time total and per stage,
  peak memory, error, status);
- ``study.json``: the fitted convergence rate of each method, the reference values used and
  the Pareto front;
- ``study.png``: error against wall time, log-log, one line per method (needs matplotlib).

A study is resumable: a run whose ``summary.json`` says it completed is not run again (one
that failed, was interrupted or killed is run again). A failed run is recorded (exit code,
message, the last step it completed) and does not stop the study; ``fem-frac study`` then
names every failed run on stderr and exits 1 once the outputs are written.

The error of a run is either the relative error against the exact solution the case
declares (``error: reference``, from ``summary.json``), or, for ``error: {quantity: NAME}``,
the relative difference of a summary quantity from a reference value estimated per method
by Richardson extrapolation of its three finest runs (:func:`richardson`).

Modules: :mod:`.spec` (the study file and its grid), :mod:`.runs` (running it),
:mod:`.analysis` (errors, rates, Pareto front), :mod:`.output` (csv, json, plot); for
``--scheduler`` (a Dask cluster, no shared filesystem): :mod:`.cluster` (submitting and
gathering), :mod:`.inputs` (the files a run reads), :mod:`.remote` (the task on a worker and
what it sends back).
"""

from .analysis import (
    Extrapolation,
    convergence_rate,
    evaluate,
    methods,
    pareto_front,
    rates,
    richardson,
    summary_value,
)
from .output import MATPLOTLIB_HINT, Outcome, plot, study_json, write_csv, write_outputs
from .runs import Result, execute, failure_line, run_study
from .spec import (
    SIZE_KEY,
    Axis,
    ErrorSpec,
    Run,
    Study,
    StudyErrors,
    StudyFile,
    load_study,
    method_label,
    run_id,
)

__all__ = [
    "MATPLOTLIB_HINT",
    "SIZE_KEY",
    "Axis",
    "ErrorSpec",
    "Extrapolation",
    "Outcome",
    "Result",
    "Run",
    "Study",
    "StudyErrors",
    "StudyFile",
    "convergence_rate",
    "evaluate",
    "execute",
    "failure_line",
    "load_study",
    "method_label",
    "methods",
    "pareto_front",
    "plot",
    "rates",
    "richardson",
    "run_id",
    "run_study",
    "study_json",
    "summary_value",
    "write_csv",
    "write_outputs",
]
