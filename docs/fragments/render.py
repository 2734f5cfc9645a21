"""Render the image sequence of docs/fragments.md off-screen with pyvista (no display).

    fem-frac run cases/breaking_beam.yaml -o out/breaking_beam --overwrite -q
    python docs/fragments/render.py out/breaking_beam
"""

import sys
from pathlib import Path

import pyvista as pv

FRAMES = (0, 2, 6, 12, 24, 60)  # output steps (every 10 analysis steps of 2 ms)
CAMERA = [(0.5, -2.2, 0.6), (0.5, 0.0, -0.25), (0.0, 0.0, 1.0)]


def render(out: Path, here: Path) -> None:
    series = pv.get_reader(str(out / "breaking_beam.pvd"))
    for frame in FRAMES:
        series.set_active_time_point(frame)
        mesh = series.read()[0].warp_by_vector("displacement")
        p = pv.Plotter(off_screen=True, window_size=(800, 450))
        p.add_mesh(mesh, scalars="fragment_id", cmap="tab10", show_edges=True,
                   edge_color="gray", show_scalar_bar=False)
        p.add_mesh(pv.Plane(center=(0.5, 0.0, -0.5), i_size=2.2, j_size=2.0), color="tan")
        p.add_text(f"t = {series.time_values[frame] * 1e3:.0f} ms", font_size=12)
        p.camera_position = CAMERA
        p.screenshot(here / f"breaking_beam_{frame:03d}.png")


if __name__ == "__main__":
    render(Path(sys.argv[1] if len(sys.argv) > 1 else "out/breaking_beam"),
           Path(__file__).parent)
