"""Render the image sequences of docs/fragments.md off-screen with pyvista (no display).

    fem-frac run cases/breaking_beam.yaml -o out/breaking_beam --overwrite -q
    python docs/fragments/render.py out/breaking_beam
    fem-frac run cases/struck_wall.yaml -o out/struck_wall --overwrite -q
    python docs/fragments/render.py out/struck_wall

The scene is the run's series name (the output directory holds ``<name>.pvd``).
"""

import sys
from pathlib import Path

import pyvista as pv

# per series: output steps to draw, camera, ground square (centre, sizes), time unit label
SCENES = {
    # every 10 analysis steps of 2 ms
    "breaking_beam": ((0, 2, 6, 12, 24, 60), [(0.5, -2.2, 0.6), (0.5, 0.0, -0.25), (0, 0, 1)],
                      ((0.5, 0.0, -0.5), 2.2, 2.0)),
    # every 20 analysis steps of 1 ms
    "struck_wall": ((0, 3, 6, 12, 35), [(1.2, -2.4, 1.1), (0.25, 0.0, 0.15), (0, 0, 1)],
                    ((0.0, 0.0, 0.0), 3.6, 1.6)),
}


def render(out: Path, here: Path) -> None:
    pvd = next(p for p in sorted(out.glob("*.pvd")) if p.stem in SCENES)
    frames, camera, (centre, i_size, j_size) = SCENES[pvd.stem]
    series = pv.get_reader(str(pvd))
    for frame in frames:
        series.set_active_time_point(frame)
        mesh = series.read()[0].warp_by_vector("displacement")
        p = pv.Plotter(off_screen=True, window_size=(800, 450))
        p.add_mesh(mesh, scalars="fragment_id", cmap="tab10", show_edges=True,
                   edge_color="gray", show_scalar_bar=False)
        p.add_mesh(pv.Plane(center=centre, i_size=i_size, j_size=j_size), color="tan")
        p.add_text(f"t = {series.time_values[frame] * 1e3:.0f} ms", font_size=12)
        p.camera_position = camera
        p.screenshot(here / f"{pvd.stem}_{frame:03d}.png")


if __name__ == "__main__":
    render(Path(sys.argv[1] if len(sys.argv) > 1 else "out/breaking_beam"),
           Path(__file__).parent)
