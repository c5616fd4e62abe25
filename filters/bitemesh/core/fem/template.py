"""The deformable elastic template of the paper (section 2): a tetrahedral mesh moved onto new data by minimising
E = E_elastic + E_data, discretised as K U = F, with the same cells.

Scheme. First a similarity (rotation, uniform scale, translation; :mod:`.alignment`) takes the template's surfaces
onto their data: iterated closest points from the data to its surface with Umeyama's closed form (the data may
sample a surface in part, as contours do), so that a pure rigid motion or scaling is recovered exactly and the
elastic part only has to bend. Then stages (load steps) of the elastic fit, each the paper's K U = F: K the
template's own P1 linear elasticity measured from the stage's start (the first stage's from the template at rest,
``rest``, when a cycle starts each frame from the last), F the pulls of the data (:func:`springs`: point to plane on
the nodes the data claim, harmonic in between, so that a surface sampled by contours 10 mm apart moves as a whole),
the correspondences recomputed each round. A cell whose shape degrades from the template's stiffens (Jacobian-based
stiffening, as in mesh moving: Stein, Tezduyar and Benney 2003); where a step would invert or flatten a cell, or
take its smallest dihedral angle below ANGLE_FLOOR (10 degrees) or its radius ratio below RATIO_FLOOR (0.2), the
step of its nodes is halved. The rounds of a stage end when the RMS step is below ``tolerance`` mean edge lengths or
a round brings the data closer by less than :data:`ROUND_GAIN` mean edge lengths; the stages, when one moves the
nodes less than :data:`STAGE_END` edge lengths (RMS). Each cell's Fibre, Sheet and SheetNormal are carried by its
deformation gradient and made orthonormal again; its quality arrays are those of the moved cell. A fit that leaves
more than FAR_SHARE of the data farther than a mean edge from its boundary is refused, not returned; so is a fit to
points of the whole boundary that leaves FAR_SHARE of its boundary's area far from every point (another shape
wrapped).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as splinalg
from scipy.spatial import cKDTree

from ..errors import InvalidInputError, MeshingError, check_number, check_points
from ..implicit.samples import sample_spacing
from ..mesh.quality import cell_quality, radius_ratio
from ..mesh.simplicial import Mesh, signed_measures
from ..mesh.topology import boundary_facets, distinct_faces
from ..parameters import Parameters, parameter
from ..progress import ProgressCallback, report
from ..mesh.simplicial import facet_measures
from ..steps.fidelity import distances_to_facets
from ..optimize.measures import inverse_mean_ratio, mean_edge_length, smallest_angles
from .alignment import align
from .assembly import Pattern, basis_gradients, elasticity_elements, solve

#: a node is pulled only by data within this many times the median distance between the surfaces and their data
#: (and two edge lengths): a part of a surface that the data does not sample follows the rest, not a far point.
REACH = 3.0
#: the most halvings of the step of a cell's nodes when it would invert the cell, and the smallest share of its
#: volume a cell may keep in one step (a step that flattens a cell is halved too).
HALVINGS, SHRINK = 12, 0.05
#: a cell's nodes' step is halved while it would take the cell's smallest dihedral angle below this (degrees) or its
#: radius ratio below RATIO_FLOOR (a cap can keep its angles and still go flat); a cell already below may not lose
#: more: FEM-grade cells whatever the data ask, with no erosion over the rounds.
ANGLE_FLOOR, RATIO_FLOOR = 10.0, 0.2
#: a pulled node's spring along its surface, as a share of the one across it (point to plane, mostly).
SLIDE = 0.1
#: a cell whose inverse mean ratio grew by a factor g from the template's stiffens by g ** STIFFENING, so that the
#: pulls cannot flatten it.
STIFFENING = 4.0
#: a fit is refused when more than this share of the data lie farther than a mean edge from its boundary (the
#: mesher's fidelity rule, in the fit's terms): the template did not take the data's shape.
FAR_SHARE = 0.05
#: the stages (load steps) end when one moves the nodes less than this many mean edge lengths (RMS).
STAGE_END = 0.1
#: a stage's rounds end at the first that brings the data closer to their surfaces by less than this many mean edge
#: lengths on average (0.002 mm at the heart's 2.4 mm edges): measured to the facets, a gain that has no floor, so
#: that neither the last bits of a distance nor the nodes' spacing end a stage whose data still come closer (ten
#: times more, 0.01, left biv-me's patient_2 refused and the walls of an end-systole 5-7 mm above its base).
ROUND_GAIN = 0.001


@dataclass(frozen=True)
class FitParameters(Parameters):
    """TemplateFit: the elastic template's one choice (the VTK filter, ParaView, ``bitemesh fit --pull``)."""

    pull: float = parameter(3.0, "the data's pull on the template's surfaces relative to its stiffness there (3: "
                            "within a tenth of an edge of contours; lower: smoother surfaces and better cells at "
                            "thin walls, farther from the data)", low=0, low_open=True)


@dataclass(frozen=True, eq=False)
class TemplateFit:
    """A template moved onto data.

    Attributes
    ----------
    mesh : the template's cells and tags on the moved points (input units of the data)
    similarity : (scale, rotation (3, 3), translation (3,)): the pre-alignment, x -> scale R x + t
    rounds : elastic rounds run; seconds : wall clock of the fit
    distances : (n,) float64, each data point's distance to the moved mesh's boundary (input units)
    """

    mesh: Mesh
    similarity: tuple
    rounds: int
    distances: np.ndarray
    seconds: float = 0.0


def node_normals(points: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """(n, 3) unit normals at the points of a triangulated surface ``facets`` (f, 3), area-weighted."""
    a, b, c = (points[facets[:, k]] for k in range(3))
    sums = np.zeros_like(points)
    cross = np.cross(b - a, c - a)
    for k in range(3):
        np.add.at(sums, facets[:, k], cross)
    return sums / np.maximum(np.linalg.norm(sums, axis=1, keepdims=True), 1e-300)


def springs(points: np.ndarray, groups: list, reach: float, weight: float):
    """(P sparse (3n, 3n), F (3n,)): the pulls of the data on the surfaces.  Each data point claims the nearest node
    of its surface (pairs longer than ``reach`` left out); a claimed node is to move across its surface onto its
    nearest data point (not the mean of a curved patch, which lies inside it); the nodes between sampled contours
    move as the harmonic interpolation of those moves over the surface (:func:`spread`).  Each node of a sampled
    surface is held to its move by a spring of stiffness ``weight`` across the surface and :data:`SLIDE` x that
    along it."""
    rows, columns, values, force = [], [], [], np.zeros(points.shape)
    for nodes, facets, data, tree in groups:
        surface = points[nodes]
        apart, nearest = cKDTree(surface).query(data)
        claimed = np.unique(nearest[apart <= reach])
        if not len(claimed):
            continue
        normal = node_normals(surface, facets)
        across = np.einsum("pi,pi->p", data[tree.query(surface[claimed])[1]] - surface[claimed], normal[claimed])
        offset = spread(facets, len(nodes), claimed, across[:, None] * normal[claimed])
        blocks = weight * ((1 - SLIDE) * normal[:, :, None] * normal[:, None, :] + SLIDE * np.eye(3))
        index = 3 * nodes[:, None] + np.arange(3)
        rows.append(np.repeat(index, 3, axis=1).ravel())
        columns.append(np.tile(index, 3).ravel())
        values.append(blocks.ravel())
        np.add.at(force, nodes, np.einsum("pij,pj->pi", blocks, offset))
    size = 3 * len(points)
    matrix = sparse.coo_matrix((np.concatenate(values), (np.concatenate(rows), np.concatenate(columns))),
                               shape=(size, size))
    return matrix.tocsr(), force.ravel()


def spread(facets: np.ndarray, count: int, known: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(count, k) ``values`` (len(known), k) given at the nodes ``known`` of the triangulation ``facets`` (f, 3),
    harmonic elsewhere (the graph Laplacian's solution; a part without a known node decays to 0)."""
    edges = distinct_faces(facets, 2)
    adjacency = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(count, count))
    adjacency = (adjacency + adjacency.T).tocsr()
    laplacian = (sparse.diags(np.asarray(adjacency.sum(axis=1)).ravel() + 1e-9) - adjacency).tocsr()
    unknown = np.setdiff1d(np.arange(count), known)
    result = np.zeros((count, values.shape[1]))
    result[known] = values
    if len(unknown):
        result[unknown] = splinalg.spsolve(laplacian[unknown][:, unknown].tocsc(),
                                           -(laplacian[unknown][:, known] @ values)).reshape(len(unknown), -1)
    return result


def median_gap(points: np.ndarray, groups: list) -> float:
    """The median distance from the data to the nearest node of its surface."""
    return float(np.median(np.concatenate([cKDTree(points[nodes]).query(data)[0] for nodes, _, data, _ in groups])))


def mean_gap(points: np.ndarray, groups: list) -> float:
    """The mean distance from the data to its surface (exact, to the facets)."""
    return float(np.mean(np.concatenate([distances_to_facets(data, points[nodes][facets])
                                         for nodes, facets, data, _ in groups])))


def surface_groups(template: Mesh, data) -> dict:
    """Surface name -> (node indices, facets over them (f, 3), data points, their cKDTree): ``data`` an (n, 3)
    array for the whole boundary (named "boundary"), or a mapping of the template's facet tag names to the points of
    that surface (a tag without data is left free)."""
    if not isinstance(data, dict):
        data = check_points(data, dims=(3,))
        if len(data) < 4:
            raise InvalidInputError(f"data: at least 4 points are needed, got {len(data)}")
        return {"boundary": local(boundary_facets(template.cells), data)}
    groups = {}
    for name, points in data.items():
        if name not in template.tag_names or template.facets is None:
            raise InvalidInputError(f"data: {name!r} is no surface of the template; its surfaces are "
                                    f"{', '.join(sorted(template.tag_names)) or 'none (untagged)'}")
        points = check_points(points, dims=(3,))
        facets = template.facets[template.facet_tags == template.tag_names[name][0]]
        if len(points) and len(facets):
            groups[name] = local(facets, points)
    if sum(len(points) for _, _, points, _ in groups.values()) < 4:
        raise InvalidInputError("data: at least 4 points on the template's surfaces are needed")
    return groups


def local(facets: np.ndarray, data: np.ndarray) -> tuple:
    """(node indices (n,), the facets over them (f, 3), data, its cKDTree): a surface as its own triangulation."""
    nodes, inverse = np.unique(facets, return_inverse=True)
    return nodes, inverse.reshape(facets.shape), data, cKDTree(data)


def fit_template(template: Mesh, data, *, pull: float = 3.0, stages: int = 4, rounds: int = 40,
                 tolerance: float = 1e-2, rest: Mesh | None = None, carried: dict | None = None,
                 progress: ProgressCallback = None) -> TemplateFit:
    """Move a tetrahedral ``template`` onto ``data`` keeping its cells (see the module docstring).

    Parameters
    ----------
    template : Mesh of tetrahedra (its tags and cell data are kept)
    data : (n, 3) float64, points on the surface to fit (input units), n >= 4; or a mapping of the template's
        surface (facet tag) names to the points of each (EPI, LV_ENDO, ...): each surface is pulled to its own
    pull : the springs' stiffness relative to the template's at its surface (larger: closer to the data, less
        smooth, poorer cells at thin walls), > 0
    stages : the most load steps, >= 1; rounds : the most rounds a stage, >= 1; tolerance : the RMS step, in mean
        edge lengths, that ends a stage
    rest : the template at rest (the same cells): the first stage's elastic energy is measured from it (moved
        by the similarity), and the stiffening keeps its cells' shapes; a cycle fits each frame from the last with
        the first frame's template at rest, so that errors do not add up over the frames; default ``template``
    carried : a mapping of surface names to more points (k, 3) derived from the data rather than measured (the wall
        guide points below a heart's base carried onto it): they pull in the elastic stages, not the similarity
        (points placed by a rule, not sampled round the shape, would bias its scale), and are not in the distances
    progress : callable(fraction, message), optional

    Returns
    -------
    TemplateFit; raises MeshingError when more than FAR_SHARE of the data lie farther than a mean edge from the
    fitted boundary
    """
    start = time.perf_counter()
    if template.dim != 3:
        raise InvalidInputError(f"template: a tetrahedral mesh is needed, got a {template.dim}D mesh")
    measured = surface_groups(template, data)
    groups = measured if not carried else surface_groups(template, _with(data, carried))
    pull = FitParameters(pull=pull).pull
    rounds = int(check_number(rounds, "rounds", low=1, high=10000))
    stages = int(check_number(stages, "stages", low=1, high=100))
    cells = template.cells
    scale, rotation, shift = align(template.points, list(measured.values()))
    points = scale * template.points @ rotation.T + shift
    reference = points if rest is None else scale * rest.points @ rotation.T + shift
    edge = mean_edge_length(points, cells)
    original = inverse_mean_ratio(reference, cells)
    pattern = Pattern.of(cells, len(points), 3)   # the stiffness's layout, the same in every stage
    done = 0
    for stage in range(stages):
        report(progress, stage / stages, f"elastic stage {stage + 1}")
        start_points = points
        points, taken = elastic_stage(points, reference, cells, pattern, list(groups.values()),
                                      list(measured.values()), pull, original, rounds, tolerance * edge)
        reference = points
        done += taken
        if np.sqrt(np.mean((points - start_points) ** 2)) < STAGE_END * edge:
            break
    cell_data = dict(template.cell_data)
    cell_data.update(carried_fibres(template.points, points, cells, cell_data))
    cell_data.update({name: values for name, values in cell_quality(Mesh(points, cells)).items() if name in cell_data})
    moved = Mesh(points, cells, cell_data, template.facets, template.facet_tags, dict(template.tag_names),
                 dict(template.point_data), template.unit)   # node i stays the same material point: its data stay
    corners, edge = points[boundary_facets(cells)], mean_edge_length(points, cells)
    distances = distances_to_facets(np.vstack([data for _, _, data, _ in measured.values()]), corners)
    check_follows(distances, edge, pull, {name: len(data) for name, (_, _, data, _) in measured.items()})
    if "boundary" in measured:
        check_covered(corners, *measured["boundary"][2:], edge)
    report(progress, 1.0, "fitted")
    return TemplateFit(moved, (scale, rotation, shift), done, distances, time.perf_counter() - start)


def _with(data, carried: dict) -> dict:
    """The data mapping (surface name -> points) with the ``carried`` points added to their surfaces."""
    if not isinstance(data, dict):
        raise InvalidInputError("carried: points carried onto named surfaces need data given per surface (a mapping)")
    return {name: np.vstack([points for points in (data.get(name), carried.get(name)) if points is not None])
            for name in {**data, **carried}}


def check_follows(distances: np.ndarray, edge: float, pull: float, sizes: dict) -> None:
    """Refuse a fit that leaves more than :data:`FAR_SHARE` of the data (distances (n,), of the surfaces and their
    numbers of points ``sizes`` in order) farther than ``edge``, naming the surface most of them belong to."""
    beyond = distances > edge
    far = float(np.mean(beyond))
    if far > FAR_SHARE:
        counts = {name: int(part.sum()) for name, part in zip(sizes, np.split(beyond, np.cumsum(list(sizes.values()))))}
        worst = max(counts, key=counts.get)
        raise MeshingError(
            f"the fitted template does not follow the data: {100 * far:.1f}% of the data points lie farther than a "
            f"mean edge ({edge:.3g}) from its boundary (allowed {100 * FAR_SHARE:g}%; the farthest "
            f"{distances.max():.3g}; most on {worst}: {counts[worst]} of its {sizes[worst]}); the data may sample "
            f"another shape than the template's (other parts, another "
            f"topology, points of another surface), or be labelled for other surfaces; if they are the template's "
            f"shape far deformed (end-systole from an end-diastolic template: the cells' quality floor holds it "
            f"back), fit through the data between, each from the last (bitemesh fit TEMPLATE FIRST ... LAST, "
            f"bitemesh.fit_cycle); or raise pull (now {pull:g}, allowed (0, inf]) so that the surfaces follow "
            f"them closer")


def check_covered(corners: np.ndarray, data: np.ndarray, tree: cKDTree, edge: float) -> None:
    """Refuse a fit to points that sample the whole boundary (``data`` (n, 3), their ``tree``) that leaves more than
    :data:`FAR_SHARE` of its boundary's area (facets ``corners`` (f, 3, 3)) farther than ``edge`` plus twice the
    data's spacing (:func:`~bitemesh.core.implicit.samples.sample_spacing`, as the mesher's fidelity allows) from
    every point: it wraps a shape that is not the data's (one ball stretched round two spheres lies near all of
    their points)."""
    spacing = sample_spacing(data)
    area = facet_measures(corners)
    bare = tree.query(corners.mean(axis=1))[0] > edge + 2 * spacing
    share = float(area[bare].sum() / area.sum())
    if share > FAR_SHARE:
        raise MeshingError(
            f"the fitted template does not take the data's shape: {100 * share:.1f}% of its boundary's area lies "
            f"farther than {edge + 2 * spacing:.3g} (a mean edge and twice the data's spacing) from every data point "
            f"(allowed {100 * FAR_SHARE:g}%); the data may sample another shape than the template's (other parts, "
            f"another topology) or only part of its boundary: give the points of each surface by its tag name "
            f"(bitemesh.fit with a mapping, or labelled guide points), or mesh the data itself (bitemesh mesh)")


def elastic_stage(points: np.ndarray, reference: np.ndarray, cells: np.ndarray, pattern: Pattern, groups: list,
                  measured: list, pull: float, original: np.ndarray, rounds: int, step_bound: float):
    """(points, rounds run): one load step from ``points``, the paper's K U = F with K the elasticity of
    ``reference`` (the template at rest, or the stage's start; assembled by ``pattern``, the cells' 3-dof
    :class:`~bitemesh.core.fem.assembly.Pattern`) and F the springs to the data (``groups``), the
    correspondences recomputed each round until the RMS step is below ``step_bound`` or a round brings the
    ``measured`` data (their groups, without the carried points) closer by less than :data:`ROUND_GAIN` (the mean
    distance to the facets: the median distance to the nearest node, which has a floor, let last bits decide between
    2 rounds and 6 on an end-systolic frame); a cell whose
    inverse mean ratio exceeds its ``original`` (m,) stiffens (:data:`STIFFENING`)."""
    gradients, volumes = basis_gradients(reference, cells)
    elements = elasticity_elements(gradients, volumes)
    squeeze = np.maximum(inverse_mean_ratio(points, cells) / original, 1.0) ** STIFFENING
    stiffness = pattern.assemble(elements * squeeze[:, None, None])
    surfaces = np.unique(np.concatenate([nodes for nodes, _, _, _ in groups]))
    weight = pull * float(pattern.assemble(elements).diagonal().reshape(-1, 3)[surfaces].mean())
    edge = mean_edge_length(points, cells)
    total = (points - reference).ravel()
    done, closeness = 0, np.inf
    while done < rounds:
        previous, closeness = closeness, mean_gap(points, measured)
        if closeness > previous - ROUND_GAIN * edge:
            break
        done += 1
        reach = max(REACH * median_gap(points, measured), 2 * edge)
        pulls, force = springs(points, groups, reach, weight)
        system = (stiffness + pulls).tocsr()
        total = total + solve(system, force + pulls @ total - system @ total, rtol=1e-6).solution
        moved = damped_step(points, cells, reference + total.reshape(-1, 3) - points)
        step, points = moved - points, moved
        total = (points - reference).ravel()
        if np.sqrt(np.mean(step ** 2)) < step_bound:
            break
        squeeze = np.maximum(inverse_mean_ratio(points, cells) / original, 1.0) ** STIFFENING
        stiffness = pattern.assemble(elements * squeeze[:, None, None])
    return points, done


def carried_fibres(before: np.ndarray, after: np.ndarray, cells: np.ndarray, cell_data: dict) -> dict:
    """The cell arrays Fibre, Sheet, SheetNormal ((m, 3) unit vectors) of the cells on ``before`` (n, 3), carried to
    ``after``: f' = F f / |F f|, s' the part of F s across f', made unit, n' = f' x s' (F = d after / d before, the
    cell's deformation gradient).  Empty without a Fibre array."""
    if "Fibre" not in cell_data or "Sheet" not in cell_data:
        return {}
    gradients, _ = basis_gradients(before, cells)
    deformation = np.einsum("mai,maj->mij", after[cells], gradients)        # F_ij = sum_a x_a,i d_j lambda_a
    fibre = np.einsum("mij,mj->mi", deformation, cell_data["Fibre"])
    fibre /= np.linalg.norm(fibre, axis=1, keepdims=True)
    sheet = np.einsum("mij,mj->mi", deformation, cell_data["Sheet"])
    sheet -= np.einsum("mi,mi->m", sheet, fibre)[:, None] * fibre
    sheet /= np.linalg.norm(sheet, axis=1, keepdims=True)
    return {"Fibre": fibre, "Sheet": sheet, "SheetNormal": np.cross(fibre, sheet)}


def damped_step(points: np.ndarray, cells: np.ndarray, step: np.ndarray) -> np.ndarray:
    """``points`` moved by ``step`` (n, 3), damped where a cell would suffer: the nodes of every cell that the move
    would invert, shrink below :data:`SHRINK` of its volume, take below the lesser of its smallest dihedral angle
    before the move and :data:`ANGLE_FLOOR`, or below the lesser of its radius ratio and :data:`RATIO_FLOOR` take
    half their step, again and again (:data:`HALVINGS` times, then
    none), so that the rest of the mesh moves in full."""
    volumes = signed_measures(points, cells)
    floor = np.minimum(smallest_angles(points, cells), ANGLE_FLOOR)
    ratio_floor = np.minimum(radius_ratio(points, cells), RATIO_FLOOR)
    fraction = np.ones(len(points))
    suffer, check = np.zeros(len(cells), bool), np.arange(len(cells))   # check: the cells a halving moved
    for halving in range(HALVINGS + len(points)):
        moved = points + fraction[:, None] * step
        some = cells[check]
        suffer[check] = (signed_measures(moved, some) <= SHRINK * volumes[check]) \
            | (smallest_angles(moved, some) < floor[check]) | (radius_ratio(moved, some) < ratio_floor[check])
        if not suffer.any():
            return moved
        halved = np.zeros(len(points), bool)
        halved[cells[suffer]] = True
        fraction[halved] = 0.5 * fraction[halved] if halving < HALVINGS else 0.0
        check = np.flatnonzero(halved[cells].any(axis=1))
    return points
