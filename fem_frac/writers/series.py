"""A VTK time series: one ``.vtu`` per output step and a ``.pvd`` index with real times.

The ``.pvd`` is rewritten after every step through a temporary file and a rename, so an
interrupted run leaves a valid, viewable series. Points hold reference coordinates; all
motion goes into the point field ``displacement`` (ParaView: Warp By Vector).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np


@dataclass
class SeriesWriter:
    directory: Path
    name: str
    entries: list[tuple[float, str]] = field(default_factory=list)

    @property
    def pvd_path(self) -> Path:
        return self.directory / f"{self.name}.pvd"

    def write(
        self,
        time: float,
        points: np.ndarray,
        cells: tuple[str, np.ndarray],
        point_data: dict[str, np.ndarray],
        cell_data: dict[str, np.ndarray],
    ) -> Path:
        """Write one step. ``cells`` is ``("tetra" | "tetra10", (n_cells, k))``; cell arrays
        are ``(n_cells,)`` or ``(n_cells, m)``."""
        import meshio

        filename = f"{self.name}_{len(self.entries):06d}.vtu"
        mesh = meshio.Mesh(
            points,
            [cells],
            point_data=point_data,
            cell_data={k: [v] for k, v in cell_data.items()},
        )
        meshio.write(self.directory / filename, mesh, file_format="vtu", binary=True)
        self.entries.append((float(time), filename))
        self._write_index()
        return self.directory / filename

    def _write_index(self) -> None:
        lines = [
            '<?xml version="1.0"?>',
            '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
            "  <Collection>",
        ]
        for time, filename in self.entries:
            attrs = f'timestep="{time:.17g}" group="" part="0" file={quoteattr(filename)}'
            lines.append(f"    <DataSet {attrs}/>")
        lines += ["  </Collection>", "</VTKFile>", ""]
        tmp = self.pvd_path.with_suffix(".pvd.tmp")
        tmp.write_text("\n".join(lines))
        os.replace(tmp, self.pvd_path)
