"""output.format: vtkhdf, one ``<name>.vtkhdf`` per series (fem_frac/writers/vtkhdf.py).

The shipped brittle bar (cases/bar_tension_break.yaml: it breaks in step 10, its vertices
duplicated along the crack, and the crack-face series goes from one vertex cell to 73
triangles) is run once with format vtu and once with vtkhdf: VTK's own reader
(vtkHDFReader) reads every step of both series equal, exactly, to VTK's reader of that
step's .vtu: points, cell types, connectivity, offsets, every point and cell array, and
the time. The writer alone: topology that changes, quadratic tets, geometry shared between
steps, a run killed between steps, and the errors of a case that asks for what cannot be
written.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.writers.series import SeriesWriter
from solve import SMALL_CASE, write_case

h5py = pytest.importorskip("h5py")
vtk = pytest.importorskip("vtk")
from vtk.util.numpy_support import vtk_to_numpy  # noqa: E402

from fem_frac.writers.vtkhdf import VtkhdfSeriesWriter, read_step  # noqa: E402

CASE = Path(__file__).resolve().parents[1] / "cases" / "bar_tension_break.yaml"
NAME = "bar_tension_break"


# --- reading with VTK ---------------------------------------------------------------------


def grid_arrays(grid) -> dict:
    """Everything of a vtkUnstructuredGrid, as numpy arrays."""
    cells = grid.GetCells()
    out = {"points": vtk_to_numpy(grid.GetPoints().GetData()) if grid.GetNumberOfPoints()
           else np.zeros((0, 3)),
           "types": vtk_to_numpy(grid.GetCellTypes()) if grid.GetNumberOfCells()
           else np.zeros(0, dtype=np.uint8),
           "connectivity": vtk_to_numpy(cells.GetConnectivityArray()),
           "offsets": vtk_to_numpy(cells.GetOffsetsArray())}
    for kind, data in (("point", grid.GetPointData()), ("cell", grid.GetCellData())):
        for i in range(data.GetNumberOfArrays()):
            array = data.GetArray(i)
            out[f"{kind}:{array.GetName()}"] = vtk_to_numpy(array)
    return out


def vtu_steps(pvd: Path) -> list[tuple[float, dict]]:
    """``(time, arrays)`` of every .vtu the .pvd lists, read by VTK's XML reader."""
    out = []
    for ds in ElementTree.parse(pvd).getroot().iter("DataSet"):
        reader = vtk.vtkXMLUnstructuredGridReader()
        reader.SetFileName(str(pvd.parent / ds.get("file")))
        reader.Update()
        out.append((float(ds.get("timestep")), grid_arrays(reader.GetOutput())))
    return out


def vtkhdf_steps(path: Path) -> list[tuple[float, dict]]:
    """``(time, arrays)`` of every step of a .vtkhdf, read by vtkHDFReader."""
    reader = vtk.vtkHDFReader()
    reader.SetFileName(str(path))
    reader.UpdateInformation()
    times = reader.GetOutputInformation(0).Get(
        vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    if times is None:  # VTK gives a series of one step no time: the file's
        with h5py.File(path, "r") as f:
            times = f["VTKHDF/Steps/Values"][:]
    out = []
    for k in range(reader.GetNumberOfSteps()):
        reader.SetStep(k)
        reader.Update()
        out.append((float(times[k]), grid_arrays(reader.GetOutput())))
    return out


def assert_same_steps(hdf: list, vtu: list) -> None:
    assert len(hdf) == len(vtu) > 0
    for k, ((t_h, a_h), (t_v, a_v)) in enumerate(zip(hdf, vtu, strict=True)):
        assert t_h == t_v, k
        assert sorted(a_h) == sorted(a_v), k
        for key in a_v:
            assert a_h[key].shape == a_v[key].shape, (k, key)
            np.testing.assert_array_equal(a_h[key], a_v[key], err_msg=f"step {k}, {key}")


# --- a fracture run in both formats -----------------------------------------------------


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = {}
    for fmt in ("vtu", "vtkhdf"):
        directory = tmp_path_factory.mktemp(fmt)
        assert main(["run", str(CASE), "-o", str(directory), "-q",
                     "--set", "output.crack_surface=true",
                     "--set", f"output.format={fmt}"]) == 0
        out[fmt] = directory
    return out


@pytest.mark.parametrize("series", [NAME, f"{NAME}_crack"])
def test_every_step_of_a_fracture_run_reads_back_equal_to_the_vtu(runs, series):
    hdf = vtkhdf_steps(runs["vtkhdf"] / f"{series}.vtkhdf")
    vtu = vtu_steps(runs["vtu"] / f"{series}.pvd")
    assert_same_steps(hdf, vtu)


def test_the_run_changes_topology_and_the_file_stores_it(runs):
    main_steps = vtkhdf_steps(runs["vtkhdf"] / f"{NAME}.vtkhdf")
    points = [len(a["points"]) for _, a in main_steps]
    assert points[0] < points[-1]  # the crack duplicated vertices
    crack = vtkhdf_steps(runs["vtkhdf"] / f"{NAME}_crack.vtkhdf")
    cells = [len(a["types"]) for _, a in crack]
    assert cells[0] == 1 and cells[-1] > 1  # one vertex cell, then the crack faces
    assert set(crack[0][1]["types"]) == {1} and set(crack[-1][1]["types"]) == {5}
    with h5py.File(runs["vtkhdf"] / f"{NAME}.vtkhdf", "r") as f:
        root = f["VTKHDF"]
        # the reference points are stored once per mesh: before and after the crack
        assert len(root["NumberOfPoints"]) == 2
        assert len(root["Points"]) == points[0] + points[-1]
        assert root["Steps"].attrs["NSteps"] == len(main_steps)


def test_the_run_lists_its_files_and_writes_no_vtu(runs):
    directory = runs["vtkhdf"]
    listed = (directory / ".fem_frac_manifest").read_text().splitlines()
    assert f"{NAME}.vtkhdf" in listed and f"{NAME}_crack.vtkhdf" in listed
    assert not list(directory.glob("*.vtu")) and not list(directory.glob("*.pvd"))
    summary = (directory / "summary.json").read_text()
    assert f"{NAME}.vtkhdf" in summary
    view = (directory / f"{NAME}_view.py").read_text()
    assert 'NAME + ".vtkhdf"' in view and '"_crack.vtkhdf"' in view
    assert 'NAME + ".pvd"' not in view and "_crack.pvd" not in view
    compile(view, "view.py", "exec")


def test_overwrite_removes_the_vtkhdf_and_a_link_at_its_name_is_refused(tmp_path, capsys):
    case = write_case(tmp_path / "beam.yaml", SMALL_CASE)
    out = tmp_path / "out"
    args = ["run", str(case), "-o", str(out), "-q", "--set", "output.format=vtkhdf"]
    assert main(args) == 0
    assert main(args) == 2  # earlier results are kept
    assert "earlier run" in capsys.readouterr().err
    assert main(args + ["--overwrite"]) == 0
    assert len(read_step(out / "beam.vtkhdf", -1)["points"]) > 0
    other = tmp_path / "other"
    target = tmp_path / "precious"
    target.write_text("keep")
    other.mkdir()
    (other / "beam.vtkhdf").symlink_to(target)
    assert main(["run", str(case), "-o", str(other), "-q", "--set",
                 "output.format=vtkhdf"]) == 2
    assert "symbolic link" in capsys.readouterr().err
    assert target.read_text() == "keep"


# --- the writer alone -----------------------------------------------------------------------


def frames(rng):
    """Three steps: two tets, the same mesh again, then three quadratic tets on more
    points (new topology, cell type and counts)."""
    p1 = rng.random((5, 3))
    c1 = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    p2 = rng.random((14, 3))
    c2 = np.array([[0, 1, 2, 3, 4, 5, 6, 7, 8, 9], [1, 2, 3, 10, 5, 11, 4, 12, 13, 8],
                   [0, 2, 3, 10, 6, 8, 7, 11, 12, 13]])
    out = []
    for points, kind, cells in ((p1, "tetra", c1), (p1, "tetra", c1), (p2, "tetra10", c2)):
        out.append((points, (kind, cells), {"displacement": rng.standard_normal((len(points), 3))},
                    {"stress": rng.standard_normal((len(cells), 6)),
                     "fragment_id": np.arange(len(cells), dtype=np.int32),
                     "rigid": np.zeros(len(cells), dtype=np.int8)}))
    return out


@pytest.mark.parametrize("compression", ["none", "zlib"])
def test_steps_of_changing_topology_and_quadratic_tets_read_back_as_their_vtu(
        tmp_path, compression):
    rng = np.random.default_rng(3)
    vtu = SeriesWriter(tmp_path, "a", compression=compression)
    hdf = VtkhdfSeriesWriter(tmp_path, "b", compression=compression)
    for t, data in zip((0.0, 0.25, 1.0 / 3.0), frames(rng), strict=True):
        vtu.write(t, *data)
        hdf.write(t, *data)
    read = vtkhdf_steps(hdf.path)
    assert_same_steps(read, vtu_steps(vtu.pvd_path))
    assert set(read[2][1]["types"]) == {24}  # VTK_QUADRATIC_TETRA, meshio's node order
    with h5py.File(hdf.path, "r") as f:
        root = f["VTKHDF"]
        assert len(root["Points"]) == 5 + 14  # step 1 shares step 0's points
        assert root["Points"].compression == ("gzip" if compression == "zlib" else None)
        assert list(root["Steps/PointOffsets"]) == [0, 0, 5]
    for k, (points, (_, cells), point_data, _) in enumerate(frames(np.random.default_rng(3))):
        step = read_step(hdf.path, k)
        np.testing.assert_array_equal(step["points"], points)
        np.testing.assert_array_equal(step["connectivity"], cells.ravel())
        np.testing.assert_array_equal(step["point_data"]["displacement"],
                                      point_data["displacement"])


def test_an_unchanged_array_is_stored_once(tmp_path):
    points = np.eye(4, 3)
    cells = ("triangle", np.array([[0, 1, 2], [1, 2, 3]]))
    hdf = VtkhdfSeriesWriter(tmp_path, "o")
    for t in range(4):
        hdf.write(float(t), points, cells, {"displacement": np.zeros((4, 3))},
                  {"obstacle_id": np.array([0, 1], dtype=np.int32)})
    with h5py.File(hdf.path, "r") as f:
        assert len(f["VTKHDF/Points"]) == 4 and len(f["VTKHDF/CellData/obstacle_id"]) == 2
    assert [t for t, _ in vtkhdf_steps(hdf.path)] == [0.0, 1.0, 2.0, 3.0]


def test_a_step_that_changes_its_arrays_is_refused(tmp_path):
    hdf = VtkhdfSeriesWriter(tmp_path, "c")
    points, cells = np.eye(4, 3), ("tetra", np.array([[0, 1, 2, 3]]))
    hdf.write(0.0, points, cells, {"u": np.zeros((4, 3))}, {})
    with pytest.raises(Exception, match="'v'"):
        hdf.write(1.0, points, cells, {"u": np.zeros((4, 3)), "v": np.zeros(4)}, {})
    assert len(vtkhdf_steps(hdf.path)) == 1


def test_a_writer_killed_after_two_steps_leaves_a_file_of_two_steps(tmp_path):
    script = textwrap.dedent(f"""
        import os, signal
        import numpy as np
        from fem_frac.writers.vtkhdf import VtkhdfSeriesWriter
        w = VtkhdfSeriesWriter({str(tmp_path)!r}, "k")
        for t in range(2):
            p = np.random.default_rng(t).random((4 + t, 3))
            w.write(float(t), p, ("tetra", np.array([[0, 1, 2, 3]])),
                    {{"u": p.copy()}}, {{"s": np.ones(1) * t}})
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    done = subprocess.run([sys.executable, "-c", script], env={**os.environ},
                          capture_output=True)
    assert done.returncode == -signal.SIGKILL
    steps = vtkhdf_steps(tmp_path / "k.vtkhdf")
    assert [t for t, _ in steps] == [0.0, 1.0]
    assert [len(a["points"]) for _, a in steps] == [4, 5]
    np.testing.assert_array_equal(steps[1][1]["point:u"], steps[1][1]["points"])


# --- what a case may ask ------------------------------------------------------------------


def test_lzma_is_refused_with_vtkhdf(tmp_path, capsys):
    case = write_case(tmp_path / "beam.yaml", SMALL_CASE)
    assert main(["check", str(case), "--set", "output.format=vtkhdf",
                 "--set", "output.compression=lzma"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "output.compression" in err and "lzma" in err


def test_without_h5py_check_and_run_say_how_to_install_it(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "h5py", None)  # import h5py raises ImportError
    case = write_case(tmp_path / "beam.yaml", SMALL_CASE)
    for command in (["check", str(case)], ["run", str(case), "-o", str(tmp_path / "o"), "-q"]):
        assert main([*command, "--set", "output.format=vtkhdf"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err
        assert "output.format" in err and "pip install h5py" in err
        assert "Traceback" not in err
    assert not (tmp_path / "o").exists()
    assert main(["check", str(case)]) == 0  # the default format needs no h5py


# --- commands that read a run's series ------------------------------------------------------


def cantilever(start: dict | None, steps: int) -> dict:
    """A steel cantilever, dynamic, started by ``start`` (a preload pulls its tip)."""
    case = {
        "mesh": {"geometry": {"type": "box", "lengths": [1.0, 0.1, 0.05]},
                 "element_size": 0.05, "order": 1},
        "material": {"youngs_modulus": 2e11, "poissons_ratio": 0.3, "density": 7800},
        "boundary_conditions": [{"type": "fixed", "boundary": "xmin"}],
        "analysis": {"type": "dynamic", "dt": 1e-4, "steps": steps},
    }
    if start is not None:
        case["analysis"]["initial_displacement"] = start
    return case


def test_from_run_starts_from_the_last_step_of_a_vtkhdf_as_of_its_vtu(tmp_path):
    tip = {"type": "traction", "boundary": "xmax", "traction": [0.0, 0.0, -1e6]}
    first = write_case(tmp_path / "first.yaml",
                       cantilever({"preload": {"boundary_conditions": [tip]}}, 3))
    starts = {}
    for fmt in ("vtu", "vtkhdf"):
        assert main(["run", str(first), "-o", str(tmp_path / f"first_{fmt}"), "-q",
                     "--set", f"output.format={fmt}"]) == 0
        second = write_case(tmp_path / f"second_{fmt}.yaml", cantilever(
            {"from_run": {"directory": f"first_{fmt}", "velocity": True}}, 1))
        assert main(["run", str(second), "-o", str(tmp_path / f"second_{fmt}"), "-q"]) == 0
        starts[fmt] = vtu_steps(tmp_path / f"second_{fmt}" / f"second_{fmt}.pvd")[0][1]
    assert np.any(starts["vtu"]["point:velocity"])
    for key in ("point:displacement", "point:velocity"):
        np.testing.assert_array_equal(starts["vtkhdf"][key], starts["vtu"][key])


def test_overlap_says_it_needs_the_vtu_format(tmp_path, capsys):
    case = write_case(tmp_path / "beam.yaml", SMALL_CASE)
    assert main(["run", str(case), "-o", str(tmp_path / "o"), "-q",
                 "--set", "output.format=vtkhdf"]) == 0
    capsys.readouterr()
    assert main(["overlap", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "output.format=vtu" in err
