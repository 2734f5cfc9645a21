"""Static runs and loose pieces: a crack that cuts off a sliver (below 1 % of the body's
volume) with no support drops it from the mesh instead of stopping the run; a larger loose
piece still stops it with the located message (fem_frac.fracture.stage)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fem_frac.app.driver import prepare
from fem_frac.config.schema import Case
from fem_frac.errors import SolverError
from fem_frac.fracture.stage import SLIVER, FractureStage
from fem_frac.fracture.topology import open_crack
from fem_frac.mesh.mesh import TET_FACES, Mesh, exterior_face_rows
from fem_frac.solve.state import initial_state
from fem_frac.timing import StageTimer
from fem_frac.world.state import body_of
from fem_frac.world.transfer import rediscretize
from meshes import structured_box

CELLS = 200  # one cell is 0.5 % of the bar


def bar_cut_at(x: float):
    case = {"units": "SI",
            "mesh": {"geometry": {"type": "box", "lengths": [1.0, 0.1, 0.1]},
                     "element_size": 0.1},
            "material": {"youngs_modulus": 1e9, "poissons_ratio": 0.25, "density": 1000},
            "body_force": {"gravity": [0.0, 0.0, -9.81]},
            "boundary_conditions": [{"type": "fixed", "boundary": "xmin"}],
            "fracture": {"tensile_strength": 1e6, "smoothing": {"rings": 1}},
            "analysis": {"type": "static"}}
    case = Case.model_validate(case)
    setup = prepare(case, Path("."), StageTimer())
    mesh = structured_box((CELLS, 1, 1), lengths=(1.0, 0.1, 0.1))
    faces = mesh.tets[:, TET_FACES].reshape(-1, 3)[exterior_face_rows(mesh.tets,
                                                                      mesh.n_points)]
    xmin = faces[np.all(np.abs(mesh.points[faces][:, :, 0]) < 1e-12, axis=1)]
    mesh = Mesh(mesh.points, mesh.tets, {"xmin": xmin})
    plane = np.flatnonzero(np.abs(mesh.points[:, 0] - x) < 1e-9)
    cut, _ = open_crack(mesh, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    disc = rediscretize(setup.disc, cut, StageTimer(), "cut")
    state = initial_state(disc.problem, disc.law, disc.ops, None, disc.constrained)
    stage = FractureStage(case.fracture, False, StageTimer())
    return stage, body_of(disc, state)


def test_a_loose_sliver_is_dropped():
    stage, body = bar_cut_at(1.0 - 1.0 / CELLS)
    assert body.n_pieces == 2
    kept, released = stage.loose(body, 3)
    assert kept.n_pieces == 1
    assert kept.mesh.n_tets == body.mesh.n_tets - 6  # the last cell's six tets
    assert 1.0 / CELLS < SLIVER
    assert released >= 0.0


def test_a_loose_piece_beyond_a_sliver_stops_the_run():
    stage, body = bar_cut_at(0.5)
    with pytest.raises(SolverError, match="step 3, stage fracture: a crack cut off a piece"):
        stage.loose(body, 3)
