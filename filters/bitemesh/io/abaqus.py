"""Abaqus ``.inp`` tags: element sets for the regions, element-based surfaces for the tagged facets.

meshio writes the nodes, the elements (``C3D4``; ``CPS3`` in 2D), the element sets and the node sets; this module
builds those sets and the text meshio has no writer for, appended to its file:

- ``*ELSET, ELSET=<region name>`` for each region (``REGION_<tag>`` when the tag has no name);
- for each facet tag, ``*ELSET, ELSET=_<surface>_S<f>`` (the elements whose face ``S<f>`` is in the surface, one
  set per face identifier, as Abaqus/CAE names its internal sets), ``*SURFACE, TYPE=ELEMENT, NAME=<surface>`` with
  one line ``_<surface>_S<f>, S<f>`` a set, and ``*NSET, NSET=<surface>`` with the surface's nodes; ``<surface>``
  is the facet tag's name (``SURFACE_<tag>`` when it has none);
- one comment line ``** bitemesh tag <name> <tag> <dimension>`` for each tag name (Abaqus has no tag numbers), so
  that the tags read back as they were written.

Face identifiers (Abaqus' element library, as CalculiX has them): C3D4 S1 = nodes 1-2-3, S2 = 1-4-2, S3 = 2-4-3,
S4 = 3-4-1; CPS3 S1 = 1-2, S2 = 2-3, S3 = 3-1.  Each facet is the face of the cell it points out of (the one of
the lower region at an interface); reading gives every facet back oriented out of that cell.
"""
from __future__ import annotations

import re
from itertools import combinations

import numpy as np

from ..core.errors import InvalidInputError
from ..core.mesh.simplicial import facet_of, facets_of, signed_measures
from ..core.mesh.topology import first_rows

#: Abaqus face identifier of the facet opposite each vertex (0-based) of a tetrahedron (k = 3) or a triangle (k = 2).
FACE_OPPOSITE = {3: ("S3", "S4", "S2", "S1"), 2: ("S2", "S3", "S1")}

#: What an Abaqus set or surface name may be without quotes: a letter, then letters, digits and underscores.
NAME_PATTERN = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,79}")

_TAG_COMMENT = re.compile(r"\*\* bitemesh tag (\S+) (\d+) (\d+)\s*$")
_DEFAULT_NAME = re.compile(r"(REGION|SURFACE)_(\d+)")


def abaqus_sets(cells: np.ndarray, regions, facets: np.ndarray, facet_tags: np.ndarray, tag_names: dict):
    """The element sets, node sets and appended text that hold ``regions`` and the tagged facets in a ``.inp``.

    Parameters
    ----------
    cells : (m, k + 1) int64
        The cells (tetrahedra, k = 3, or triangles, k = 2), positively oriented.
    regions : (m,) int32 or None
        The region of each cell.
    facets : (b, k) int64
        Tagged facets, each a face of a cell.
    facet_tags : (b,) int32
        The tag of each facet.
    tag_names : dict
        Name -> (tag, dimension).

    Returns
    -------
    cell_sets : dict
        Name -> [(c,) int cell indices] (meshio's form, one cell block).
    point_sets : dict
        Surface name -> (p,) int node indices.
    text : str
        The tag comments and the ``*SURFACE`` sections, to append to meshio's file.

    Raises
    ------
    InvalidInputError
        A tag name that Abaqus cannot take unquoted, or a facet that is no face of any cell.
    """
    k = cells.shape[1] - 1
    names = {(tag, dimension): name for name, (tag, dimension) in _checked_names(tag_names).items()}
    cell_sets, point_sets = {}, {}
    for tag in ([] if regions is None else np.unique(regions)):
        cell_sets[names.get((int(tag), k), f"REGION_{tag}")] = [np.flatnonzero(regions == tag)]
    lines = [f"** bitemesh tag {name} {tag} {dimension}" for (tag, dimension), name in names.items()]
    cell, vertex = faces_of(cells, facets)
    for tag in np.unique(facet_tags):
        surface = names.get((int(tag), k - 1), f"SURFACE_{tag}")
        lines.append(f"*SURFACE, TYPE=ELEMENT, NAME={surface}")
        for opposite, face in enumerate(FACE_OPPOSITE[k]):
            chosen = cell[(facet_tags == tag) & (vertex == opposite)]
            if chosen.size:
                cell_sets[f"_{surface}_{face}"] = [np.unique(chosen)]
                lines.append(f"_{surface}_{face}, {face}")
        point_sets[surface] = np.unique(facets[facet_tags == tag])
    return cell_sets, point_sets, "".join(line + "\n" for line in lines)


def _checked_names(tag_names: dict) -> dict:
    upper = {}
    for name in tag_names:
        if not NAME_PATTERN.fullmatch(name):
            suggestion = re.sub(r"[^A-Za-z0-9_]", "_", name)
            suggestion = (suggestion if suggestion[:1].isalpha() else "T_" + suggestion)[:80]
            raise InvalidInputError(
                f"mesh.tag_names: {name!r} cannot name an Abaqus set or surface (a letter, then up to 79 letters, "
                f"digits or underscores); rename it, e.g. {suggestion!r}")
        other = upper.setdefault(name.upper(), name)
        if other != name:
            raise InvalidInputError(f"mesh.tag_names: {other!r} and {name!r} are one name to Abaqus, which ignores "
                                    "case; rename one of them")
    return tag_names


def faces_of(cells: np.ndarray, facets: np.ndarray):
    """(b,) cell and (b,) opposite vertex of each facet: the cell it points out of, else any cell it bounds."""
    k = cells.shape[1] - 1
    faces = facets_of(cells).reshape(-1, k)
    found = first_rows(_oriented_key(faces), _oriented_key(facets))
    lost = np.flatnonzero(found < 0)
    if lost.size:
        found[lost] = first_rows(np.sort(faces, axis=1), np.sort(facets[lost], axis=1))
    if (found < 0).any():
        first = int(np.argmax(found < 0))
        raise InvalidInputError(
            f"mesh.facets[{first}] = {facets[first].tolist()} is not a face of any cell; an Abaqus surface is made "
            "of element faces: give only boundary and interface facets of the cells")
    return np.divmod(found, k + 1)


def _oriented_key(rows: np.ndarray) -> np.ndarray:
    """The sorted nodes of each row and the parity of the permutation that sorts them: equal for the same facet
    with the same orientation."""
    parity = sum((rows[:, i] > rows[:, j]).astype(np.int64) for i, j in combinations(range(rows.shape[1]), 2)) % 2
    return np.column_stack([np.sort(rows, axis=1), parity])


def read_abaqus_tags(path, data, chosen, points: np.ndarray, cells: np.ndarray):
    """The regions, tagged facets and names of a ``.inp`` file read by meshio (as :func:`abaqus_sets` writes them).

    Element sets named in the file's tag comments, or ``REGION_<tag>``, give the regions; ``*SURFACE,
    TYPE=ELEMENT`` sections whose lines name element sets give the facets, tagged by the comments, by
    ``SURFACE_<tag>``, or else numbered after the highest tag (and named after the surface); surface lines that
    name an element by its number, not a set, are skipped.

    Parameters
    ----------
    path : Path
        The file (read again for the comments and surfaces).
    data : meshio.Mesh
        What meshio read from it.
    chosen : list of int
        The blocks of ``data.cells`` that make ``cells``, in order.
    points : (n, k) float64
        The nodes.
    cells : (m, k + 1) int64
        The cells of the chosen blocks, in the file's vertex order.

    Returns
    -------
    regions : (m,) int32 or None
        None when no element set is a region.
    facets : (b, k) int64
        Each oriented out of its cell.
    facet_tags : (b,) int32
    tag_names : dict
        Name -> (tag, dimension).
    """
    k = cells.shape[1] - 1
    tag_names, surfaces = _parse(path)
    offsets = np.cumsum([0] + [len(data.cells[i].data) for i in chosen])

    def members(name):
        blocks = data.cell_sets.get(name)
        if blocks is None:
            return None
        return np.concatenate([np.asarray(blocks[i], np.int64) + offset for i, offset in zip(chosen, offsets)])

    def tag_of(name, dimension):
        if name in tag_names and tag_names[name][1] == dimension:
            return tag_names[name][0]
        default = _DEFAULT_NAME.fullmatch(name)
        prefix = "REGION" if dimension == k else "SURFACE"
        return int(default.group(2)) if default and default.group(1) == prefix else None

    regions = None
    for name in data.cell_sets:
        tag = tag_of(name, k)
        if tag is not None:
            regions = np.zeros(len(cells), np.int32) if regions is None else regions
            regions[members(name)] = tag
    found, opposite, tags = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)], [np.zeros(0, np.int32)]
    highest = max([tag for tag, dimension in tag_names.values() if dimension == k - 1], default=0)
    for surface, lines in surfaces.items():
        tag = tag_of(surface, k - 1)
        if tag is None:
            highest = tag = highest + 1
            tag_names[surface] = (tag, k - 1)
        for elset, face in lines:
            cell = members(elset)
            if cell is not None and face in FACE_OPPOSITE[k]:
                found.append(cell)
                opposite.append(np.full(len(cell), FACE_OPPOSITE[k].index(face)))
                tags.append(np.full(len(cell), tag, np.int32))
    cell, opposite = np.concatenate(found), np.concatenate(opposite)
    facets = facet_of(cells, cell, opposite)
    inverted = signed_measures(points, cells[cell]) < 0
    facets[inverted] = facets[inverted, ::-1]
    return regions, facets, np.concatenate(tags), tag_names


def _parse(path):
    """The tag comments (name -> (tag, dimension)) and element surfaces (name -> [(element set, face id)])."""
    tag_names, surfaces, surface = {}, {}, None
    with open(path, encoding="utf-8", errors="replace") as stream:
        for line in stream:
            comment = _TAG_COMMENT.match(line)
            if comment:
                tag_names[comment.group(1)] = (int(comment.group(2)), int(comment.group(3)))
            elif line.startswith("**"):
                continue
            elif line.startswith("*"):
                options = dict(_option(part) for part in line.strip().split(",")[1:])
                keyword = line.split(",")[0].strip().upper()
                surface = options.get("NAME") if keyword == "*SURFACE" and \
                    options.get("TYPE", "ELEMENT").upper() == "ELEMENT" else None
                if surface is not None:
                    surfaces.setdefault(surface, [])
            elif surface is not None and line.strip():
                elset, _, face = (part.strip() for part in line.partition(","))
                surfaces[surface].append((elset, face.upper()))
    return tag_names, surfaces


def _option(part: str):
    key, _, value = part.partition("=")
    return key.strip().upper(), value.strip()
