"""What a run shows while it steps: a bar with the steps done, elapsed time and ETA on a
terminal, the stages' messages above it; plain lines elsewhere; nothing with -q."""

import io
import re
import time

import pytest

from fem_frac.app.cli import main
from fem_frac.app.output import Console, Progress
from fem_frac.solve.state import StepInfo
from solve import SMALL_CASE, write_case


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def _steps(progress: Progress, console, steps: int, message_at: int | None = None,
           explicit: bool = False) -> None:
    for n in range(steps + 1):
        progress(n, 0.5 * n, StepInfo(3, 2e-10), {"crack_faces": 4 * n, "fragments": 1},
                 explicit)
        if n == message_at:
            console(f"fracture   step {n}: 1 site(s) in 1 pass(es)")


def _screen(text: str) -> list[str]:
    """The lines a terminal keeps: what follows the last carriage return of each."""
    return [line.rsplit("\r", 1)[-1] for line in text.split("\n")]


def test_on_a_terminal_a_bar_with_eta_and_the_messages_above_it():
    stream = Terminal()
    console = Console(stream)
    _steps(Progress(console, 4), console, 4, message_at=2)
    console("done       ...")
    out = stream.getvalue()
    assert "\r" in out  # redrawn in place
    assert "ETA ?" in out  # before the first step
    assert re.search(r"ETA \d\d:\d\d", out)
    screen = _screen(out)
    assert screen[0] == "fracture   step 2: 1 site(s) in 1 pass(es)"
    bar = screen[1]
    assert bar.startswith("step       4/4 |") and "100%" in bar and "elapsed 00:0" in bar
    assert "t = 2, 3 iterations, 16 crack faces, 1 fragment, residual 2.0e-10" in bar
    assert screen[2] == "done       ..."
    assert console.bar is None  # the last step closes the bar


def test_an_explicit_step_counts_substeps():
    stream = Terminal()
    console = Console(stream)
    _steps(Progress(console, 2), console, 2, explicit=True)
    bar = _screen(stream.getvalue())[0]
    assert "3 substeps" in bar and "iterations" not in bar and "residual" not in bar


def test_a_run_stopped_early_ends_the_bar_line():
    stream = Terminal()
    console = Console(stream)
    progress = Progress(console, 10)
    progress(0, 0.0, StepInfo(0, 0.0))
    progress(1, 0.1, StepInfo(2, 1e-9))
    console.close()
    assert stream.getvalue().endswith("\n")
    assert _screen(stream.getvalue())[0].startswith("step       1/10 |")


def test_elsewhere_plain_lines_at_a_low_rate_and_the_last_step():
    stream = io.StringIO()
    console = Console(stream)
    _steps(Progress(console, 4), console, 4, message_at=2)  # 10 s between lines
    lines = stream.getvalue().splitlines()
    assert "\r" not in stream.getvalue()
    assert lines[0] == "fracture   step 2: 1 site(s) in 1 pass(es)"
    assert re.fullmatch(r"step       4/4  elapsed 00:00  ETA 00:00  t = 2, 3 iterations, "
                        r"16 crack faces, 1 fragment, residual 2\.0e-10", lines[1])
    assert len(lines) == 2
    stream = io.StringIO()
    _steps(Progress(Console(stream), 4, every=0.0), console, 4)
    assert [line.split()[1] for line in stream.getvalue().splitlines()] == \
        ["1/4", "2/4", "3/4", "4/4"]


def test_eta_at_the_mean_rate_of_the_steps_so_far():
    progress = Progress(lambda _: None, 40)
    now = time.perf_counter()
    progress.start = now - 30.0
    assert progress.eta(0, now) == "?"
    assert progress.eta(10, now) == "01:30"
    assert progress.eta(40, now) == "00:00"


def test_a_plain_log_function_gets_the_plain_lines():
    lines = []
    _steps(Progress(lines.append, 3), lines.append, 3)
    assert [line.split()[1] for line in lines] == ["3/3"]


@pytest.mark.parametrize("stream", [Terminal(), io.StringIO()], ids=["terminal", "pipe"])
def test_quiet_shows_nothing(stream):
    console = Console(stream, quiet=True)
    _steps(Progress(console, 3), console, 3, message_at=1)
    console.close()
    assert stream.getvalue() == ""


CASE = SMALL_CASE


def test_a_run_on_a_pipe_and_with_q(tmp_path, capsys):
    case = write_case(tmp_path / "beam.yaml", CASE)
    assert main(["run", str(case), "-o", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "\r" not in err
    assert re.search(r"^step       2/2  elapsed \S+  ETA 00:00  t = 1, \d+ iterations?, "
                     r"residual \S+$", err, re.M)
    assert re.search(r"^done .*, 2 steps, \d+ iterations, energy balance error \S+ "
                     r"\(relative\), ", err, re.M)
    assert main(["run", str(case), "-o", str(tmp_path / "b"), "-q"]) == 0
    # -q silences progress and messages; warnings about the case stay (this coarse beam
    # has about one linear tet across its depth)
    out, err = capsys.readouterr()
    assert out == "" and err
    assert all(line.startswith("warning: ") for line in err.splitlines())


def test_work_inside_a_step_shows_in_the_bar_and_nowhere_else():
    """A fracture batch under way replaces the bar's status until the step is drawn; off
    a terminal the note is not printed (the stage's own line is)."""
    stream = Terminal()
    console = Console(stream)
    progress = Progress(console, 4)
    progress(0, 0.0, StepInfo(0, 0.0))
    progress(1, 0.1, StepInfo(2, 1e-9))
    console.note("fracture   step 2: pass 1, opening 4 site(s), 0 opened so far")
    assert _screen(stream.getvalue())[-1].endswith("opening 4 site(s), 0 opened so far")
    for n in (2, 3, 4):
        progress(n, 0.1 * n, StepInfo(2, 1e-9))
    assert "t = 0.4" in _screen(stream.getvalue())[0]  # the step's status is back
    plain = io.StringIO()
    Console(plain).note("fracture   step 2: pass 1")
    assert plain.getvalue() == ""
