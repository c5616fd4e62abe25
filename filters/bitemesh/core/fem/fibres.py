"""Myocardial fibres of a biventricular mesh by the Laplace-Dirichlet rule-based method of Bayer, Blake, Plank and
Trayanova (2012, Ann. Biomed. Eng. 40: 2243-2254): fibre, sheet and sheet-normal directions per cell.

The steps of the paper, on the P1 elements of :mod:`bitemesh.core.fem.assembly`:

1. Four Laplace problems on the mesh, whose boundary is tagged EPI, LV_ENDO, RV_ENDO and BASE (facet tags; a left
   ventricle, tagged EPI, ENDO and BASE, has no RV problem: phi_rv = 0, d = 0, Q_endo = Q_lv):
   psi (apex to base): 0 at the apex node, 1 on BASE; phi_epi, phi_lv, phi_rv (transmural): 1 on their own surface
   (EPI, LV_ENDO, RV_ENDO), 0 on the other two.  Every other boundary is natural (zero flux): BASE for the
   transmural problems, all but BASE and the apex for psi.  The apex is the EPI node farthest below the base plane
   (the BASE triangles' area-weighted centroid and mean normal): the LV apex, which lies below the RV's in a heart.
   A node on two of EPI, LV_ENDO, RV_ENDO (a wall one cell thick) belongs to the later one in that order, so that
   phi_epi + phi_lv + phi_rv = 1 holds at the nodes, as in the continuous problem.
2. Per cell: the scalars at its centroid (the mean of its nodes' values) and the gradients recovered at the nodes
   (the volume-weighted mean of the P1 gradients of the cells around each node, a lumped L2 projection), averaged
   over its four nodes.  Recovered gradients are smooth and nowhere zero, also in a cell whose four nodes lie on
   one surface.
3. The rule, per cell, with d = phi_rv / (phi_lv + phi_rv) (0.5 where both vanish), angles in degrees:
   alpha_s = alpha_endo (1 - 2 d), beta_s = beta_endo (1 - 2 d) in the septum, alpha_w = alpha_endo (1 - phi_epi)
   + alpha_epi phi_epi and beta_w likewise in the walls; the frames Q_lv = orient(axis(grad psi, -grad phi_lv),
   alpha_s, beta_s), Q_rv = orient(axis(grad psi, grad phi_rv), alpha_s, beta_s), Q_epi = orient(axis(grad psi,
   grad phi_epi), alpha_w, beta_w); Q_endo = bislerp(Q_lv, Q_rv, d), Q = bislerp(Q_endo, Q_epi, phi_epi).  Its
   columns are the fibre, the sheet and the sheet normal.

``axis(u, v)`` is the orthonormal frame (e_C, e_L, e_T) of the circumferential, longitudinal (u, apex to base)
and transmural (v made orthogonal to u) directions, e_C = e_L x e_T: counter-clockwise seen from the base when e_T
points out of the wall.  ``orient(Q, alpha, beta)`` turns the frame by alpha about e_T (the fibre from e_C towards
e_L: alpha is the helix angle), then by beta about the fibre (the sheet from e_L towards -e_T).  ``bislerp(A, B,
t)`` is the spherical interpolation of the rotations' unit quaternions from the quaternion of A, or of A turned by
half a turn about one of its axes (the same fibre line), whichever is nearest to B's; unlike Bayer's, the
quaternion is normalised after the linear interpolation that replaces slerp for nearly equal rotations, so that
every frame is orthonormal to round-off.

Across a free wall (d = 0) the helix angle then falls monotonically from alpha_endo at the endocardium to alpha_epi
at the epicardium, but not linearly: it is about alpha_endo + phi_epi^2 (alpha_epi - alpha_endo) (the two
interpolations compound) until Q_endo and Q_epi are about a quarter turn apart; there bislerp's nearest quaternion
goes the other way round and the fibre jumps to about alpha_epi (the paper's angles: from -30 to -50 degrees at
phi_epi = 0.9; 60 and -60: from -7 to -53 at 0.77).  On the way the fibre leaves the wall's tangent plane by up to
8 degrees (the sheet's turn by beta mixes in).  Both are the method's, as published and as the ldrb package
(finsberg/ldrb) has it.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from . import assembly as fem
from ..errors import BitemeshWarning, InvalidInputError
from ..mesh.simplicial import Mesh
from ..parameters import Parameters, parameter
from ..progress import ProgressCallback, report

#: the facet tags the method needs, by name (the names of
# :func:`bitemesh.core.sources.contours.function.boundary_surfaces`).
SURFACES = ("EPI", "LV_ENDO", "RV_ENDO", "BASE")
#: a wall is "one cell thick" where more than this share of the cells on its endocardium reach the epicardium.
ONE_CELL = 0.5
#: the cell arrays :func:`with_fibres` adds: unit vectors (m, 3), and the helix angle (m,) in degrees.
FIBRE_ARRAYS = ("Fibre", "Sheet", "SheetNormal", "HelixAngle")
#: the point arrays of the four Laplace solutions psi, phi_epi, phi_lv, phi_rv (no unit, 0 to 1).
LAPLACE_ARRAYS = ("Psi", "PhiEpi", "PhiLV", "PhiRV")


@dataclass(frozen=True)
class FibreParameters(Parameters):
    """FibreField: rule-based fibre, sheet and sheet-normal directions of a biventricular mesh (Bayer et al. 2012).

    ``fibres`` is the switch of the command line (``--fibres``); the FibreField filter always runs and has only the
    angles.  The defaults are the paper's.
    """

    fibres: int = parameter(0, "1 adds the rule-based myocardial fibres (Bayer et al. 2012) as the cell vectors "
                            "Fibre, Sheet and SheetNormal and the cell scalar HelixAngle (.vtu, .vtk and .xdmf keep "
                            "them, .pts Fibre and Sheet; .msh, .inp and .mesh cannot); needs a heart mesh whose "
                            "boundary is tagged EPI, LV_ENDO, RV_ENDO and BASE (or EPI, ENDO and BASE: a left "
                            "ventricle); 0 adds none", low=0, high=1, integer=True)
    alpha_endo: float = parameter(40.0, "the fibres' helix angle on the endocardia (against the circumferential "
                                  "direction, towards the base)", unit="degrees", low=-90, high=90)
    alpha_epi: float = parameter(-50.0, "the fibres' helix angle on the epicardium", unit="degrees", low=-90,
                                 high=90)
    beta_endo: float = parameter(-65.0, "the sheets' angle about the fibre on the endocardia", unit="degrees",
                                 low=-90, high=90)
    beta_epi: float = parameter(25.0, "the sheets' angle about the fibre on the epicardium", unit="degrees",
                                low=-90, high=90)


@dataclass(frozen=True, eq=False)
class Fibres:
    """The fibre field of a mesh (m cells, n nodes).

    Attributes
    ----------
    fibre, sheet, sheet_normal : (m, 3) float64, unit and mutually orthogonal, a right-handed frame per cell
    helix_angle : (m,) float64, degrees in [-90, 90]: the fibre's angle against the circumferential direction
        e_L x e_T in the plane normal to e_T = grad phi_epi, towards e_L = grad psi: the helix angle of the free
        walls (in the septum grad phi_epi runs along the wall, and the angle is not a helix angle)
    laplace : name -> (n,) float64, the nodal solutions, named as :data:`LAPLACE_ARRAYS`
    apex : int, the node where psi = 0
    solves : the four :class:`~bitemesh.core.fem.assembly.Solve` (psi, phi_epi, phi_lv, phi_rv)
    seconds : float, wall-clock seconds of the whole computation
    """

    fibre: np.ndarray
    sheet: np.ndarray
    sheet_normal: np.ndarray
    helix_angle: np.ndarray
    laplace: dict
    apex: int
    solves: tuple
    seconds: float


def surface_facets(mesh: Mesh, what: str = "fibres") -> dict:
    """The tagged boundary triangles of each of :data:`SURFACES`: name -> (b, 3) int64.  An LV-only mesh (EPI, ENDO
    and BASE, as cardiac-geometries tags an LV) gives ENDO as LV_ENDO and no RV_ENDO triangle.

    Raises :class:`InvalidInputError` naming the surfaces the mesh lacks (no facet tag of that name, or no facet
    with its tag), and ``what`` needs them.
    """
    if mesh.dim != 3:
        raise InvalidInputError(f"{what} need a tetrahedral mesh; this mesh is {mesh.dim}D")
    tags = {name: tag for name, (tag, dimension) in mesh.tag_names.items() if dimension == 2}
    left_ventricle = "ENDO" in tags and "LV_ENDO" not in tags and "RV_ENDO" not in tags
    source = {"LV_ENDO": "ENDO"} if left_ventricle else {}
    facets = {}
    if mesh.facets is not None:
        facets = {name: mesh.facets[mesh.facet_tags == tags[source.get(name, name)]] for name in SURFACES
                  if source.get(name, name) in tags}
    needed = ("EPI", "LV_ENDO", "BASE") if left_ventricle else SURFACES
    missing = [source.get(name, name) for name in needed if len(facets.get(name, ())) == 0]
    if missing:
        present = ", ".join(sorted(tags)) if tags else "none"
        raise InvalidInputError(
            f"{what} need the boundary surfaces {', '.join(SURFACES)} (a biventricular heart) or EPI, ENDO and BASE "
            f"(a left ventricle) tagged on the mesh, and it has no {', '.join(missing)} (its facet tags: "
            f"{present}); mesh labelled heart contours (a biv-me GPFile), whose mesh carries these tags")
    facets.setdefault("RV_ENDO", np.zeros((0, 3), np.int64))
    return facets


def thin_walls(mesh: Mesh) -> dict:
    """Endocardium name -> the share (0 to 1) of the cells with a face on it that also reach the epicardium (a node
    on EPI and not on that endocardium): where the share is large the wall is one cell thick, and fibres and
    coordinates across it have one value."""
    facets = surface_facets(mesh)
    epi = np.zeros(len(mesh.points), bool)
    epi[facets["EPI"].ravel()] = True
    shares = {}
    for name in ("LV_ENDO", "RV_ENDO"):
        if not len(facets[name]):
            continue
        endo = np.zeros(len(mesh.points), bool)
        endo[facets[name].ravel()] = True
        on_it = endo[mesh.cells].sum(axis=1) >= 3
        across = (epi & ~endo)[mesh.cells].any(axis=1)
        shares["ENDO" if "ENDO" in mesh.tag_names else name] = float(across[on_it].mean())
    return shares


def warn_thin_walls(mesh: Mesh, radius: float, asked: str, hint: float) -> None:
    """A :class:`BitemeshWarning` for each wall more than :data:`ONE_CELL` of whose endocardial cells reach the
    epicardium (:func:`thin_walls`); ``asked`` names the option (``--fibres``), ``hint`` the radius that puts about
    two cells across it."""
    for name, share in thin_walls(mesh).items():
        if share > ONE_CELL:
            warnings.warn(f"{asked}: the wall under {name} is about one cell thick ({100 * share:.0f}% of the cells on "
                          f"{name} reach the epicardium, at R = {radius:.3g}): the fibres and coordinates across it "
                          "take one value where they turn from endocardium to epicardium (rule-based fibres by 90 "
                          f"degrees). For two cells across it, mesh with --radius {hint:.3g} (about "
                          f"{(radius / hint) ** 3:.0f}x the cells)", BitemeshWarning, stacklevel=2)


def lowest_node(points: np.ndarray, nodes: np.ndarray, base: np.ndarray) -> int:
    """The one of ``nodes`` farthest below the plane of the BASE triangles ``base`` (b, 3): an apex."""
    centre, normal = base_plane(points, base)
    return int(nodes[np.argmax((centre - points[nodes]) @ normal)])


def base_plane(points: np.ndarray, base: np.ndarray):
    """The plane of the base: the area-weighted centroid (3,) of the BASE triangles (b, 3) and their mean unit
    normal (3,), turned to point away from the rest of the mesh (away from the apex)."""
    corners = points[base]
    doubled = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])   # 2 x area x normal
    areas = np.linalg.norm(doubled, axis=1)
    centre = (areas @ corners.mean(axis=1)) / areas.sum()
    normal = doubled.sum(axis=0)
    normal /= np.linalg.norm(normal)
    return centre, normal if (points.mean(axis=0) - centre) @ normal < 0 else -normal


def laplace_solutions(points: np.ndarray, cells: np.ndarray, facets: dict, gradients: np.ndarray,
                      volumes: np.ndarray, progress: ProgressCallback = None):
    """Step 1: the four Laplace problems (see the module's docstring; three in a left ventricle, phi_rv = 0), by
    Jacobi-CG to a relative residual of 1e-10.

    Returns
    -------
    solutions : (4, n) float64, psi, phi_epi, phi_lv, phi_rv at the nodes (no unit, in [0, 1])
    apex : int, the node where psi = 0
    solves : tuple of four (three) :class:`~bitemesh.core.fem.assembly.Solve`
    """
    n = len(points)
    matrix = fem.assemble(fem.laplace_elements(gradients, volumes), cells, n)
    owner = np.full(n, -1)
    for number, name in enumerate(SURFACES[:3]):          # EPI, then LV_ENDO, then RV_ENDO win a shared node
        owner[facets[name].ravel()] = number
    apex = lowest_node(points, np.flatnonzero(owner == 0), facets["BASE"])
    on_base = np.zeros(n, dtype=bool)
    on_base[facets["BASE"].ravel()] = True
    problems = [(on_base | (np.arange(n) == apex), on_base.astype(np.float64))]
    problems += [(owner >= 0, (owner == number).astype(np.float64)) for number in range(3 if len(facets["RV_ENDO"])
                                                                                       else 2)]
    solutions, solves = np.zeros((4, n)), []   # phi_rv = 0 in a left ventricle
    for number, (fixed, values) in enumerate(problems):
        solutions[number], solve = fem.harmonic(matrix, fixed, values)
        solves.append(solve)
        report(progress, 0.2 * (number + 1), f"fibres: Laplace problem {number + 1} of {len(problems)}")
    return solutions, apex, tuple(solves)


def recovered_gradients(cells: np.ndarray, gradients: np.ndarray, volumes: np.ndarray,
                        nodal: np.ndarray) -> np.ndarray:
    """Step 2: the gradients of nodal fields (k, n) recovered at the nodes and averaged over each cell: (k, m, 3),
    units of the field per input unit."""
    per_cell = np.einsum("mai,kma->kmi", gradients, nodal[:, cells])          # (k, m, 3), exact P1 gradients
    m, n = len(cells), nodal.shape[1]
    weights = sparse.csr_matrix((np.repeat(volumes, 4), (cells.ravel(), np.repeat(np.arange(m), 4))), shape=(n, m))
    at_nodes = np.stack([weights @ field for field in per_cell]) / (weights @ np.ones(m))[None, :, None]
    return at_nodes[:, cells].mean(axis=2)


def fibre_field(mesh: Mesh, parameters: FibreParameters = FibreParameters(),
                progress: ProgressCallback = None) -> Fibres:
    """The rule-based fibres of a biventricular (or left-ventricular) tetrahedral mesh (the module's docstring).

    Parameters
    ----------
    mesh : Mesh, tetrahedra (m, 4) on points (n, 3), input units (mm), with the facet tags :data:`SURFACES`
    parameters : the angles (degrees); its ``fibres`` switch is not read here
    progress : callable(fraction, message), optional; raising :class:`~bitemesh.core.errors.Cancelled` stops

    Returns
    -------
    Fibres; the same mesh gives the same fibres, bit for bit.
    """
    start = time.perf_counter()
    facets = surface_facets(mesh)
    points, cells = np.asarray(mesh.points, dtype=np.float64), np.asarray(mesh.cells, dtype=np.int64)
    gradients, volumes = fem.basis_gradients(points, cells)
    solutions, apex, solves = laplace_solutions(points, cells, facets, gradients, volumes, progress)
    grad_psi, grad_epi, grad_lv, grad_rv = recovered_gradients(cells, gradients, volumes, solutions)
    phi_epi, phi_lv, phi_rv = np.clip(solutions[1:, cells].mean(axis=2), 0.0, 1.0)
    endo = phi_lv + phi_rv
    right_ventricle = len(facets["RV_ENDO"]) > 0
    d = np.divide(phi_rv, endo, out=np.full_like(endo, 0.5 if right_ventricle else 0.0), where=endo > 1e-12)
    p = parameters
    septum = (p.alpha_endo * (1 - 2 * d), p.beta_endo * (1 - 2 * d))
    wall = (p.alpha_endo + (p.alpha_epi - p.alpha_endo) * phi_epi, p.beta_endo + (p.beta_epi - p.beta_endo) * phi_epi)
    q_lv = quaternions(orient(axis(grad_psi, -grad_lv), *septum))
    q_rv = quaternions(orient(axis(grad_psi, grad_rv), *septum))
    q_epi = quaternions(orient(axis(grad_psi, grad_epi), *wall))
    q_endo = bislerp(q_lv, q_rv, d) if right_ventricle else q_lv
    fibre, sheet, sheet_normal = np.ascontiguousarray(rotations(bislerp(q_endo, q_epi, phi_epi))
                                                      .transpose(2, 0, 1))     # the columns of each frame
    report(progress, 1.0, "fibres")
    return Fibres(fibre=fibre, sheet=sheet, sheet_normal=sheet_normal,
                  helix_angle=helix_angles(fibre, axis(grad_psi, grad_epi)),
                  laplace=dict(zip(LAPLACE_ARRAYS, solutions)), apex=apex, solves=solves,
                  seconds=time.perf_counter() - start)


def with_fibres(mesh: Mesh, parameters: FibreParameters = FibreParameters(), progress: ProgressCallback = None):
    """A copy of ``mesh`` with the cell arrays :data:`FIBRE_ARRAYS` of :func:`fibre_field` and its Laplace
    solutions as the point arrays :data:`LAPLACE_ARRAYS` (as the FibreField filter gives them), and the seconds it
    took."""
    fibres = fibre_field(mesh, parameters, progress)
    return mesh.with_cell_data(Fibre=fibres.fibre, Sheet=fibres.sheet, SheetNormal=fibres.sheet_normal,
                               HelixAngle=fibres.helix_angle).with_point_data(**fibres.laplace), fibres.seconds


def helix_angles(fibre: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """(m,) degrees in [-90, 90]: the angle of each fibre line (m, 3) against the first axis e_C of its frame
    (m, 3, 3), towards the second e_L, in their plane (the fibre's sign does not count)."""
    along = np.einsum("mi,mi->m", fibre, frames[:, :, 0])
    up = np.einsum("mi,mi->m", fibre, frames[:, :, 1])
    return np.degrees(np.arctan2(np.where(along < 0, -up, up), np.abs(along)))


# --- frames and their rotations -----------------------------------------------------------------------------------

def _unit(vectors: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """(m, 3) the vectors scaled to unit length; ``fallback`` (m, 3), unit, where a vector is (nearly) zero."""
    norms = np.linalg.norm(vectors, axis=1, keepdims=True)
    small = norms < 1e-12 * max(float(norms.max(initial=0.0)), 1e-300)
    return np.where(small, fallback, vectors / np.where(small, 1.0, norms))


def axis(longitudinal: np.ndarray, transmural: np.ndarray) -> np.ndarray:
    """(m, 3, 3) the frames whose columns are e_C, e_L, e_T: e_L along ``longitudinal`` (m, 3), e_T along
    ``transmural`` (m, 3) made orthogonal to it, e_C = e_L x e_T.  Where a direction is missing (a zero vector,
    or e_T along e_L) any unit vector orthogonal to the others stands in, so that every frame is a rotation."""
    e_l = _unit(longitudinal, np.broadcast_to([0.0, 0.0, 1.0], longitudinal.shape))
    across = np.eye(3)[np.argmin(np.abs(e_l), axis=1)]          # the coordinate axis farthest from e_L
    e_t = _unit(transmural - np.einsum("mi,mi->m", e_l, transmural)[:, None] * e_l,
                _unit(np.cross(e_l, across), across))
    return np.stack([np.cross(e_l, e_t), e_l, e_t], axis=2)


def orient(frames: np.ndarray, alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """(m, 3, 3) ``frames`` (columns e_C, e_L, e_T) turned by ``alpha`` (m,) degrees about e_T, then by ``beta``
    (m,) degrees about the new first column (the fibre): Q A(alpha) B(beta) of Bayer et al."""
    ca, sa = np.cos(np.radians(alpha))[:, None], np.sin(np.radians(alpha))[:, None]
    cb, sb = np.cos(np.radians(beta))[:, None], np.sin(np.radians(beta))[:, None]
    e_c, e_l, e_t = frames[:, :, 0], frames[:, :, 1], frames[:, :, 2]
    fibre, turned = ca * e_c + sa * e_l, ca * e_l - sa * e_c
    return np.stack([fibre, cb * turned - sb * e_t, sb * turned + cb * e_t], axis=2)


def quaternions(frames: np.ndarray) -> np.ndarray:
    """(m, 4) unit quaternions (w, x, y, z) of rotation matrices (m, 3, 3), from the row of the symmetric matrix
    4 q q^T with the largest diagonal entry (Shepperd's method: never divides by less than 1)."""
    r = frames
    trace = r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2]
    wx, wy, wz = r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]
    xy, xz, yz = r[:, 0, 1] + r[:, 1, 0], r[:, 0, 2] + r[:, 2, 0], r[:, 1, 2] + r[:, 2, 1]
    outer = np.stack([np.stack([1 + trace, wx, wy, wz], axis=1),
                      np.stack([wx, 1 + 2 * r[:, 0, 0] - trace, xy, xz], axis=1),
                      np.stack([wy, xy, 1 + 2 * r[:, 1, 1] - trace, yz], axis=1),
                      np.stack([wz, xz, yz, 1 + 2 * r[:, 2, 2] - trace], axis=1)], axis=1)   # 4 q_k q_i
    row = outer[np.arange(len(r)), np.argmax(np.einsum("mkk->mk", outer), axis=1)]
    return row / np.linalg.norm(row, axis=1, keepdims=True)


def rotations(q: np.ndarray) -> np.ndarray:
    """(m, 3, 3) the rotation matrices of unit quaternions (m, 4) (w, x, y, z)."""
    w, x, y, z = q.T
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)], axis=1)


def bislerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(m, 4) Bayer's bislerp of two frames given as unit quaternions (m, 4) at ``t`` (m,) in [0, 1] (0: a's frame,
    1: b's): slerp to ``b`` from whichever of a, a i, a j, a k (a's frame turned half a turn about one of its own
    axes, which keeps each axis's line) or their negatives is nearest to it."""
    w, x, y, z = a.T
    candidates = np.stack([a, np.stack([-x, w, z, -y], axis=1), np.stack([-y, -z, w, x], axis=1),
                           np.stack([-z, y, -x, w], axis=1)], axis=1)     # a, a i, a j, a k
    dots = np.einsum("mki,mi->mk", candidates, b)
    nearest = np.argmax(np.abs(dots), axis=1)
    rows = np.arange(len(a))
    sign = np.where(dots[rows, nearest] < 0, -1.0, 1.0)
    start, cosine = sign[:, None] * candidates[rows, nearest], np.abs(dots[rows, nearest])
    angle = np.arccos(np.minimum(cosine, 1.0))
    sine = np.sin(angle)
    close = sine < 1e-6                                        # (nearly) the same rotation: interpolate linearly
    safe = np.where(close, 1.0, sine)
    weight_a = np.where(close, 1 - t, np.sin((1 - t) * angle) / safe)
    weight_b = np.where(close, t, np.sin(t * angle) / safe)
    q = weight_a[:, None] * start + weight_b[:, None] * b
    return q / np.linalg.norm(q, axis=1, keepdims=True)
