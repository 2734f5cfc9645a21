"""A run stopped from outside says how far it got and keeps a readable series.

Killed outright (SIGKILL: no handler runs) the run leaves what it wrote as it went: a
``.pvd`` listing only complete frames, the resolved case, and a summary marked ``running``
with the step it had reached. Interrupted (SIGINT, SIGTERM) it also marks the summary
``interrupted`` at that step and exits 128 + the signal number.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import pytest

from fem_frac.config import load_case

CASE = Path(__file__).resolve().parents[1] / "cases" / "vibrating_beam.yaml"


def _default_interrupt() -> None:
    """In the child before it starts: SIGINT back to its default. A shell that starts the
    tests in the background has them ignore it, and Python then leaves it ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start(out: Path) -> subprocess.Popen:
    """The vibrating beam, long enough to be stopped half-way (a frame every step)."""
    return subprocess.Popen(
        [sys.executable, "-m", "fem_frac", "run", str(CASE), "-o", str(out), "-q",
         "--set", "analysis.t_end=1.0", "--set", "analysis.output_every=1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=_default_interrupt)


def _wait_for_steps(out: Path, proc: subprocess.Popen, steps: int = 3,
                    limit: float = 120.0) -> dict:
    """Poll the summary until the run reports ``steps`` committed steps."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < limit:
        assert proc.poll() is None, proc.communicate()
        try:
            summary = json.loads((out / "summary.json").read_text())
        except (FileNotFoundError, json.JSONDecodeError):
            summary = {}
        if summary.get("step", 0) >= steps:
            return summary
        time.sleep(0.2)
    proc.kill()
    raise AssertionError("the run reported no progress")


def _signal_masks(pid: int) -> str:
    """The child's ignored and caught signals (/proc), to say why a signal did nothing."""
    try:
        lines = Path(f"/proc/{pid}/status").read_text().splitlines()
    except OSError:
        return "unknown"
    return ", ".join(x.replace("\t", " ") for x in lines if x.startswith(("SigIgn", "SigCgt")))


def _check_kept(out: Path) -> dict:
    """The series, the resolved case and the summary a stopped run leaves."""
    pvd = ET.parse(out / "vibrating_beam.pvd").getroot()
    files = [d.get("file") for d in pvd.iter("DataSet")]
    assert len(files) >= 2
    for f in files:  # every frame listed is complete
        assert len(meshio.read(out / f).points) > 0
    case, _ = load_case(out / "case.resolved.yaml")
    assert case.analysis.t_end == 1.0  # the --set overrides are recorded
    return json.loads((out / "summary.json").read_text())


def test_a_killed_run_leaves_a_readable_series_and_how_far_it_got(tmp_path):
    out = tmp_path / "out"
    proc = _start(out)
    _wait_for_steps(out, proc)
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    summary = _check_kept(out)
    assert summary["status"] == "running" and 3 <= summary["step"] < summary["steps"]


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_run_says_where_it_stopped(tmp_path, signum):
    out = tmp_path / "out"
    proc = _start(out)
    _wait_for_steps(out, proc)
    signals = _signal_masks(proc.pid)
    proc.send_signal(signum)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
        summary = json.loads((out / "summary.json").read_text())
        raise AssertionError(
            f"the run went on after the signal (its masks then: {signals}; it reached step "
            f"{summary.get('step')} of {summary.get('steps')}, {summary.get('status')}); "
            f"stderr: {err[-2000:]}") from None
    assert proc.returncode == 128 + signum
    summary = _check_kept(out)
    assert summary["status"] == "interrupted" and 3 <= summary["step"] < summary["steps"]
    assert f"at step {summary['step']} of {summary['steps']}" in summary["message"]
    assert err.strip().splitlines()[-1].startswith(f"interrupted at step {summary['step']}")
    assert "Traceback" not in err
