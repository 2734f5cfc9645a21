"""The ``mesh:`` section of a case -> :class:`Mesh` (gmsh for geometry, meshio for files)."""

from __future__ import annotations

from pathlib import Path

from ..config.schema import MeshSection
from ..errors import CaseError, MeshError
from .mesh import Mesh


def mesh_file_path(section: MeshSection, case_dir: Path) -> Path:
    """The mesh file of ``section``, relative paths taken from the case file's directory."""
    path = Path(section.file).expanduser()
    return path if path.is_absolute() else case_dir / path


def describe_source(section: MeshSection) -> str:
    if section.geometry is not None:
        g = section.geometry
        return f"gmsh {g.type}, element_size {section.element_size:g}, order {section.order}"
    kind = "gmsh .geo" if section.file.endswith(".geo") else "meshio file"
    return f"{kind} {section.file}, order {section.order}"


def build_mesh(section: MeshSection, case_dir: Path) -> Mesh:
    """Mesh the geometry or read the file; errors name the ``mesh`` key they come from."""
    if section.geometry is not None:
        from .geometry import build

        params = section.geometry.model_dump(exclude={"type"})
        try:
            return build(section.geometry.type, params, section.element_size, section.order)
        except MeshError as exc:
            raise CaseError(("mesh", "geometry"), str(exc)) from None
    path = mesh_file_path(section, case_dir)
    if not path.is_file():
        raise CaseError(("mesh", "file"), f"no such mesh file: {path}")
    try:
        if path.suffix == ".geo":
            from .geometry import from_geo_file

            return from_geo_file(path, section.element_size, section.order,
                                 allow_commands=section.allow_geo_commands)
        from .reader import read_mesh_file

        return read_mesh_file(path, section.order)
    except MeshError as exc:
        raise CaseError(("mesh", "file"), str(exc)) from None
