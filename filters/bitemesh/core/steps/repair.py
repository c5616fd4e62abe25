"""From all Delaunay cells to a valid domain: spurious cells out, enclosed voids filled, stray parts dropped,
and the boundary made a closed manifold.

A plain implementation of the paper leaves flat cells, pinched edges and vertices, and loose components; the
product hands on only meshes that pass :func:`bitemesh.core.mesh.topology.non_manifold_faces` with nothing found.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from ..errors import MeshingError
from ..grid.sampled import ImplicitGrid, SampledGrid
from .handles import MAX_DEPTH, THICK_DEPTH, break_handles, handle_count
from ..mesh.betti import THIN_VOID
from ..mesh.simplicial import Mesh, facet_measures, regular_edge, signed_measures
from ..parameters import SpuriousParameters
from ..mesh.validity import check_valid_domain
from ..mesh.quality import radius_ratio
from ..progress import ProgressCallback, report, sub_progress
from .spurious import outside_cells
from ..mesh.topology import CellComplex, euler_change, vertex_incidence

logger = logging.getLogger("bitemesh")

#: rounds of repair before giving up (after the fill rounds each round removes cells, so the repair ends; a 4-D
#: space-time heart takes about 75), and the first rounds, for each size of pinched face, in which a pinch may be
#: mended by filling (in 4-D the edges and vertices are pinched only once the ridges are mended: filling them
#: keeps 99 % of the domain's volume where removing them alone kept 90 %).
MAX_REPAIR_ROUNDS = 200
FILL_ROUNDS = 5
#: rounds of handle removal, each followed by the repair.
HANDLE_ROUNDS = 2
#: cells with a radius ratio below this are flat.
FLAT_QUALITY = 0.02
#: cells with a radius ratio below this have no volume to speak of (a finite-element solver cannot use them).
DEGENERATE = 1e-6


@dataclass(frozen=True)
class DelaunayCells:
    """All the Delaunay cells, with what the repair asks of them round after round, computed once: their facet
    and ridge tables (``complex``), volume, and which are flat or degenerate (radius ratio below
    :data:`FLAT_QUALITY`, :data:`DEGENERATE`), and f at their centroids (``centroid_values``, None without a
    grid: in more than 3-D f is the function itself, which the voids' test asked of every dropped cell every round:
    545 s of a space-time heart's 644); each (m,)."""

    points: np.ndarray
    cells: np.ndarray
    complex: CellComplex
    volume: np.ndarray
    flat: np.ndarray
    degenerate: np.ndarray
    centroid_values: np.ndarray | None = None

    @classmethod
    def of(cls, points: np.ndarray, cells: np.ndarray, grid: SampledGrid | None = None) -> DelaunayCells:
        quality = radius_ratio(points, cells)
        values = None if grid is None else grid.evaluate(points[cells].mean(axis=1))
        return cls(points, cells, CellComplex(cells, len(points)), signed_measures(points, cells),
                   quality < FLAT_QUALITY, quality < DEGENERATE, values)


def enclosed_inside_voids(delaunay: DelaunayCells, keep: np.ndarray, every: bool = False) -> np.ndarray:
    """(m,) bool, the dropped cells that form voids closed off from the hull and lie inside (mean f > 0 there, from
    ``delaunay.centroid_values``), or are narrower than :data:`THIN_VOID` cells (below the mesh's resolution); with
    ``every``, every void closed off from the hull (a domain known to have none: a myocardium).

    A cavity that f says is outside (a ventricle, the hole of a shell) stays open unless ``every``.
    """
    dropped = np.flatnonzero(~keep)
    if len(dropped) == 0:
        return np.zeros(len(keep), bool)
    complex_ = delaunay.complex
    on_hull = (complex_.hull_counts[complex_.facet_ids[dropped]] == 1).any(axis=1)
    labels = complex_.components(~keep)
    touches_hull = np.bincount(labels, weights=on_hull) > 0
    volume = delaunay.volume[dropped]
    centroid_value = delaunay.centroid_values[dropped]
    void_volume = np.bincount(labels, weights=volume)
    mean_value = np.bincount(labels, weights=volume * centroid_value) / void_volume
    facets = complex_.facet_ids[dropped]
    walls = complex_.facet_counts(~keep)[facets] == 1   # (d, k + 1): the facets they share with kept cells
    wall_cells, _ = np.nonzero(walls)
    area = facet_measures(delaunay.points[complex_.facets[facets[walls]]])
    k = delaunay.cells.shape[1] - 1
    width = k * void_volume / np.maximum(np.bincount(labels[wall_cells], weights=area, minlength=len(void_volume)),
                                         1e-300)
    thin = width < THIN_VOID * regular_edge(float(np.median(delaunay.volume[keep])), k) if keep.any() else False
    fill = np.zeros(len(keep), bool)
    fill[dropped] = (~touches_hull & ((mean_value > 0) | thin | every))[labels]
    return fill


def drop_small_components(delaunay: DelaunayCells, keep: np.ndarray, fraction: float) -> np.ndarray:
    """``keep`` without the facet-connected parts whose volume is below ``fraction`` x the largest part's."""
    kept = np.flatnonzero(keep)
    labels = delaunay.complex.components(keep)
    volume = np.bincount(labels, weights=delaunay.volume[kept])
    result = keep.copy()
    result[kept] = (volume >= fraction * volume.max())[labels]
    return result


def peel_flat_boundary_cells(delaunay: DelaunayCells, keep: np.ndarray) -> np.ndarray:
    """``keep`` without the nearly flat cells that lie on the boundary, layer by layer.

    Nodes projected onto a planar part of the surface are coplanar, and qhull joins four of them into a flat cell
    that lies on the surface (two or more facets on the boundary): it carries no volume, and removing it leaves
    the boundary where it was.  A flat cell with a single boundary facet is a slit into the domain: removing it
    would pinch the boundary, and the pinch repair would then cut a notch; such a cell goes only when it has no
    volume at all (``DEGENERATE``).  Each layer updates the facet counts by the cells peeled.
    """
    facet_ids = delaunay.complex.facet_ids
    counts = delaunay.complex.facet_counts(keep)
    candidates = np.flatnonzero(keep & delaunay.flat)
    result = keep.copy()
    for _ in range(MAX_REPAIR_ROUNDS):
        candidates = candidates[result[candidates]]
        on_boundary = (counts[facet_ids[candidates]] == 1).sum(axis=1)
        peel = candidates[(on_boundary >= 2) | ((on_boundary == 1) & delaunay.degenerate[candidates])]
        if len(peel) == 0:
            break
        result[peel] = False
        counts -= np.bincount(facet_ids[peel].ravel(), minlength=len(counts))
    return result


def fans(n_points: int, cells: np.ndarray, facet_size: int):
    """(count, labels) of the groups of the (c, k + 1) ``cells`` joined through shared facets (``facet_size``
    vertices in common)."""
    local = vertex_incidence(n_points, cells)
    shared = (sparse.csr_matrix(local.T) @ local).toarray()
    return csgraph.connected_components(shared >= facet_size, directed=False)


def unpinch(delaunay: DelaunayCells, keep: np.ndarray, faces: list, *, fill: bool) -> np.ndarray:
    """``keep`` mended around each face where the domain is not a manifold.

    The kept cells around a face fall into fans (two share a facet, of k vertices, that then holds the face),
    and so do the missing ones (the sides of the gap).  Either every fan but the one of largest volume goes (with
    a single fan, a vertex whose link is an annulus, all go), or, with ``fill``, the missing Delaunay cells around
    the face come in, which makes it a manifold point, or, around a vertex whose link is an annulus (a vertex on
    both sides of a wall one cell thick), those of one side: whichever changes less volume, unless it opens a
    tunnel (lowers the Euler characteristic: removing the annulus punches a hole through the wall, a fill can
    put a pillar across a thin cavity) and another choice does not.  Flat cells never come in (the peel would
    take them out again).
    """
    points, cells, volume, flat = delaunay.points, delaunay.cells, delaunay.volume, delaunay.flat
    incidence = delaunay.complex.incidence
    result = keep.copy()
    facet = cells.shape[1] - 1
    for face in (f for group in faces for f in group):
        around = delaunay.complex.cells_around(face)
        members, gap = around[keep[around]], around[~keep[around]]
        n_fans, labels = fans(len(points), cells[members], facet)
        largest = np.argmax(np.bincount(labels, weights=volume[members])) if n_fans > 1 else -1
        choices = [(members[labels != largest], False)]
        if fill and not flat[gap].any():
            choices.append((gap, True))
        if fill and n_fans == 1 and len(gap):
            n_sides, sides = fans(len(points), cells[gap], facet)
            choices += [(gap[sides == side], True) for side in range(n_sides)
                        if n_sides > 1 and not flat[gap[sides == side]].any()]
        if len(choices) > 1:   # a removal alone needs no comparing (most faces after the fill rounds)
            cost = [(euler_change(incidence, cells, result, *choice) < 0, volume[choice[0]].sum())
                    for choice in choices]
            choices = [choices[min(range(len(choices)), key=cost.__getitem__)]]
        changed, value = choices[0]
        result[changed] = value
    return result


def repaired(delaunay: DelaunayCells, keep: np.ndarray, parameters: SpuriousParameters,
             progress: ProgressCallback = None) -> np.ndarray:
    """``keep`` made a valid domain: flat boundary cells peeled, small parts dropped, pinches mended, round after
    round until the boundary is a manifold; enclosed voids filled."""
    filled = {}   # rounds that could fill, per size of pinched face
    for round_ in range(MAX_REPAIR_ROUNDS):
        report(progress, round_ / MAX_REPAIR_ROUNDS, "repairing the boundary")
        if not keep.any():
            raise MeshingError("no cell is inside the domain; check the normals' orientation, or lower radius")
        keep = peel_flat_boundary_cells(delaunay, keep)
        keep = drop_small_components(delaunay, keep, parameters.min_component)
        pinched = delaunay.complex.non_manifold_faces(keep)
        if not pinched:
            voids = enclosed_inside_voids(delaunay, keep)
            if not voids.any():
                break
            # filled, and checked again: two voids meeting at a vertex (the 25-frame space-time heart's), one of
            # them filled, pinch the domain there
            keep = keep | voids
            continue
        # each size of face may be mended by filling in its first rounds, then only by removing: the rounds that
        # only remove cannot cycle.  Beyond 3-D the largest pinched faces first (ridges, then edges, then vertices),
        # whose mending changes the links below: all at once, the fills of a 6-frame space-time heart's edges and
        # vertices took its pinched ridges from 316 to 2,910, and the removal rounds then ate the domain.  In 3-D
        # ridges and vertices together, as every real heart is tested (the ridges first left a heart of the
        # long-axis-shifted class with 2 handles that the handle removal did not break)
        mended = pinched if delaunay.cells.shape[1] <= 4 else pinched[:1]
        for size in {faces.shape[1] for faces in mended}:
            filled[size] = filled.get(size, 0) + 1
        fill = filled[mended[0].shape[1]] <= FILL_ROUNDS
        keep = unpinch(delaunay, keep, mended, fill=fill)
        if fill:   # a fill next to a removal can close off a void
            keep |= enclosed_inside_voids(delaunay, keep)
    else:
        raise MeshingError(f"the boundary is still not a manifold after {MAX_REPAIR_ROUNDS} rounds of repair; "
                           "try a smaller radius or a finer grid_spacing")
    return keep


def without_handles(grid: ImplicitGrid, delaunay: DelaunayCells, keep: np.ndarray, parameters: SpuriousParameters,
                    progress: ProgressCallback = None, surface_of=None) -> np.ndarray:
    """``keep`` with its handles thinner than about two cells cut or filled, then those up to about four cells
    thick (a domain with no handle by nature), repaired (a repair can reopen a fill: then once more), and every
    enclosed void filled (a domain without handles has none: a spurious bubble of a fitted surface inside a wall);
    what was done is logged.  ``surface_of``: see :func:`~bitemesh.core.steps.handles.break_handles`."""
    points, cells = delaunay.points, delaunay.cells
    voids = enclosed_inside_voids(delaunay, keep, every=True)
    if voids.any():
        logger.info("%d enclosed void(s) filled, %.3g in all (a bubble of a fitted surface inside the wall; "
                    "handles = 'remove')", int(delaunay.complex.components(voids).max() + 1),
                    float(delaunay.volume[voids].sum()))
        keep = repaired(delaunay, keep | voids, parameters)
    for depth, words in ((MAX_DEPTH, "thinner than two cells"), (THICK_DEPTH, "two to four cells thick")):
        before, handles = keep, handle_count(cells[keep])
        for round_ in range(HANDLE_ROUNDS):
            report(progress, round_ / HANDLE_ROUNDS, "removing handles")
            keep, removed = break_handles(grid, points, delaunay.complex, keep, depth, surface_of)
            if not removed:
                break
            keep = repaired(delaunay, keep, parameters)
        left = handle_count(cells[keep])
        if left < handles:
            logger.info("%d handle(s) %s removed: %d cells cut, %d filled (handles = 'remove')", handles - left,
                        words, int((before & ~keep).sum()), int((keep & ~before).sum()))
    if left:
        logger.info("%d handle(s) kept: thicker than four cells, or no single cut or fill removes them", left)
    return keep


def carve_domain(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray,
                 parameters: SpuriousParameters = SpuriousParameters(),
                 progress: ProgressCallback = None, surface_of=None) -> Mesh:
    """Keep the Delaunay cells of the domain and make it a valid one; with ``parameters.handles`` "remove" (3D),
    without handles too (:func:`bitemesh.core.steps.handles.break_handles`).

    Parameters
    ----------
    grid : the implicit function f on the grid I
    points : (n, k) float64, the nodes
    cells : (m, k + 1) int64, all Delaunay cells of the nodes, positively oriented
    surface_of : which of the data's surfaces gives f where (see :func:`~bitemesh.core.steps.handles.break_handles`),
        or None

    Returns
    -------
    The valid domain mesh; unused nodes are dropped.
    """
    keep = _domain_cells(grid, points, cells, parameters, progress, surface_of)
    report(progress, 1.0, "repairing the boundary")
    mesh = compact(points, cells[keep])   # the tables of all Delaunay cells (about 10x the cells' bytes) are gone
    problems = check_valid_domain(mesh)
    if problems:
        raise MeshingError(f"the mesh is not a valid domain: {problems[0]}; try a smaller radius or a finer "
                           "grid_spacing")
    return mesh


def _domain_cells(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, parameters: SpuriousParameters,
                  progress: ProgressCallback, surface_of) -> np.ndarray:
    """(m,) bool, the Delaunay cells of the valid domain: inside f > 0 (and the voids they enclose), repaired,
    without handles when asked."""
    delaunay = DelaunayCells.of(points, cells, grid)
    keep = ~outside_cells(grid, points, cells, parameters.threshold, centroid_values=delaunay.centroid_values)
    keep |= enclosed_inside_voids(delaunay, keep)
    keep = repaired(delaunay, keep, parameters, sub_progress(progress, 0.0, 0.8))
    if parameters.handles == "remove" and cells.shape[1] == 4:
        keep = without_handles(grid, delaunay, keep, parameters, sub_progress(progress, 0.8, 1.0), surface_of)
    return keep


def compact(points: np.ndarray, cells: np.ndarray) -> Mesh:
    """The mesh of ``cells`` with only the points they use, renumbered in their original order."""
    used = np.unique(cells)
    renumber = np.full(len(points), -1, dtype=np.int64)
    renumber[used] = np.arange(used.size)
    return Mesh(points[used], renumber[cells])
