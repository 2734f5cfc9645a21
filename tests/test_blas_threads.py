"""The ``fem-frac`` command runs numpy's OpenBLAS on one thread unless told otherwise
(fem_frac/app/cli.py: idle OpenBLAS workers busy-wait and add CPU time, not speed)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

PROBE = """
import ctypes
import json
import fem_frac.app.cli  # noqa: F401  (before numpy, as the command imports it)
import numpy  # noqa: F401
libs = sorted({line.split()[-1] for line in open('/proc/self/maps') if 'openblas' in line.lower()})
counts = []
for path in libs:
    lib = ctypes.CDLL(path)
    for name in ('scipy_openblas_get_num_threads64_', 'scipy_openblas_get_num_threads',
                 'openblas_get_num_threads64_', 'openblas_get_num_threads'):
        if hasattr(lib, name):
            counts.append(getattr(lib, name)())
            break
print(json.dumps(counts))
"""


def _threads(env_value: str | None) -> list[int]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    if env_value is not None:
        env["OPENBLAS_NUM_THREADS"] = env_value
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True,
                         text=True, check=True, timeout=120)
    return json.loads(out.stdout)


@pytest.mark.skipif(not os.path.exists("/proc/self/maps"), reason="needs /proc (Linux)")
def test_openblas_runs_on_one_thread_unless_the_environment_says_otherwise():
    default = _threads(None)
    if not default:
        pytest.skip("numpy is not linked to OpenBLAS here")
    assert default == [1] * len(default)
    if (os.cpu_count() or 1) >= 2:
        assert _threads("2") == [2] * len(default)
