"""Element-wise work over the cores (fem_frac.threads): the ranges cover the items in order,
an error in any range is raised, and the split work is the same bits as one call."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from fem_frac import threads
from fem_frac.fem.tensors import matrices_from_mandel, principal
from fem_frac.fracture.smoothing import smooth


@pytest.fixture
def split(monkeypatch):
    """Split from 8 items over 3 threads, whatever this machine has."""
    monkeypatch.setattr(threads, "MIN_ITEMS", 8)
    monkeypatch.setattr(threads, "threads", lambda: 3)


def test_ranges_cover_the_items_in_order(split):
    assert threads.map_ranges(lambda a, b: (a, b), 10) == [(0, 3), (3, 6), (6, 10)]
    assert threads.map_ranges(lambda a, b: (a, b), 7) == [(0, 7)]  # below MIN_ITEMS


def test_an_error_in_a_thread_is_raised(split):
    def fail_late(a, b):
        if a > 0:
            raise ValueError(f"range {a}:{b}")
        return a

    with pytest.raises(ValueError, match="range 3:6|range 6:10"):
        threads.map_ranges(fail_late, 10)


def test_threads_follow_omp_num_threads(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert threads.threads() == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "x")
    assert 1 <= threads.threads() <= threads.MAX_THREADS


def test_split_eigen_decomposition_and_smoothing_are_the_same_bits(split):
    rng = np.random.default_rng(0)
    m = 1001
    stress = rng.standard_normal((6, m))
    values, vectors = principal(stress)
    one = np.linalg.eigh(matrices_from_mandel(stress))
    np.testing.assert_array_equal(values, one[0])
    np.testing.assert_array_equal(vectors, one[1])
    rows = np.repeat(np.arange(m), 7)
    operator = sp.csr_matrix((rng.random(rows.size), (rows, rng.integers(0, m, rows.size))),
                             shape=(m, m))
    smoothed = smooth(operator, stress)
    assert smoothed.shape == stress.shape
    np.testing.assert_array_equal(smoothed, np.asarray((operator @ stress.T).T))
