"""fem_frac.writers.vtu writes meshio's ``vtu`` layout byte for byte (all but the comment
line naming the writer), for every cell kind, dtype and codec the series use, empty
frames included; and meshio reads the arrays back."""

import meshio
import numpy as np
import pytest

from fem_frac.writers.vtu import VTK_TYPES, write_vtu

WIDTH = {"vertex": 1, "triangle": 3, "quad": 4, "tetra": 4, "tetra10": 10}


def _frame(kind: str, n: int, m: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    points = rng.standard_normal((n, 3))
    cells = rng.integers(0, max(n, 1), (m, WIDTH[kind])).astype(np.int32 if seed % 2 else
                                                                  np.int64)
    point_data = {"displacement": rng.standard_normal((n, 3)), "w": rng.random(n)}
    cell_data = {"stress": rng.standard_normal((m, 6)),
                 "fragment_id": rng.integers(0, 5, m).astype(np.int32),
                 "flag": rng.integers(0, 2, m).astype(np.uint8)}
    return points, (kind, cells), point_data, cell_data


def _meshio_bytes(path, points, cells, point_data, cell_data, compression):
    mesh = meshio.Mesh(points, [cells], point_data=dict(point_data),
                       cell_data={k: [v] for k, v in cell_data.items()})
    meshio.vtu.write(path, mesh, binary=True, compression=compression)
    return path.read_bytes()


def _without_comment(data: bytes) -> list[bytes]:
    return [line for line in data.split(b"\n") if not line.startswith(b"<!--")]


@pytest.mark.parametrize("compression", [None, "zlib", "lzma"])
@pytest.mark.parametrize("kind", sorted(VTK_TYPES))
@pytest.mark.parametrize("size", [(0, 0), (7, 5), (3000, 4500)])
def test_the_same_bytes_as_meshio(tmp_path, kind, compression, size):
    seed = sum(map(ord, kind)) + size[0]
    frame = _frame(kind, *size, seed=seed)
    ours = tmp_path / "ours.vtu"
    write_vtu(ours, *frame, compression=compression)
    theirs = _meshio_bytes(tmp_path / "theirs.vtu", *frame, compression)
    assert _without_comment(ours.read_bytes()) == _without_comment(theirs)
    assert ours.read_bytes().count(b"<!--") == 1
    if size[1]:
        back = meshio.read(ours)
        np.testing.assert_array_equal(back.points, frame[0])
        np.testing.assert_array_equal(back.cells[0].data, frame[1][1])
        for name, values in frame[3].items():
            np.testing.assert_array_equal(back.cell_data[name][0], values)


def test_arrays_of_the_wrong_length_are_refused(tmp_path):
    points, cells, point_data, cell_data = _frame("tetra", 6, 4)
    with pytest.raises(ValueError, match="point array 'w'"):
        write_vtu(tmp_path / "a.vtu", points, cells, {"w": np.zeros(5)}, cell_data)
    with pytest.raises(ValueError, match="cell array 'stress'"):
        write_vtu(tmp_path / "a.vtu", points, cells, point_data, {"stress": np.zeros(3)})
