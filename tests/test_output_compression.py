"""output.compression: the .vtu arrays written plain (the default), with zlib or lzma, and
read back identical (fem_frac.writers.series)."""

import meshio
import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.writers.series import SeriesWriter
from solve import SMALL_CASE, write_case

COMPRESSOR = {"none": None, "zlib": b"vtkZLibDataCompressor", "lzma": b"vtkLZMADataCompressor"}


@pytest.mark.parametrize("compression", ["none", "zlib", "lzma"])
def test_each_compression_reads_back_the_same_arrays(tmp_path, compression):
    rng = np.random.default_rng(1)
    points = rng.random((5, 3))
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    u, s = rng.standard_normal((5, 3)), rng.standard_normal((2, 6))
    path = SeriesWriter(tmp_path, "f", compression=compression).write(
        0.0, points, ("tetra", tets), {"displacement": u}, {"stress": s})
    head = path.read_bytes()[:400]
    if COMPRESSOR[compression] is None:
        assert b"compressor" not in head
    else:
        assert COMPRESSOR[compression] in head
    back = meshio.read(path)
    np.testing.assert_array_equal(back.points, points)
    np.testing.assert_array_equal(back.point_data["displacement"], u)
    np.testing.assert_array_equal(back.cell_data["stress"][0], s)


def test_a_run_writes_plain_arrays_by_default_and_refuses_an_unknown_codec(tmp_path, capsys):
    case = write_case(tmp_path / "beam.yaml", SMALL_CASE)
    assert main(["run", str(case), "-o", str(tmp_path / "a"), "-q"]) == 0
    assert b"compressor" not in (tmp_path / "a" / "beam_000000.vtu").read_bytes()[:400]
    capsys.readouterr()
    assert main(["check", str(case), "--set", "output.compression=lz4"]) == 2
    err = capsys.readouterr().err
    assert "output.compression" in err and len(err.strip().splitlines()) == 1
