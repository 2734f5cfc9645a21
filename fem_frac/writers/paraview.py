"""A ParaView script written beside a series: ``<name>_view.py`` opens it with sensible
defaults (warped by ``displacement`` at a visible scale, coloured by ``von_mises``, the
crack-face series on top when there is one, the ground planes of rigid fragments and the
fixed obstacles in grey when there are some, at the last time step).

Run it with ``pvpython <name>_view.py`` (renders and saves ``<name>_view.png``; add
``--interact`` for a window to turn the model in), with ``paraview --script=<name>_view.py``,
or from ParaView's Python Shell (*Run Script*): there it builds the pipeline in the open
session. The series is looked for beside the script, so the output folder can be moved.
With ``output.format: vtkhdf`` the series are ``.vtkhdf`` files (ParaView 5.12 or later
reads their time steps).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

# The warped model shows its largest displacement as about this share of its bounding-box
# diagonal (rounded down to 1, 2 or 5 times a power of ten: between 4 and 10 %).
VISIBLE_SHARE = 0.1


def view_scale(max_displacement: float, points: np.ndarray) -> float:
    """The Warp By Vector scale factor that shows ``max_displacement`` as 4 to 10 % of the
    diagonal of the bounding box of ``points (n, 3)``; 1 (true scale) where the motion is
    already that large (fragments flying off) or there is none."""
    diagonal = float(np.linalg.norm(np.ptp(np.asarray(points, dtype=float), axis=0)))
    if not max_displacement > 0.0 or not np.isfinite(max_displacement) or diagonal == 0.0:
        return 1.0
    wanted = VISIBLE_SHARE * diagonal / max_displacement
    if wanted <= 1.0:
        return 1.0
    power = 10.0 ** np.floor(np.log10(wanted))
    step = max(m for m in (1.0, 2.0, 5.0, 10.0) if m * power <= wanted * (1 + 1e-12))
    return float(step * power)


def write_paraview_script(directory: Path, name: str, scale: float, has_cracks: bool,
                          ground: bool = False, obstacles: bool = False,
                          suffix: str = ".pvd") -> Path:
    """Write ``<name>_view.py`` into ``directory`` (beside ``<name>.pvd`` and, with
    ``has_cracks``, ``<name>_crack.pvd``; with ``ground``, ``<name>_ground.vtu``, shown
    unwarped in grey, half transparent; with ``obstacles``, ``<name>_obstacles.pvd``, the
    fixed obstacles, in grey); warp factor ``scale`` (see :func:`view_scale`); ``suffix``:
    the series files' (``.pvd`` or ``.vtkhdf``). Returns its path."""
    directory = Path(directory)
    path = directory / f"{name}_view.py"
    path.write_text(script_text(name, scale, has_cracks, directory.resolve(), ground,
                                obstacles, suffix))
    return path


def script_text(name: str, scale: float, has_cracks: bool, directory: Path,
                ground: bool = False, obstacles: bool = False, suffix: str = ".pvd") -> str:
    """The text of the view script (see the module docstring)."""
    return _TEMPLATE.format(name=repr(name), ext=suffix, scale=repr(float(scale)),
                            cracks=repr(bool(has_cracks)), ground=repr(bool(ground)),
                            obstacles=repr(bool(obstacles)), directory=repr(str(directory)))


_TEMPLATE = '''\
"""ParaView view of the fem_frac series {name}: the model warped by its displacement
(WARP times), coloured by von_mises, the crack faces coloured by their opening, the ground
planes (fixed: not warped) in grey, half transparent, the fixed obstacles in grey.

    pvpython <this file>               renders the last step, saves NAME_view.png
    pvpython <this file> --interact    and opens a window to turn the model in
    paraview --script=<this file>      opens it in ParaView (or: Python Shell, Run Script)

Written by fem_frac; edit WARP to change the warp factor.
"""

import os
import sys

from paraview.simple import (
    ColorBy,
    GetActiveViewOrCreate,
    GetAnimationScene,
    Interact,
    OpenDataFile,
    PVDReader,
    RenameSource,
    Render,
    SaveScreenshot,
    Show,
    WarpByVector,
    XMLUnstructuredGridReader,
)

NAME = {name}
WARP = {scale}
CRACKS = {cracks}
GROUND = {ground}
OBSTACLES = {obstacles}
# where the series was written; the folder of this file wins when it is known
WRITTEN_IN = {directory}

SCRIPT = globals().get("__file__")
HERE = os.path.dirname(os.path.abspath(SCRIPT)) if SCRIPT else WRITTEN_IN
if not os.path.exists(os.path.join(HERE, NAME + "{ext}")):
    HERE = WRITTEN_IN


def series_reader(path):
    """A reader of a series file: the .pvd index, or a .vtkhdf file."""
    if path.endswith(".pvd"):
        return PVDReader(FileName=path)
    return OpenDataFile(path)


def warped(pvd, label):
    """The series of ``pvd`` moved by its point field displacement, WARP times."""
    reader = series_reader(os.path.join(HERE, pvd))
    RenameSource(label, reader)
    warp = WarpByVector(Input=reader)
    warp.Vectors = ["POINTS", "displacement"]
    warp.ScaleFactor = WARP
    RenameSource(label + " (warp x%g)" % WARP, warp)
    return warp


view = GetActiveViewOrCreate("RenderView")
model = Show(warped(NAME + "{ext}", NAME), view)
ColorBy(model, ("CELLS", "von_mises"))
model.SetScalarBarVisibility(view, True)
cracks = None
if CRACKS and os.path.exists(os.path.join(HERE, NAME + "_crack{ext}")):
    cracks = Show(warped(NAME + "_crack{ext}", NAME + " crack faces"), view)
    ColorBy(cracks, ("CELLS", "opening_norm"))
    cracks.SetScalarBarVisibility(view, True)

scene = GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
scene.GoToLast()
model.RescaleTransferFunctionToDataRange(False, True)
if cracks is not None:
    cracks.RescaleTransferFunctionToDataRange(False, True)
view.ResetCamera()
# the ground after the camera is set: the model fills the view, the ground runs out of it
if GROUND and os.path.exists(os.path.join(HERE, NAME + "_ground.vtu")):
    plane = XMLUnstructuredGridReader(FileName=[os.path.join(HERE, NAME + "_ground.vtu")])
    RenameSource(NAME + " ground", plane)
    ground = Show(plane, view)
    ColorBy(ground, None)
    ground.AmbientColor = [0.6, 0.6, 0.6]
    ground.DiffuseColor = [0.6, 0.6, 0.6]
    ground.Opacity = 0.5
# the fixed obstacles and planes of the case's obstacles (moving ones are in the model)
if OBSTACLES and os.path.exists(os.path.join(HERE, NAME + "_obstacles{ext}")):
    fixed = series_reader(os.path.join(HERE, NAME + "_obstacles{ext}"))
    RenameSource(NAME + " obstacles", fixed)
    obstacles = Show(fixed, view)
    ColorBy(obstacles, None)
    obstacles.AmbientColor = [0.7, 0.7, 0.7]
    obstacles.DiffuseColor = [0.7, 0.7, 0.7]
    obstacles.Opacity = 0.6
Render(view)

# run as a program (pvpython): save a picture, and with --interact open a window
if SCRIPT and sys.argv and os.path.abspath(sys.argv[0]) == os.path.abspath(SCRIPT):
    SaveScreenshot(os.path.join(HERE, NAME + "_view.png"), view, ImageResolution=[1280, 800])
    if "--interact" in sys.argv[1:]:
        Interact(view)
'''
