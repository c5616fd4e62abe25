"""The shape of a domain as topology counts it: parts, holes through it (handles), and voids inside it.

For a mesh (2D triangles, 3D tetrahedra; beyond, simplices) they come from its cells and its boundary; for {f > 0} on a
grid, from the union of the closed voxels (pixels) whose nodes are inside: its Euler characteristic counted on the
cubical complex, its parts labelled with 26- (8-) connectivity and its enclosed background with 6- (4-).  A mesh of
f holds no handle or void that f's region on the grid I lacks: the grid resolves f four times finer than R, so a
hole that the mesh has and the grid has not is a tear of a part thinner than R (:func:`torn`).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..errors import BitemeshWarning, MeshingError, point_text
from .simplicial import Mesh
from .topology import boundary_facets, connected_components, euler_characteristic


@dataclass(frozen=True)
class Topology:
    """Betti numbers of a domain: ``parts`` (b0), ``handles`` (b1: tunnels through it, in 2D its holes; beyond 3D
    see :func:`_from_euler`) and ``voids`` (b_(k-1): closed cavities inside it; 0 in 2D)."""

    parts: int
    handles: int
    voids: int

    def describe(self) -> str:
        return f"{self.parts} part(s), {self.handles} handle(s), {self.voids} void(s)"


def mesh_topology(mesh: Mesh) -> Topology:
    """The :class:`Topology` of a valid mesh: parts from its cells, and from its boundary (closed surfaces in 3D,
    loops in 2D) the voids (surfaces beyond one per part) and the handles (the surfaces' genus; in 2D the loops
    beyond one per part, the holes)."""
    cells = np.asarray(mesh.cells)
    if not len(cells):
        return Topology(0, 0, 0)
    parts = int(connected_components(cells).max() + 1)
    facets = boundary_facets(cells)
    surfaces = int(connected_components(facets).max() + 1) if len(facets) else 0
    if cells.shape[1] == 3:
        return Topology(parts, surfaces - parts, 0)
    if cells.shape[1] == 4:
        genus = (2 * surfaces - euler_characteristic(facets)) // 2
        return Topology(parts, int(genus), surfaces - parts)
    return _from_euler(parts, surfaces - parts, euler_characteristic(cells), cells.shape[1] - 1)


def enclosed_voids(mesh: Mesh) -> list:
    """(volume, centre (3,)) of each void of a valid tetrahedral mesh, the largest first: the boundary surfaces
    whose facets, facing out of the cells, enclose a negative volume (the centre: their nodes' mean)."""
    facets = boundary_facets(np.asarray(mesh.cells))
    if mesh.cells.shape[1] != 4 or not len(facets):
        return []
    surface = connected_components(facets)
    corners = mesh.points[facets]
    volume = np.bincount(surface, weights=np.einsum("fi,fi->f", corners[:, 0],
                                                    np.cross(corners[:, 1], corners[:, 2])) / 6.0)
    voids = [(-float(volume[label]), mesh.points[np.unique(facets[surface == label])].mean(axis=0))
             for label in np.flatnonzero(volume < 0)]
    return sorted(voids, key=lambda void: -void[0])


def _from_euler(parts: int, voids: int, euler: int, k: int) -> Topology:
    """The :class:`Topology` of a k-D domain (k >= 3) from its parts (b0), voids (b_(k-1)) and Euler characteristic:
    ``handles`` is b1 - b2 + b3 - ... over the dimensions between (b1 in 3D; in 4-D b1 - b2, which a tunnel raises
    and a closed surface of cavity lowers: the count compared between a mesh and f's grid)."""
    return Topology(parts, int(parts + (-1) ** (k - 1) * voids - euler), voids)


def grid_topology(inside: np.ndarray) -> Topology:
    """The :class:`Topology` of the union of the closed cells (voxels, pixels) of a 2D or 3D grid whose ``inside``
    flags (one per cell) are set."""
    inside = np.asarray(inside, dtype=bool)
    parts = grid_parts(inside)[1]
    enclosed = ndimage.label(np.pad(~inside, 1, constant_values=True))[1] - 1   # the background all round is one
    if inside.ndim == 2:
        return Topology(parts, enclosed, 0)
    return _from_euler(parts, enclosed, cubical_euler(inside), inside.ndim)


def grid_parts(inside: np.ndarray):
    """The parts of the union of the closed cells flagged in ``inside`` (cells meeting at a corner are one part):
    (an array like ``inside`` of part numbers from 1, 0 outside; how many parts)."""
    return ndimage.label(inside, structure=np.ones((3,) * inside.ndim))


def closest_approach(labels: np.ndarray, first: int, second: int) -> tuple:
    """Where the parts numbered ``first`` and ``second`` of ``labels`` (:func:`grid_parts`) come nearest: (the point
    midway across, in node indices (k,): the mean of the midpoints of the node pairs within half a spacing of the
    nearest, so that a flat contact is found at its centre; the distance between the nearest nodes, grid units)."""
    distance, nearest = ndimage.distance_transform_edt(labels != first, return_indices=True)
    gap = float(distance[labels == second].min())
    close = (labels == second) & (distance <= gap + 0.5)
    midpoints = (np.argwhere(close) + nearest[(slice(None),) + np.nonzero(close)].T) / 2.0
    return midpoints.mean(axis=0), gap


def touch(region: np.ndarray):
    """Where the two largest parts of ``region`` (flags on the grid I) come nearest (see :func:`closest_approach`),
    or None when it has one part."""
    labels, count = grid_parts(region)
    if count < 2:
        return None
    largest = np.argsort(np.bincount(labels.ravel())[1:])[::-1][:2] + 1
    return closest_approach(labels, *largest)[0]


def cubical_euler(inside: np.ndarray) -> int:
    """The Euler characteristic of the union of the closed unit cells flagged in ``inside`` (k-D): the alternating
    sum over the cells of every dimension (vertices, edges, squares, cubes) of how many touch a flagged one."""
    padded = np.pad(np.asarray(inside, dtype=bool), 1)
    total = 0
    for size in range(padded.ndim + 1):
        for along in combinations(range(padded.ndim), size):   # the axes a cell of this dimension spans
            touched = padded
            for axis in set(range(padded.ndim)) - set(along):   # at the lattice planes between cells elsewhere
                touched = _either(touched, axis)
            total += (-1) ** size * int(np.count_nonzero(touched))
    return total


def _either(flags: np.ndarray, axis: int) -> np.ndarray:
    """(..., n - 1, ...) the planes between neighbouring cells along ``axis``: flagged where either cell is."""
    first = [slice(None)] * flags.ndim
    second = [slice(None)] * flags.ndim
    first[axis], second[axis] = slice(None, -1), slice(1, None)
    return flags[tuple(first)] | flags[tuple(second)]


def torn(mesh: Topology, grid: Topology, handles: bool = True) -> str:
    """What the mesh has that f's region has not (more parts, handles or voids), as words; "" when nothing.
    ``handles`` False leaves the handles out: beyond 3-D they count b1 - b2, which a tunnel raises and so does a
    small cavity of f (a 2-cycle, a void of some frames of a space-time shape) that the mesh at R does not keep."""
    extra = [f"{count} {what}" for count, what in ((mesh.parts - grid.parts, "part(s) more"),
                                                  (mesh.handles - grid.handles if handles else 0,
                                                   "hole(s) or tunnel(s)"),
                                                  (mesh.voids - grid.voids, "void(s)")) if count > 0]
    return ", ".join(extra)


def joined_parts(mesh: Mesh, grid, inside: np.ndarray) -> tuple:
    """Parts of the region ``inside`` (flags on the nodes of ``grid``), each of a ball of R at least (4^k nodes),
    that share a part of the mesh with another: parts of f that the cells join (across a gap narrower than R),
    which the count of parts alone misses (the mesh joins two, f has two: one part fewer, as a part dropped on
    purpose).  (how many, the narrowest gap between two of them, grid units: spacing 1, the point midway across it in
    node indices (k,)); (0, 0.0, None) when none."""
    labels, count = grid_parts(inside)
    if count < 2 or not len(mesh.cells):
        return 0, 0.0, None
    big = np.flatnonzero(np.bincount(labels.ravel(), minlength=count + 1) >= 4 ** inside.ndim)
    covered = labels[grid.nearest_nodes(mesh.points[mesh.cells].mean(axis=1))]
    component = connected_components(np.asarray(mesh.cells))
    pairs = np.unique(np.column_stack([component, covered])[np.isin(covered, big[big > 0])], axis=0)
    joined = [pairs[pairs[:, 0] == part, 1] for part in np.unique(pairs[:, 0])]
    joined = [parts for parts in joined if len(parts) > 1]
    if not joined:
        return 0, 0.0, None
    where, gap = min((closest_approach(labels, parts[0], other) for parts in joined for other in parts[1:]),
                     key=lambda approach: approach[1])
    return sum(map(len, joined)), max(gap - 1.0, 0.0), where   # node to node, less a spacing: between the surfaces


def check_topology(mesh: Mesh, inside: np.ndarray, radius: float, allow: bool, around=None,
                   one_fit: bool = False, grid=None, frame=None) -> str:
    """Refuse (:class:`MeshingError`; a :class:`BitemeshWarning` when ``allow``) a mesh with parts, handles or voids
    that the region ``inside`` (f > 0 on the grid I) lacks, or handles or voids that f > 0 has at its zero level
    alone: ``around`` () -> (f > -d, f > +d) on the grid I (SampledGrid.inside_offsets), asked only when the mesh
    (or, with ``one_fit``, the grid) has a handle or a void (d, a grid spacing: a tunnel or a cavity of the shape is
    there at one level at least, one that appears at f = 0 alone is a fold of f where surfaces cross or normals
    disagree).  When f is ``one_fit`` of every sample (scattered points), a fold of f > 0 on the grid at the mesh's
    resolution (:func:`at_mesh_resolution`) is refused too, whether the mesh shows it or not (the mesh of a folded
    f may miss part of the shape with no handle of its own); a function built otherwise (labelled contours, a
    label map) may have small handles at its zero level that no mesh at R has.  With ``grid`` (the nodes of
    ``inside``), parts of f that a part of the mesh joins are refused too (:func:`joined_parts`), naming the gap
    and where it is, and so is where objects touch; with ``one_fit``, parts of f a spacing inside that a part of the
    mesh joins and f > 0 joins at its zero level alone (objects in contact, each sampled whole); ``frame``: the
    grid's local frame (its ``scale`` and ``to_user``), None for user coordinates.  What the mesh or f has more
    ("" when nothing); ``radius``: R in user units, for the message."""
    scale = 1.0 if frame is None else frame.scale

    def place(index) -> str:   # " around (x, y, z)" of a point in node indices
        if grid is None or index is None:
            return ""
        point = (grid.origin + index * grid.spacing)[None]
        point = point if frame is None else frame.to_user(point)
        return f" around {point_text(point[0])}"
    mine, data = mesh_topology(mesh), grid_topology(inside)
    joined, gap, where = joined_parts(mesh, grid, inside) if grid is not None else (0, 0.0, None)
    gap *= float(np.min(grid.spacing)) * scale if grid is not None else 0.0
    tear = torn(mine, data, handles=inside.ndim <= 3)
    # a fold of f (scattered points) is asked first: it explains a tear of the mesh too (overlapping objects).  Not
    # beyond 3-D, where "handles" is b1 - b2 (a void of a 3-D frame that lasts a while is a 2-cycle of space-time):
    # that count cannot tell a fold at the zero level from cavities that come and go (4 frames of a space-time heart:
    # -2 at f = 0 in the mesh and on the grid alike, -6 a grid spacing inside, -52 outside)
    across = radius / (float(np.min(grid.spacing)) * scale) if grid is not None else DEFAULT_SPACINGS_PER_R
    fold = _fold(mine, data, inside, around, one_fit, across, lambda region: place(touch(region))) \
        if not joined and (one_fit or not tear) and around is not None and inside.ndim <= 3 else None
    # parts of f > 0 a spacing inside its zero level that meet at the zero level alone: objects that touch, each
    # sampled whole (a sharp-edge fit joins them with no fold of f), or a neck that no mesh at R follows
    touched, _, contact = joined_parts(mesh, grid, around()[1]) \
        if one_fit and not joined and fold is None and grid is not None and around is not None else (0, 0.0, None)
    extra = ", ".join(word for word in ((f"{joined} parts of f joined" if joined else ""), tear) if word)
    if joined:
        text = (f"the mesh joins {joined} parts of the fitted surface that come within about {gap:.3g} of each "
                f"other{place(where)}, less than R = {radius:.4g} (the mesh: {mine.describe()}; f > 0 on the grid: "
                f"{data.describe()}): objects that touch, or a gap narrower than R; give radius <= {gap:.3g} "
                "(or more cells) to keep them apart, or mesh each object apart")
    elif fold is not None:
        extra, text = fold
    elif touched:
        extra = f"{touched} parts of f joined at its zero level"
        text = (f"the mesh joins {touched} parts of the fitted surface that meet at f's zero level alone, apart a "
                f"grid spacing inside it (the mesh: {mine.describe()}; f > 0 on the grid: {data.describe()}): "
                f"sampled surfaces that cross or touch{place(contact)} (objects in contact, each sampled whole) or a "
                "neck narrower than R / 2; give the samples of each object apart, or lower radius (or raise cells) "
                "until R is below twice the neck's width")
    elif extra:
        cause = (f"cells join parts of f that come closer than R = {radius:.4g} (objects that touch)"
                 if mine.parts < data.parts else f"parts thinner than R = {radius:.4g} tear between its nodes")
        text = (f"the mesh has {extra} that the fitted surface does not have (the mesh: {mine.describe()}; f > 0 on "
                f"the grid: {data.describe()}): {cause}; lower radius (or raise cells) until R is below the "
                "thinnest part and the narrowest gap")
    if extra:
        text += ", or set allow_unfaithful (--allow-unfaithful) to keep the mesh anyway"
        if not allow:
            raise MeshingError(text)
        warnings.warn(text, BitemeshWarning, stacklevel=2)
    return extra


def _fold(mine: Topology, data: Topology, inside: np.ndarray, around, one_fit: bool, cells_across: float,
          place):
    """(what, the message) when the mesh (or, ``one_fit``, f > 0 on the grid at the mesh's resolution) has handles
    or voids that f > 0 has at its zero level alone, not a grid spacing inside or outside it (``around``); else
    None.  The levels are asked only when there is a handle or a void to judge.  ``cells_across``: R in grid
    spacings (:func:`at_mesh_resolution`).  ``place``: a region of the grid ->
    " around (x, y, z)" where its two largest parts come nearest ("" for one part): where objects touch, from the
    level with the most parts."""
    if not (mine.handles or mine.voids or one_fit and (data.handles or data.voids)):
        return None
    resolved = grid_topology(at_mesh_resolution(inside, cells_across)) if one_fit else None
    regions = around()
    levels = [grid_topology(region) for region in regions]
    steady = Topology(0, max(level.handles for level in levels), max(level.voids for level in levels))
    shapes = [("the mesh", mine)] + ([("f > 0 on the grid at the mesh's resolution", resolved)] if one_fit else [])
    folded = [(what, torn(Topology(0, shape.handles, shape.voids), steady)) for what, shape in shapes]
    what, extra = next(((what, extra) for what, extra in folded if extra), ("", ""))
    if not extra:
        return None
    touching = place(max(zip([data.parts] + [level.parts for level in levels], [inside, *regions]),
                         key=lambda pair: pair[0])[1])
    return extra, (f"{what} has {extra} that appear at f's zero level alone, not a grid spacing inside or outside "
                   f"it (the mesh: {mine.describe()}; f > 0 on the grid: {data.describe()}; f a spacing inside: "
                   f"{levels[1].describe()}, outside: {levels[0].describe()}): f folds where sampled surfaces cross "
                   f"or touch{touching} (objects that overlap or touch, each sampled whole) or normals disagree, and "
                   "the mesh follows the fold; give the samples of the outer surface only, or of each object apart")


#: an enclosed void less than about a cell across is below a mesh's resolution: its width k x volume / wall area
#: (a ball's radius, k / 2 x a flat pocket's thickness) below this many cells' edges (about R).  Filled by the repair
#: (:func:`bitemesh.core.steps.repair.enclosed_inside_voids`) and by :func:`at_mesh_resolution`: a bubble of about
#: ten cells, or a pocket sealed off where two fitted walls meet at a small angle (the two-cavity heart of 136,000
#: cells, where its RV cavity meets the septum: 19 and 34 cells 0.47 and 0.52 edges wide, f < 0 there from the fit's
#: rounded crease, 0.05 edges deep; on its grid 0.37 and 0.53 R).  Kept: the cavity of a 4-D shell one cell thick
#: (radius 1.5 R), 0.80 edges wide.
THIN_VOID = 0.6
#: R in grid spacings where the grid is not known (the default grid I: R / 4).
DEFAULT_SPACINGS_PER_R = 4.0


def at_mesh_resolution(inside: np.ndarray, radius: float) -> np.ndarray:
    """The region ``inside`` (flags on the grid I) without what no mesh at R (``radius``, grid spacings) shows:
    opened and closed by one spacing, so that bridges and pockets of a voxel or two (a noisy scan's bumps in f, scans
    merged a noise apart) are gone, and its enclosed voids narrower than :data:`THIN_VOID` x R filled, as the
    repair fills the mesh's (a pocket sealed off where two fitted walls meet at a small angle)."""
    structure = np.ones((3,) * inside.ndim, bool)
    padded = np.pad(np.asarray(inside, dtype=bool), 2)
    region = ndimage.binary_closing(ndimage.binary_opening(padded, structure), structure)
    voids, _ = ndimage.label(~region)
    outside = voids[(0,) * region.ndim]   # all round (padded)
    for label, box in enumerate(ndimage.find_objects(voids), start=1):
        if label == outside or box is None:
            continue
        around = tuple(slice(side.start - 1, side.stop + 1) for side in box)   # inside the padding
        void = voids[around] == label
        walls = sum(np.count_nonzero(np.diff(void.view(np.int8), axis=axis)) for axis in range(region.ndim))
        if region.ndim * np.count_nonzero(void) / walls < THIN_VOID * radius:
            region[around] |= void
    return region


def on_dropped_parts(grid, inside: np.ndarray, centroids: np.ndarray, samples: np.ndarray, min_component: float):
    """The samples (n, k) on parts of f > 0 (``inside``, on the nodes of ``grid``) that the mesh, whose cells'
    centroids are (m, k), has no cell in and whose volume is below ``min_component`` x the largest part's: parts
    dropped on purpose (a sample's part: the one nearest to it).  Returns ((n,) bool, how many such parts)."""
    parts, count = grid_parts(inside)
    on_them = np.zeros(len(samples), bool)
    if count < 2:
        return on_them, 0
    volume = np.bincount(parts.ravel())[1:]
    small = np.flatnonzero(volume < min_component * volume.max()) + 1
    dropped = np.setdiff1d(small, parts[grid.nearest_nodes(centroids)])
    if len(dropped):   # a sample belongs to the part nearest to it (on f = 0 or, noisy, beside it)
        node = grid.nearest_nodes(samples)
        part = parts[node]
        outside = part == 0
        if outside.any():   # the part node nearest an outside node has a face neighbour outside: on a part's rim
            rim = np.argwhere((parts > 0) & ~ndimage.binary_erosion(parts > 0))
            nearest = rim[cKDTree(rim).query(np.stack(node, axis=1)[outside])[1]]
            part[outside] = parts[tuple(nearest.T)]
        on_them = np.isin(part, dropped)
    return on_them, len(dropped)
