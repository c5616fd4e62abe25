"""openCARP's text mesh format (``carp_txt``, as openCARP and its meshtool read it).

A mesh written to ``heart.pts`` (openCARP's unit is the micrometre) is:

- ``heart.pts``: the node count, then ``x y z`` a line, in micrometres, converted from the mesh's unit (z = 0 for a
  2D mesh); read back in mm;
- ``heart.elem``: the cell count, then ``Tt n0 n1 n2 n3 region`` a line (``Tr`` triangles in 2D): 0-based nodes,
  positively oriented (meshtool's quality check flags the others), the region the ``Region`` array's (1 without);
- ``heart.lon``: the number of directions a cell (2: fibre and sheet, as openCARP's bidomain reads them; 1: the fibre
  only), then the unit vectors of each cell a line; without fibres, one zero direction a cell, as meshtool writes
  (openCARP then takes the conductivity as isotropic);
- ``heart_NAME.surf`` for each tagged surface: the triangle count, then ``Tr a b c`` (edges ``Ln a b`` in 2D), turned
  as meshtool's ``extract surface`` turns them (normals into the domain), and ``heart_NAME.vtx``: the node count,
  ``intra``, then the surface's nodes, one a line (openCARP's stimulus and boundary condition sets);
- ``heart_tags.json``: the names of the regions and surfaces, ``{"EPI": [tag, dimension], ...}`` as the ``.vtu``'s
  field data, so that the mesh reads back with its tags and a user finds the region numbers of the ``.elem``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..core.errors import InvalidInputError

#: micrometres in each unit a mesh may be in: openCARP's coordinates are micrometres.
MICROMETRES = {"um": 1.0, "mm": 1e3, "cm": 1e4, "m": 1e6}
#: openCARP's element code of a cell with k + 1 nodes, and of a facet with k nodes.
CELL_CODES = {4: "Tt", 3: "Tr"}
FACET_CODES = {3: "Tr", 2: "Ln"}


def companion(path: Path, suffix: str) -> Path:
    """``heart.elem`` for ``heart.pts``; ``heart_EPI.surf`` for suffix ``_EPI.surf``."""
    return path.with_name(path.stem + suffix)


def surface_names(tag_names: dict, dim: int) -> list:
    """The names of the facet tags (dimension dim - 1), in tag order."""
    return sorted((name for name, (_, dimension) in tag_names.items() if dimension == dim - 1),
                  key=lambda name: tag_names[name][0])


def opencarp_files(path, tag_names: dict, dim: int) -> list:
    """The files :func:`write_opencarp` writes for ``path`` (``heart.pts``), ``path`` first; refuses a surface name
    that cannot name a file."""
    check_names(tag_names)
    path = Path(path)
    files = [path] + [companion(path, suffix) for suffix in (".elem", ".lon", "_tags.json")]
    for name in surface_names(tag_names, dim):
        files += [companion(path, f"_{name}.surf"), companion(path, f"_{name}.vtx")]
    return files


def check_names(tag_names: dict) -> None:
    """A surface's name goes into a file name: no folder separator, nothing a shell would need to quote."""
    for name in tag_names:
        if not name or any(not (char.isalnum() or char in "_-+") for char in name):
            raise InvalidInputError(f"tag name {name!r} cannot name an openCARP surface file (heart_NAME.surf): use "
                                    "letters, digits, '_', '-' or '+' (rename it in the mesh's tag_names)")


def write_opencarp(mesh, regions, temporaries: list, files: list) -> None:
    """Write ``mesh`` (points in mm) to the temporary paths of ``files`` (:func:`opencarp_files`)."""
    dim = mesh.points.shape[1]
    points = np.zeros((len(mesh.points), 3))
    points[:, :dim] = mesh.points * MICROMETRES[mesh.unit]
    regions = np.ones(len(mesh.cells), np.int64) if regions is None else np.asarray(regions, np.int64)
    written = iter(temporaries)
    write_table(next(written), len(points), [f"{x:.17g} {y:.17g} {z:.17g}" for x, y, z in points])
    code = CELL_CODES[mesh.cells.shape[1]]
    write_table(next(written), len(mesh.cells),
                [f"{code} {' '.join(map(str, cell))} {region}" for cell, region in zip(mesh.cells, regions)])
    write_lon(next(written), mesh.cell_data, len(mesh.cells), dim)
    Path(next(written)).write_text(json.dumps({name: list(value) for name, value in mesh.tag_names.items()},
                                              indent=1))
    code = FACET_CODES[dim]
    for name in surface_names(mesh.tag_names, dim):
        facets = mesh.facets[mesh.facet_tags == mesh.tag_names[name][0]][:, ::-1]   # into the domain
        write_table(next(written), len(facets), [f"{code} {' '.join(map(str, facet))}" for facet in facets])
        nodes = np.unique(facets)
        write_table(next(written), len(nodes), ["intra", *map(str, nodes)])


def write_lon(path, cell_data: dict, count: int, dim: int) -> None:
    """The cells' fibre and sheet directions (``Fibre``, ``Sheet``; 3D vectors), or zeros."""
    fibre, sheet = cell_data.get("Fibre"), cell_data.get("Sheet")
    if fibre is None or np.shape(fibre) != (count, 3):
        directions, fields = np.zeros((count, 3)), 1
    elif sheet is None or np.shape(sheet) != (count, 3):
        directions, fields = np.asarray(fibre, np.float64), 1
    else:
        directions, fields = np.hstack([fibre, sheet]).astype(np.float64), 2
    write_table(path, fields, [" ".join(f"{value:.9g}" for value in row) for row in directions])


def write_table(path, header, lines) -> None:
    Path(path).write_text(f"{header}\n" + "".join(f"{line}\n" for line in lines))


def read_opencarp(path: Path):
    """(points (n, k) in mm (from micrometres), cells (m, k + 1), cell_data, facets, facet_tags, tag_names) of
    ``heart.pts`` and its companions (``heart_tags.json`` and the surfaces it names, when present)."""
    def rows(file: Path, counted: bool = True) -> list:
        """The rows of ``file`` after its header (the row count, unless not ``counted``)."""
        if not file.is_file():
            raise InvalidInputError(f"cannot read an openCARP mesh from '{path}': '{file.name}' is missing beside it")
        lines = file.read_text().split("\n")
        found = [line.split() for line in lines[1:] if line.strip()]
        return found[:int(lines[0].split()[0])] if counted else found

    try:
        points = np.array(rows(path), dtype=np.float64) / MICROMETRES["mm"]
        elements = rows(companion(path, ".elem"))
        codes = {row[0] for row in elements}
        if len(codes) != 1 or codes - set(CELL_CODES.values()):
            raise InvalidInputError(f"cannot read an openCARP mesh from '{path}': its elements are "
                                    f"{', '.join(sorted(codes))}; bitemesh reads tetrahedra (Tt) or triangles (Tr)")
        table = np.array([row[1:] for row in elements], dtype=np.int64)
    except (ValueError, IndexError) as error:
        raise InvalidInputError(f"cannot read an openCARP mesh from '{path}': {error}") from None
    dim = 3 if codes == {"Tt"} else 2
    cells, cell_data = table[:, :dim + 1], {"Region": table[:, dim + 1].astype(np.int32)}
    points = points[:, :dim]
    lon = companion(path, ".lon")
    if lon.is_file():
        directions = np.array(rows(lon, counted=False), dtype=np.float64).reshape(len(cells), -1)
        if np.abs(directions[:, :3]).sum() > 0:
            cell_data["Fibre"] = directions[:, :3]
            if directions.shape[1] >= 6:
                cell_data["Sheet"] = directions[:, 3:6]
                cell_data["SheetNormal"] = np.cross(directions[:, :3], directions[:, 3:6])
    names_file = companion(path, "_tags.json")
    tag_names = {name: tuple(value) for name, value in json.loads(names_file.read_text()).items()} \
        if names_file.is_file() else {}
    facets, tags = [], []
    for name in surface_names(tag_names, dim):
        found = np.array([row[1:] for row in rows(companion(path, f"_{name}.surf"))], dtype=np.int64)
        facets.append(found.reshape(-1, dim)[:, ::-1])
        tags.append(np.full(len(facets[-1]), tag_names[name][0], np.int32))
    facets = np.concatenate(facets) if facets else None
    return points, cells, cell_data, facets, np.concatenate(tags) if tags else None, tag_names
