"""Mesh optimisation: the relaxation and the sliver removal that the paper leaves to future work (sections 5-6).

1. Boundary nodes: every node on the boundary of the mesh goes onto f = 0 (Newton steps along grad f,
   :func:`bitemesh.core.biting.project_to_surface`) and every later move keeps it there.
2. Relaxation (:func:`relax`): optimal Delaunay triangulation (ODT) smoothing, Alliez et al. 2005.  Each interior
   node moves to the volume-weighted mean of the circumcentres of its cells, each boundary node towards the
   area-weighted mean of the centroids of its boundary facets, along the surface and back onto f = 0; then the
   nodes are triangulated again (Delaunay and the circumcentre test), until the mean radius ratio stops rising.
   The last state is carved into a valid domain (:func:`bitemesh.core.domain.carve_domain`).
3. Sliver removal (:func:`remove_slivers`): rounds of flips (:func:`flip`), which replace the cells around an
   interior edge (edge removal: 3-2, 4-4, 5-6 ... flips) or on both sides of an interior facet (2-3 flips; 2-2 in
   2D) when that raises the worst radius ratio among them, then of smoothing (:func:`smooth`), which moves the nodes
   down sum over the cells of (1 / mean ratio)^2 (Knupp's inverse mean ratio, infinite for a flat cell) with the
   boundary nodes sliding on f = 0.  A poor cell left (an angle below ``min_dihedral`` or a radius ratio below
   ``min_quality``) that lies on the surface is peeled (:func:`peel`).  The rounds end when no cell is poor (within
   ``SLIVER_ROUNDS``).
4. Nothing turns a valid mesh into an invalid one: flips only replace cells inside the domain and smoothing keeps
   every cell positive; :func:`bitemesh.core.quality.check_valid_domain` then judges the states met, and the best
   valid one is returned (the input itself when nothing did better).  Nor does anything change its topology (the
   boundary's components and Euler characteristic, :func:`topology`): a relaxation that opened or closed a hole
   through a wall thinner than about a cell is abandoned, and the sliver removal starts from the input.

The nodes are the biting's, only moved (the carving may drop one that no cell inside uses): the node spacing stays
uniform.  Everything is deterministic.  Measured on a sphere of 10,000 cells (``tests/core/test_optimize.py``): mean
radius ratio 0.81 -> 0.90, smallest dihedral angle 0.6 -> 32 degrees, edge-length CV 0.17 -> 0.12, in 2.5 s,
about 9 times the mesh steps before it (biting, Delaunay, carving) and 1.8 times the whole pipeline from scattered
points.
"""
from __future__ import annotations

from itertools import combinations, permutations
from math import factorial

import numpy as np

from .biting import project_to_surface
from .delaunay import delaunay
from .domain import carve_domain, compact
from .errors import InvalidInputError, MeshingError
from .grid import ImplicitGrid
from .mesh import Mesh, circumspheres
from .parameters import OptimizeParameters, SpuriousParameters
from .progress import ProgressCallback, report, sub_progress
from .quality import (boundary_euler_characteristic, check_valid_domain, count_boundary_components, dihedral_angles,
                      edge_lengths)
from .spurious import outside_cells
from .topology import boundary_facets, facet_table, neighbour_pairs, non_manifold_faces, unique_rows

#: the relaxation, and the rounds of sliver removal once no cell is below the angle bound, stop when the mean
#: radius ratio has not risen by MEAN_GAIN over their last PATIENCE iterations (rounds: over the last one).
MEAN_GAIN = 2e-3
PATIENCE = 2
#: rounds of carving the relaxed nodes into a domain and moving the boundary nodes it left off f = 0.
SURFACE_ROUNDS = 3
#: an interior node may come no closer to f = 0 than this fraction of the mean edge length.
INTERIOR_MARGIN = 0.3
#: rounds of flips and smoothing, and the smoothing iterations in each round.
SLIVER_ROUNDS = 4
SMOOTH_ITERATIONS = 6
#: a flip must raise the worst radius ratio of the cells it replaces by at least FLIP_GAIN; only groups of cells
#: with a radius ratio below FLIP_QUALITY are tried (the others rarely gain: measured, no change in the result).
FLIP_GAIN = 1e-3
FLIP_QUALITY = 0.8
#: passes of flips in a round (each pass makes a set of flips that share no cell), and the largest ring of cells
#: around an edge that edge removal triangulates again (in 42 ways for 7).
FLIP_PASSES = 12
MAX_RING = 7
#: smoothing: exponent p of the cost (1 / mean ratio)^p, longest move (x mean edge length), the step lengths tried.
SMOOTH_POWER = 2
MAX_MOVE = 0.2
STEP_FRACTIONS = (1.0, 0.5, 0.25, 0.125)
#: rounds in which moves that made a shared cell worse are taken back (smoothing), or in which peeled cells that
#: pinched the boundary come back (peel).
REVERT_ROUNDS = 10
#: sum of squared edge lengths / V^(2/k) of the regular triangle and tetrahedron.
MEAN_RATIO_SCALE = {2: 4.0 * np.sqrt(3.0), 3: 12.0 * 3.0 ** (2.0 / 3.0)}
#: a boundary node is on the surface when |f| there is below this fraction of the mean edge length.
SURFACE_TOLERANCE = 0.01


# --- measures of cells ---------------------------------------------------------------------------------------------

def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of (m, 3) arrays (faster than ``np.cross`` on short rows)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def signed_radius_ratio(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m,) the radius ratio Q = k r_in / R_circ of each cell, negative for an inverted cell, 0 for a flat one.

    Closed forms.  3D, with a, b, c the edges from vertex 0 and V6 = a . (b x c) six times the volume:
    Q = 6 V6 |V6| / (S |N|), S twice the surface area, N = |a|^2 b x c + |b|^2 c x a + |c|^2 a x b
    (R_circ = |N| / 2 |V6|).  2D: Q = 4 A2 |A2| / (P l_a l_b l_c), A2 twice the signed area, P the perimeter.
    Equal to :func:`bitemesh.core.quality.radius_ratio` on positive cells, and several times faster.
    """
    corners = points[cells]
    a, b = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    if points.shape[1] == 2:
        twice_area = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        sides = [np.sqrt(_dot(v, v)) for v in (a, b, b - a)]
        numerator = 4.0 * twice_area * np.abs(twice_area)
        denominator = (sides[0] + sides[1] + sides[2]) * sides[0] * sides[1] * sides[2]
    else:
        c = corners[:, 3] - corners[:, 0]
        bc, ca, ab = _cross(b, c), _cross(c, a), _cross(a, b)
        six_volume = _dot(a, bc)
        centre = _dot(a, a)[:, None] * bc + _dot(b, b)[:, None] * ca + _dot(c, c)[:, None] * ab
        facing = bc + ca + ab  # twice the area vector of the facet opposite vertex 0
        surface = sum(np.sqrt(_dot(v, v)) for v in (bc, ca, ab, facing))
        numerator = 6.0 * six_volume * np.abs(six_volume)
        denominator = surface * np.sqrt(_dot(centre, centre))
    return np.divide(numerator, denominator, out=np.zeros(len(cells)), where=denominator > 0)


def mean_ratio_cost(volume: np.ndarray, squares: np.ndarray, k: int) -> np.ndarray:
    """(m,) 1 / mean ratio of simplices of signed measure ``volume`` and sum of squared edge lengths ``squares``.

    The mean ratio is eta = C_k V^(2/k) / (sum of squared edge lengths), 1 for the regular simplex.  1 / eta is
    smooth, >= 1, and grows without bound as a cell flattens (inf for no or negative volume): a descent on it
    cannot invert a cell.
    """
    cost = np.full(len(volume), np.inf)
    positive = volume > 0
    cost[positive] = squares[positive] / (MEAN_RATIO_SCALE[k] * volume[positive] ** (2.0 / k))
    return cost


def mean_ratio_terms(corners: np.ndarray):
    """What :func:`mean_ratio_cost` and its derivatives need, for (m, k + 1, k) ``corners``.

    Returns
    -------
    volume : (m,) signed measure
    squares : (m,) sum of the squared edge lengths
    volume_gradient : (m, k + 1, k) d volume / d vertex; the volume is linear in each vertex, so
        volume + volume_gradient[:, i] . d is exact when vertex i alone moves by d
    centred : (m, k + 1, k) the vertices minus their mean; when vertex i alone moves by d, squares grows by
        2 (k + 1) centred[:, i] . d + k |d|^2
    """
    k = corners.shape[-1]
    edges = corners[:, 1:] - corners[:, :1]
    # d V / d x_i for i >= 1: the cofactors of the edge matrix; d V / d x_0 = -(their sum)
    if k == 2:
        cofactors = np.stack([np.stack([edges[:, 1, 1], -edges[:, 1, 0]], axis=1),
                              np.stack([-edges[:, 0, 1], edges[:, 0, 0]], axis=1)], axis=1)
    else:
        cofactors = np.stack([_cross(edges[:, 1], edges[:, 2]), _cross(edges[:, 2], edges[:, 0]),
                              _cross(edges[:, 0], edges[:, 1])], axis=1)
    cofactors /= factorial(k)
    volume = _dot(edges[:, 0], cofactors[:, 0])
    volume_gradient = np.concatenate([-cofactors.sum(axis=1, keepdims=True), cofactors], axis=1)
    total = edges.sum(axis=1)
    squares = (k + 1) * np.einsum("mij,mij->m", edges, edges) - _dot(total, total)
    centred = np.concatenate([np.zeros_like(edges[:, :1]), edges], axis=1) - total[:, None] / (k + 1)
    return volume, squares, volume_gradient, centred


def inverse_mean_ratio(corners: np.ndarray) -> np.ndarray:
    """(m,) :func:`mean_ratio_cost` of the simplices with (m, k + 1, k) ``corners``."""
    k = corners.shape[-1]
    edges = corners[:, 1:] - corners[:, :1]
    if k == 2:
        volume = 0.5 * (edges[:, 0, 0] * edges[:, 1, 1] - edges[:, 0, 1] * edges[:, 1, 0])
    else:
        volume = _dot(edges[:, 0], _cross(edges[:, 1], edges[:, 2])) / 6.0
    total = edges.sum(axis=1)
    squares = (k + 1) * np.einsum("mij,mij->m", edges, edges) - _dot(total, total)
    return mean_ratio_cost(volume, squares, k)


def smallest_angles(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m,) the smallest dihedral angle (3D) or interior angle (2D) of each cell, degrees; 0 for a flat cell."""
    return np.nan_to_num(dihedral_angles(points, cells).min(axis=1), nan=0.0)


def mean_edge_length(points: np.ndarray, cells: np.ndarray) -> float:
    return float(edge_lengths(points, cells)[1].mean())


def boundary_nodes(cells: np.ndarray, n_points: int) -> np.ndarray:
    """(n_points,) bool, True for the vertices of the boundary facets."""
    on_boundary = np.zeros(n_points, bool)
    on_boundary[boundary_facets(cells).ravel()] = True
    return on_boundary


def off_surface_nodes(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, tolerance: float) -> np.ndarray:
    """The boundary nodes where |f| exceeds ``tolerance``."""
    nodes = np.flatnonzero(boundary_nodes(cells, len(points)))
    return nodes[np.abs(grid.evaluate(points[nodes])) > tolerance]


def _scatter(n_points: int, simplices: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(n_points, k) the sums at each vertex of ``values`` (m, j, k), one row per corner of the (m, j) simplices."""
    flat = values.reshape(simplices.size, -1)
    return np.stack([np.bincount(simplices.ravel(), flat[:, d], n_points) for d in range(flat.shape[1])], axis=1)


def _tangential(grid: ImplicitGrid, points: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """``vectors`` at ``points`` without their component along grad f."""
    gradient = grid.gradient(points)
    normals = gradient / np.maximum(np.linalg.norm(gradient, axis=1, keepdims=True), 1e-300)
    return vectors - _dot(vectors, normals)[:, None] * normals


# --- relaxation ----------------------------------------------------------------------------------------------------

def odt_targets(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, margin: float) -> np.ndarray:
    """(n, k) where the ODT smoothing moves each node (Alliez et al. 2005, section 4).

    Interior nodes: the volume-weighted mean of the circumcentres of their cells, pushed back to f = ``margin``
    when it lies closer to the surface.  Boundary nodes: the area-weighted mean of the centroids of their boundary
    facets, the move taken along the surface, then onto f = 0.  A node in no cell with volume stays.
    """
    n, k = points.shape
    centres, _ = circumspheres(points, cells)
    volume = np.abs(np.linalg.det(points[cells[:, 1:]] - points[cells[:, :1]])) / factorial(k)
    usable = np.isfinite(centres).all(axis=1)
    weight = np.bincount(cells[usable].ravel(), np.repeat(volume[usable], k + 1), n)
    weighted = np.repeat((volume[usable, None] * centres[usable])[:, None], k + 1, axis=1)
    targets = points.copy()
    inner = np.flatnonzero(weight > 0)
    targets[inner] = _scatter(n, cells[usable], weighted)[inner] / weight[inner, None]

    facets = boundary_facets(cells)
    corners = points[facets]
    spans = corners[:, 1:] - corners[:, :1]
    area = np.linalg.norm(_cross(spans[:, 0], spans[:, 1]) if k == 3 else spans[:, 0], axis=1)
    along = _scatter(n, facets, np.repeat((area[:, None] * corners.mean(axis=1))[:, None], k, axis=1))
    along_weight = np.bincount(facets.ravel(), np.repeat(area, k), n)

    on_boundary = boundary_nodes(cells, n)
    inner = np.flatnonzero(~on_boundary)
    value = grid.evaluate(targets[inner])
    shallow = inner[value < margin]
    if len(shallow):
        gradient = grid.gradient(targets[shallow])
        squared = np.maximum(_dot(gradient, gradient), 1e-12)
        targets[shallow] += ((margin - value[value < margin]) / squared)[:, None] * gradient
    outer = np.flatnonzero(on_boundary & (along_weight > 0))
    goal = along[outer] / along_weight[outer, None]
    targets[outer] = project_to_surface(grid, points[outer] + _tangential(grid, points[outer], goal - points[outer]))
    return targets


def relax(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, iterations: int,
          spurious: SpuriousParameters = SpuriousParameters(), progress: ProgressCallback = None):
    """ODT relaxation: move the nodes (:func:`odt_targets`), triangulate them again, keep the cells inside; repeat.

    Between the moves only the circumcentre test of the spurious-cell filter sorts the cells (fast); the last state
    is carved into a valid domain, and moved and carved again while that left boundary nodes off f = 0 (at most
    ``SURFACE_ROUNDS`` times).  Stops after ``iterations`` moves, or when the mean radius ratio has not risen by
    ``MEAN_GAIN`` over ``PATIENCE`` iterations.  Nodes that no cell inside uses are dropped.

    Returns
    -------
    points, cells : the relaxed valid mesh
    history : list of float, the mean radius ratio after each move

    Raises :class:`MeshingError` when the moved nodes leave no cell inside or cannot be carved into a valid domain.
    """
    length = mean_edge_length(points, cells)
    margin = INTERIOR_MARGIN * length
    history = []
    for iteration in range(iterations):
        moved = odt_targets(grid, points, cells, margin)
        triangulation = delaunay(moved)
        inside = triangulation[~outside_cells(grid, moved, triangulation, spurious.threshold)]
        if len(inside) == 0:
            raise MeshingError("the relaxed nodes leave no cell inside the domain")
        relaxed = compact(moved, inside)
        points, cells = relaxed.points, relaxed.cells
        history.append(float(signed_radius_ratio(points, cells).mean()))
        report(progress, (iteration + 1) / iterations,
               f"relaxation {iteration + 1}/{iterations}: mean radius ratio {history[-1]:.4f}")
        if len(history) > PATIENCE and max(history[-PATIENCE:]) < max(history[:-PATIENCE]) + MEAN_GAIN:
            break
    for round_ in range(SURFACE_ROUNDS):
        if round_:  # the carving laid nodes bare: move them onto f = 0, with the others
            points = odt_targets(grid, points, cells, margin)
        mesh = carve_domain(grid, points, delaunay(points), spurious)
        points, cells = mesh.points, mesh.cells
        if len(off_surface_nodes(grid, points, cells, SURFACE_TOLERANCE * length)) == 0:
            break
    report(progress, 1.0, f"relaxation: {len(history)} iterations, mean radius ratio "
                          f"{signed_radius_ratio(points, cells).mean():.4f} in the carved domain")
    return points, cells, history


# --- smoothing -----------------------------------------------------------------------------------------------------

def smooth(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, iterations: int,
           progress: ProgressCallback = None) -> np.ndarray:
    """Move the nodes to lower sum over the cells of (1 / mean ratio)^p; the cells stay as they are.

    Each iteration takes, for every node, a step down the gradient of the cost of its cells (boundary nodes: its
    tangential part, then back onto f = 0): the best of ``STEP_FRACTIONS`` with the other nodes fixed (exact and
    cheap: a cell's volume is linear in one vertex).  All nodes move at once; a node whose cells then cost more
    than before, or one of which is inverted, goes back.  A boundary node off f = 0 goes onto it as soon as its
    cells stay positive there.

    Returns
    -------
    (n, k) float64, the new node positions
    """
    n, k = points.shape
    corner_of = cells.ravel()
    degree = np.bincount(corner_of, minlength=n)
    on_boundary = np.flatnonzero(boundary_nodes(cells, n))
    length = mean_edge_length(points, cells)
    for iteration in range(iterations):
        report(progress, iteration / iterations, f"smoothing {iteration + 1}/{iterations}")
        volume, squares, volume_gradient, centred = mean_ratio_terms(points[cells])
        cost = mean_ratio_cost(volume, squares, k)
        with np.errstate(all="ignore"):  # inf on cells with no volume: their nodes do not move
            gradient = (SMOOTH_POWER * cost ** SMOOTH_POWER)[:, None, None] * (
                2.0 * (k + 1) * centred / squares[:, None, None] - (2.0 / k) * volume_gradient / volume[:, None, None])
        current = np.bincount(corner_of, np.repeat(cost ** SMOOTH_POWER, k + 1), n)
        descent = -_scatter(n, cells, gradient)
        descent[on_boundary] = _tangential(grid, points[on_boundary], descent[on_boundary])
        # a Newton-like scale: the cost of a node's cells changes by about its own size over an edge length
        descent *= (0.5 * length ** 2 * degree / np.maximum(current, 1e-300))[:, None]
        descent[~np.isfinite(descent).all(axis=1)] = 0.0
        step = np.linalg.norm(descent, axis=1)
        descent *= np.minimum(1.0, MAX_MOVE * length / np.maximum(step, 1e-300))[:, None]

        off_surface = np.zeros(n, bool)
        off_surface[on_boundary] = np.abs(grid.evaluate(points[on_boundary])) > SURFACE_TOLERANCE * length
        limit = np.where(off_surface, np.inf, current)
        best_cost, best_move = limit.copy(), np.zeros_like(points)
        for fraction in STEP_FRACTIONS:
            move = fraction * descent
            move[on_boundary] = project_to_surface(grid, points[on_boundary] + move[on_boundary]) - points[on_boundary]
            # the cost of each node's cells when that node alone moves
            shift = move[cells]
            trial_volume = volume[:, None] + np.einsum("mij,mij->mi", volume_gradient, shift)
            trial_squares = squares[:, None] + np.einsum("mij,mij->mi", 2.0 * (k + 1) * centred + k * shift, shift)
            trial = np.bincount(corner_of, mean_ratio_cost(trial_volume.ravel(), trial_squares.ravel(), k)
                                ** SMOOTH_POWER, n)
            better = trial < best_cost
            best_cost[better], best_move[better] = trial[better], move[better]
        moving = np.isfinite(best_cost) & np.any(best_move != 0, axis=1)
        new = points.copy()
        new[moving] += best_move[moving]
        for _ in range(REVERT_ROUNDS):
            cost = inverse_mean_ratio(new[cells]) ** SMOOTH_POWER
            worse = np.bincount(corner_of, np.repeat(cost, k + 1), n) > limit
            worse[cells[~np.isfinite(cost)].ravel()] = True
            worse &= moving
            if not worse.any():
                break
            new[worse] = points[worse]
            moving &= ~worse
        else:
            new = points
        points = new
    report(progress, 1.0, "smoothing")
    return points


# --- flips ---------------------------------------------------------------------------------------------------------

def polygon_triangulations(n: int):
    """The triangulations of a convex polygon with vertices 0 .. n - 1.

    Returns
    -------
    triangles : (t, 3) int64, every triangle (i < j < l) of the polygon, in the polygon's orientation
    triangulations : (T, n - 2) int64, the rows of ``triangles`` that make up each triangulation (1, 2, 5, 14, 42
        of them for n = 3 .. 7)
    """
    triangles = np.array(list(combinations(range(n), 3)), dtype=np.int64)
    row = {tuple(t): i for i, t in enumerate(triangles.tolist())}

    def triangulate(vertices):
        if len(vertices) < 3:
            return [[]]
        first, last = vertices[0], vertices[-1]
        return [left + [row[(first, apex, last)]] + right
                for split, apex in enumerate(vertices[1:-1], start=1)
                for left in triangulate(vertices[:split + 1]) for right in triangulate(vertices[split:])]
    return triangles, np.array(triangulate(list(range(n))), dtype=np.int64)


RING_TRIANGULATIONS = {n: polygon_triangulations(n) for n in range(3, MAX_RING + 1)}


def _is_even(permutation) -> bool:
    return sum(a > b for a, b in combinations(permutation, 2)) % 2 == 0


#: for each edge (i, j) of a tetrahedron, the other two vertices (k, l) ordered so that (i, j, k, l) is an even
#: permutation of (0, 1, 2, 3): then (v_i, v_j, v_k, v_l) is as positively oriented as (v_0, v_1, v_2, v_3).
EDGE_PAIRS = np.array(list(combinations(range(4), 2)))
EDGE_OTHERS = np.array([next(rest for rest in permutations(set(range(4)) - {i, j}) if _is_even((i, j) + rest))
                        for i, j in EDGE_PAIRS])


def edge_rings(cells: np.ndarray, max_ring: int = MAX_RING) -> dict:
    """The interior edges of a tetrahedral mesh with the cells around them in order.

    Returns
    -------
    n -> (a, b, ring, around) for each ring size n in 3 .. ``max_ring``: the edges (a, b) (E,) whose cells close
    a ring of n; ``ring`` (E, n) the vertices x_0 .. x_{n-1} around the edge, ordered so that every cell
    (a, b, x_i, x_{i+1}) is positively oriented; ``around`` (E, n) the cell holding x_i and x_{i+1}.
    """
    a, b = cells[:, EDGE_PAIRS[:, 0]].ravel(), cells[:, EDGE_PAIRS[:, 1]].ravel()
    x, y = cells[:, EDGE_OTHERS[:, 0]].ravel(), cells[:, EDGE_OTHERS[:, 1]].ravel()
    swap = a > b  # (b, a, x, y) has the other orientation: the ring runs the other way
    a, b, x, y = np.where(swap, b, a), np.where(swap, a, b), np.where(swap, y, x), np.where(swap, x, y)
    owner = np.repeat(np.arange(len(cells)), len(EDGE_PAIRS))
    edges, group, counts = unique_rows(np.stack([a, b], axis=1))
    order = np.argsort(group, kind="stable")
    start = np.concatenate([[0], np.cumsum(counts)])
    rings = {}
    for n in range(3, max_ring + 1):
        chosen = np.flatnonzero(counts == n)
        rows = order[start[chosen][:, None] + np.arange(n)]
        xs, ys, cell = x[rows], y[rows], owner[rows]
        every = np.arange(len(chosen))
        ring, around = np.empty_like(xs), np.empty_like(cell)
        ring[:, 0], around[:, 0], current = xs[:, 0], cell[:, 0], ys[:, 0]
        closed = np.ones(len(chosen), bool)  # an edge on the boundary has an open fan of cells
        for i in range(1, n):
            hit = xs == current[:, None]
            closed &= hit.sum(axis=1) == 1
            column = np.argmax(hit, axis=1)
            ring[:, i], around[:, i], current = current, cell[every, column], ys[every, column]
        closed &= current == ring[:, 0]
        rings[n] = (edges[chosen[closed], 0], edges[chosen[closed], 1], ring[closed], around[closed])
    return rings


def flip_candidates(points: np.ndarray, cells: np.ndarray, quality: np.ndarray):
    """The flips that raise the worst radius ratio of the cells they replace by more than ``FLIP_GAIN``, among
    the groups of cells whose worst radius ratio is below ``FLIP_QUALITY``.

    3D: edge removal (the n cells around an interior edge by the 2 (n - 2) cells of the best triangulation of
    their ring joined to both ends of the edge; n = 3 is the 3-2 flip, n = 4 the 4-4 flip) and 2-3 flips (the two
    cells on an interior facet by three around the edge joining their far vertices).  2D: 2-2 flips.  Every new
    cell must be positively oriented, so the new cells fill exactly the old ones' place.

    Returns
    -------
    list of (old (c, j) cell indices, new (c, j', k + 1) cells, gain (c,)), one entry per kind of flip
    """
    k = points.shape[1]
    found = []
    if k == 3:
        for n, (a, b, ring, around) in edge_rings(cells).items():
            worst_old = quality[around].min(axis=1)
            poor = worst_old < FLIP_QUALITY
            a, b, ring, around, worst_old = a[poor], b[poor], ring[poor], around[poor], worst_old[poor]
            triangles, triangulations = RING_TRIANGULATIONS[n]
            x, y, z = (ring[:, triangles[:, i]] for i in range(3))
            apex_b, apex_a = (np.broadcast_to(v[:, None], x.shape) for v in (b, a))
            new = np.stack([np.stack([x, y, z, apex_b], axis=-1), np.stack([x, z, y, apex_a], axis=-1)], axis=2)
            worst = signed_radius_ratio(points, new.reshape(-1, 4)).reshape(new.shape[:3]).min(axis=2)
            by_triangulation = worst[:, triangulations].min(axis=2)  # (E, T)
            best = np.argmax(by_triangulation, axis=1) if len(a) else np.zeros(0, np.int64)
            gain = by_triangulation[np.arange(len(a)), best] - worst_old
            keep = gain > FLIP_GAIN
            chosen = new[np.flatnonzero(keep)[:, None], triangulations[best[keep]]].reshape(-1, 2 * (n - 2), 4)
            found.append((around[keep], chosen, gain[keep]))
    facets, inverse, _ = facet_table(cells)
    first, second = neighbour_pairs(inverse)
    cell_a, cell_b = first // (k + 1), second // (k + 1)
    worst_old = np.minimum(quality[cell_a], quality[cell_b])
    poor = worst_old < FLIP_QUALITY
    first, second, cell_a, cell_b, worst_old = first[poor], second[poor], cell_a[poor], cell_b[poor], worst_old[poor]
    a, b = cells[cell_a, first % (k + 1)], cells[cell_b, second % (k + 1)]
    facet = facets[first]  # oriented out of cell_a, towards b
    if k == 3:
        new = np.stack([np.stack([a, b, facet[:, i], facet[:, (i + 1) % 3]], axis=1) for i in range(3)], axis=1)
    else:
        new = np.stack([np.stack([a, facet[:, 0], b], axis=1), np.stack([b, facet[:, 1], a], axis=1)], axis=1)
    gain = signed_radius_ratio(points, new.reshape(-1, k + 1)).reshape(new.shape[:2]).min(axis=1) - worst_old
    keep = gain > FLIP_GAIN
    found.append((np.stack([cell_a, cell_b], axis=1)[keep], new[keep], gain[keep]))
    return found


def independent_flips(candidates: list, n_cells: int) -> np.ndarray:
    """(c,) bool over all candidates in order: flips that share no cell, the largest gains first.

    In rounds, a candidate wins when its gain is the largest among the candidates that share a cell with it; the
    candidates that touch a winner's cells drop out.  Each round settles at least the largest gain left.
    """
    gains = np.concatenate([gain for _, _, gain in candidates])
    offsets = np.cumsum([0] + [len(gain) for _, _, gain in candidates])
    owners = np.concatenate([np.repeat(np.arange(len(old)) + offset, old.shape[1])
                             for (old, _, _), offset in zip(candidates, offsets)])
    touched = np.concatenate([old.ravel() for old, _, _ in candidates])
    key = gains + 1e-12 * np.arange(len(gains)) / max(len(gains), 1)  # no ties
    active = np.ones(len(gains), bool)
    chosen = np.zeros(len(gains), bool)
    for _ in range(len(gains)):
        if not active.any():
            break
        live = active[owners]
        best = np.full(n_cells, -np.inf)
        np.maximum.at(best, touched[live], key[owners[live]])
        beaten = np.zeros(len(gains), bool)
        beaten[owners[live & (best[touched] > key[owners])]] = True
        winners = active & ~beaten
        chosen |= winners
        used = np.zeros(n_cells, bool)
        used[touched[winners[owners]]] = True
        blocked = np.zeros(len(gains), bool)
        blocked[owners[used[touched]]] = True
        active &= ~blocked
    return chosen


def flip(points: np.ndarray, cells: np.ndarray, passes: int = FLIP_PASSES,
         progress: ProgressCallback = None) -> np.ndarray:
    """Apply improving flips (:func:`flip_candidates`), pass after pass, until none is left (at most ``passes``).

    Flips replace cells inside the domain only: the boundary, the nodes and the volume stay as they are.

    Returns
    -------
    (m', k + 1) int64, the new cells, positively oriented
    """
    for pass_ in range(passes):
        candidates = flip_candidates(points, cells, signed_radius_ratio(points, cells))
        found = sum(len(gain) for _, _, gain in candidates)
        report(progress, pass_ / passes, f"flip pass {pass_ + 1}: {found} improving flips")
        if not found:
            break
        chosen = independent_flips(candidates, len(cells))
        removed = np.zeros(len(cells), bool)
        added = []
        start = 0
        for old, new, gain in candidates:
            take = chosen[start:start + len(gain)]
            start += len(gain)
            removed[old[take].ravel()] = True
            added.append(new[take].reshape(-1, cells.shape[1]))
        cells = np.concatenate([cells[~removed]] + added)
    return cells


# --- the step ------------------------------------------------------------------------------------------------------

def peel(cells: np.ndarray, n_points: int, candidates: np.ndarray) -> np.ndarray:
    """``cells`` without those of the ``candidates`` (indices) that have two or more boundary facets.

    Such a cell lies on the surface (across a crease, or flat on a curved part): its vertices are boundary nodes
    before and after, and the boundary moves in by the cell's volume.  A cell whose removal would pinch the
    boundary or leave a node unused stays.
    """
    k = cells.shape[1] - 1
    _, inverse, counts = facet_table(cells)
    on_surface = (counts[inverse] == 1).reshape(-1, k + 1).sum(axis=1) >= 2
    removed = np.zeros(len(cells), bool)
    removed[candidates[on_surface[candidates]]] = True
    for _ in range(REVERT_ROUNDS):
        if not removed.any():
            break
        kept = cells[~removed]
        trouble = np.bincount(kept.ravel(), minlength=n_points) == 0
        for faces in non_manifold_faces(kept, n_points):
            trouble[faces.ravel()] = True
        restore = removed & trouble[cells].any(axis=1)
        if not restore.any():
            return kept
        removed &= ~restore
    return cells


def poor_cells(points: np.ndarray, cells: np.ndarray, min_angle: float, min_quality: float) -> np.ndarray:
    """The cells with an angle below ``min_angle`` (degrees; dihedral in 3D, interior in 2D) or a radius ratio
    below ``min_quality``."""
    return np.flatnonzero((smallest_angles(points, cells) < min_angle)
                          | (signed_radius_ratio(points, cells) < min_quality))


def remove_slivers(grid: ImplicitGrid, points: np.ndarray, cells: np.ndarray, min_angle: float,
                   min_quality: float, progress: ProgressCallback = None) -> list:
    """Rounds of :func:`flip` and :func:`smooth` until no cell is poor (:func:`poor_cells`).

    After a round's smoothing, the poor cells that lie on the surface are peeled (:func:`peel`).  At least two
    rounds (the second gains from the first's flips), at most ``SLIVER_ROUNDS``; they stop once no cell is poor
    and the mean radius ratio no longer rises by ``MEAN_GAIN``.

    Returns
    -------
    list of (points, cells), the state after each round
    """
    states = []
    mean = signed_radius_ratio(points, cells).mean()
    for round_ in range(SLIVER_ROUNDS):
        cells = flip(points, cells, progress=sub_progress(progress, round_ / SLIVER_ROUNDS,
                                                          (round_ + 0.2) / SLIVER_ROUNDS))
        points = smooth(grid, points, cells, SMOOTH_ITERATIONS,
                        sub_progress(progress, (round_ + 0.2) / SLIVER_ROUNDS, (round_ + 1) / SLIVER_ROUNDS))
        poor = poor_cells(points, cells, min_angle, min_quality)
        if len(poor):
            cells = peel(cells, len(points), poor)
            poor = poor_cells(points, cells, min_angle, min_quality)
        states.append((points, cells))
        previous, mean = mean, signed_radius_ratio(points, cells).mean()
        report(progress, (round_ + 1) / SLIVER_ROUNDS,
               f"sliver removal round {round_ + 1}: mean radius ratio {mean:.4f}, {len(poor)} cells with an angle "
               f"below {min_angle:g} degrees or a radius ratio below {min_quality:g}")
        if round_ >= 1 and len(poor) == 0 and mean < previous + MEAN_GAIN:
            break
    return states


def _defects(grid: ImplicitGrid, mesh: Mesh, parameters: OptimizeParameters, tolerance: float) -> tuple:
    """What keeps ``mesh`` from the goal: the number of poor cells, of boundary nodes off f = 0, and the mean
    radius ratio."""
    poor = len(poor_cells(mesh.points, mesh.cells, parameters.min_dihedral, parameters.min_quality))
    off = len(off_surface_nodes(grid, mesh.points, mesh.cells, tolerance))
    return poor, off, float(signed_radius_ratio(mesh.points, mesh.cells).mean())


def topology(mesh: Mesh) -> tuple:
    """(boundary components, boundary Euler characteristic) of a valid mesh: what optimising must not change."""
    return count_boundary_components(mesh), boundary_euler_characteristic(mesh)


def optimize_mesh(grid: ImplicitGrid, mesh: Mesh, parameters: OptimizeParameters = OptimizeParameters(),
                  progress: ProgressCallback = None) -> Mesh:
    """Relax the nodes, remove the slivers and keep the boundary on f = 0 (see the module's docstring).

    Parameters
    ----------
    grid : the implicit function f on the grid I (f > 0 inside)
    mesh : a valid mesh of {f > 0}, triangles (2D) or tetrahedra (3D), positively oriented, as from
        :func:`bitemesh.core.pipeline.mesh_from_grid`; it is not modified
    parameters : the relaxation's iteration bound and the bounds (angle, radius ratio) of the sliver removal
    progress : callable(fraction, message), optional; the messages report the mean radius ratio as it converges
        and, last, what remains (poor cells, boundary nodes off f = 0); it may raise
        :class:`~bitemesh.core.errors.Cancelled`

    Returns
    -------
    A valid mesh without cell data: of the states met (the input, the relaxed mesh, the mesh after each round of
    sliver removal) the valid one with the input's :func:`topology` and the fewest poor cells (:func:`poor_cells`)
    plus boundary nodes off f = 0, then the highest mean radius ratio; the input's points and cells when nothing did
    better.
    Raises :class:`MeshingError` when no state, the input included, is a valid domain.
    """
    if mesh.dim != grid.dim:
        raise InvalidInputError(f"mesh is {mesh.dim}D but grid is {grid.dim}D; optimise a mesh of the same dimension")
    if len(mesh.cells) == 0:
        raise InvalidInputError("mesh has no cells: there is nothing to optimise")
    start = Mesh(np.array(mesh.points, dtype=np.float64), np.array(mesh.cells, dtype=np.int64))
    tolerance = SURFACE_TOLERANCE * mean_edge_length(start.points, start.cells)
    states = [start]
    shape = topology(start)
    points, cells = start.points, start.cells
    if parameters.iterations:
        try:
            points, cells, _ = relax(grid, points, cells, parameters.iterations,
                                     progress=sub_progress(progress, 0.0, 0.5))
            if topology(Mesh(points, cells)) != shape:
                raise MeshingError("the relaxed boundary has (components, Euler characteristic) "
                                   f"{topology(Mesh(points, cells))}, the input {shape}")
            states.append(Mesh(points, cells))
        except MeshingError as error:  # the relaxed nodes do not carve into the input's valid domain
            report(progress, 0.5, f"relaxation abandoned ({error}); removing the input's slivers")
            points, cells = start.points, start.cells
    states += [Mesh(p, c) for p, c in remove_slivers(grid, points, cells, parameters.min_dihedral,
                                                     parameters.min_quality, sub_progress(progress, 0.5, 0.95))]
    report(progress, 0.95, "checking the result")
    defects = [_defects(grid, state, parameters, tolerance) for state in states]
    for index in sorted(range(len(states)), key=lambda i: (defects[i][0] + defects[i][1], -defects[i][2], -i)):
        if not check_valid_domain(states[index]) and topology(states[index]) == shape:
            poor, off, mean = defects[index]
            outcome = "optimised" if index else "kept the input (nothing did better)"
            report(progress, 1.0, f"{outcome}: mean radius ratio {mean:.4f}; remain {poor} cells with an angle "
                                  f"below {parameters.min_dihedral:g} degrees or a radius ratio below "
                                  f"{parameters.min_quality:g}, {off} boundary nodes off f = 0")
            return states[index]
    raise MeshingError("the mesh is not a valid domain, and optimising did not make it one: "
                       + "; ".join(check_valid_domain(start)))
