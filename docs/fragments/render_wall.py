"""Render the struck wall's image sequence of docs/fragments.md off-screen with pyvista.

    fem-frac run cases/struck_wall.yaml -o out/struck_wall --overwrite -q
    python docs/fragments/render_wall.py out/struck_wall
"""

import sys
from pathlib import Path

import pyvista as pv

FRAMES = (0, 3, 6, 12, 35)  # output steps (every 20 analysis steps of 1 ms)
CAMERA = [(1.2, -2.4, 1.1), (0.25, 0.0, 0.15), (0.0, 0.0, 1.0)]


def render(out: Path, here: Path) -> None:
    series = pv.get_reader(str(out / "struck_wall.pvd"))
    for frame in FRAMES:
        series.set_active_time_point(frame)
        mesh = series.read()[0].warp_by_vector("displacement")
        p = pv.Plotter(off_screen=True, window_size=(800, 450))
        p.add_mesh(mesh, scalars="fragment_id", cmap="tab10", show_edges=True,
                   edge_color="gray", show_scalar_bar=False)
        p.add_mesh(pv.Plane(center=(0.0, 0.0, 0.0), i_size=3.6, j_size=1.6), color="tan")
        p.add_text(f"t = {series.time_values[frame] * 1e3:.0f} ms", font_size=12)
        p.camera_position = CAMERA
        p.screenshot(here / f"struck_wall_{frame:03d}.png")


if __name__ == "__main__":
    render(Path(sys.argv[1]), Path(__file__).resolve().parent)
