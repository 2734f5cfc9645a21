"""Render the pictures of docs/fracture.md off-screen with pyvista (no display needed).

    for c in notched_beam plate_with_hole impact_plate; do
        fem-frac run cases/$c.yaml -o out/$c --overwrite -q; done
    python docs/fracture/render.py out
"""

import sys
from pathlib import Path

import pyvista as pv

VIEWS = {  # case: (scalar field, warp factor, camera, zoom)
    "notched_beam": ("smoothed_max_principal_stress", 300, "xz", 3.0),
    "plate_with_hole": ("fragment_id", 300, "xy", 1.0),
    "impact_plate": ("fragment_id", 3,
                     [(0.05, -0.12, -0.12), (0.05, 0.05, 0.005), (0, 0, 1)], 1.0),
}


def render(out: Path, case: str, here: Path) -> None:
    field, factor, camera, zoom = VIEWS[case]
    last = sorted((out / case).glob(f"{case}_[0-9]*.vtu"))[-1]
    mesh = pv.read(last).warp_by_vector("displacement", factor=factor)
    p = pv.Plotter(off_screen=True, window_size=(900, 600))
    p.add_mesh(mesh, scalars=field, cmap="coolwarm", show_edges=case == "notched_beam",
               edge_color="gray", line_width=0.3,
               scalar_bar_args={"title": field.replace("_", " ")})
    p.camera_position = camera
    p.camera.zoom(zoom)
    p.screenshot(here / f"{case}.png")


if __name__ == "__main__":
    for name in VIEWS:
        render(Path(sys.argv[1] if len(sys.argv) > 1 else "out"), name, Path(__file__).parent)
