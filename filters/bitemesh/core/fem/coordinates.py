"""Ventricular coordinates of a biventricular mesh, after the universal ventricular coordinates (UVC) of Bayer et
al. (2018, Med. Image Anal. 45: 83-93), the AHA 17 segments (Cerqueira et al. 2002), and data carried from one heart
to another through them.

Everything comes from the four Laplace solutions of the fibres (:func:`~.fibres.laplace_solutions`: psi, 0 at the
apex and 1 on BASE; phi_epi, phi_lv, phi_rv, each 1 on its surface and 0 on the other two) and the LV's long axis:

- **where a node or cell lies**: the least of phi_epi, phi_lv, phi_rv.  phi_rv vanishes on both faces of the LV free
  wall, phi_lv on both faces of the RV free wall, phi_epi deep in the septum (between the two endocardia): cell
  array ``Ventricle`` 1 (LV free wall), 2 (RV free wall), 3 (septum), from the cell's mean values; a node is in the
  RV free wall when most of the volume of its cells is.
- ``ApicoBasal`` (Z): the height above the apex along the LV long axis (below), 0 at the apex and 1 at the LV's
  basal ring, above 1 where the base rises higher (the RV outflow, a tilted annulus).  UVC take psi, which is flat
  near the base (1 on all of BASE): carried through psi, nodes in the basal third landed up to 50 mm from where
  they started (the round trip below); psi is kept as ``Psi``.
- ``Transmural`` (rho): 0 on a node's own endocardium, 1 on the epicardium; the septum counts to the LV, as in UVC,
  and runs from the LV endocardium (0) to the RV's (1): 1 - phi_lv in the LV and the septum, 1 - phi_rv in the RV
  free wall.
- ``Transventricular`` (V): -1 in the LV and the septum, +1 in the RV free wall (UVC's).
- ``Rotational`` (phi): radians in (-pi, pi], the angle about the LV long axis (the apex, the EPI node farthest
  below the base, to the centre of the LV's basal ring), 0 towards the centre of the septum, +pi/2 anterior.
  Anterior is e_L x e_S (e_L the long axis, e_S towards the septum): the side of the RV outflow in a right-handed
  patient frame (LPS or RAS, as scanners and biv-me give; a mirrored mesh turns it to the posterior side).  In the
  RV free wall, UVC's own (:func:`rv_rotation`): a Laplace problem from its posterior septal junction (-pi/2) to
  its anterior one (+pi/2); the angle about the LV's axis folds there near the base, where the RV wraps round the
  LV (a ray crosses its free wall twice).
- ``AHA`` (cell array, 1-17; 0 in the RV free wall): the LV and septum cells by the height of their centroid along
  the long axis (17 below the LV cavity's tip; then the apical, mid and basal thirds up to the LV's basal ring, the
  cells above it basal) and by phi: six 60-degree sectors in the basal and mid rings (1 anterior from 60 to 120
  degrees, 2 anteroseptal, 3 inferoseptal, 4 inferior, 5 inferolateral, 6 anterolateral; 7-12 the same), four
  90-degree sectors in the apical ring (13 anterior, 14 septal centred on 0, 15 inferior, 16 lateral).

The coordinates are not UVC's to the letter: UVC's apicobasal coordinate and its rotational one in the LV come from
Laplace problems, these are geometric.  :func:`carry` maps point data between two hearts through (Z, rho, phi)
within each V.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from . import assembly as fem
from ..errors import InvalidInputError
from ..mesh.simplicial import Mesh
from ..parameters import Parameters, parameter
from .fibres import base_plane, laplace_solutions, surface_facets

#: the cell array ``Ventricle``'s values.
LV_FREE_WALL, RV_FREE_WALL, SEPTUM = 1, 2, 3
#: the point arrays :func:`ventricular_coordinates` adds (with the Laplace solutions, fibres.LAPLACE_ARRAYS).
COORDINATE_ARRAYS = ("ApicoBasal", "Transmural", "Rotational", "Transventricular")
#: the source nodes nearest in the coordinates through which :func:`carry` fits its affine map (5 unknowns).
NEIGHBOURS = 10
#: the formats that keep point arrays.
POINT_ARRAY_FORMATS = (".vtu", ".vtk", ".xdmf", ".npz", ".h5")


@dataclass(frozen=True)
class CoordinateParameters(Parameters):
    """Coordinates: the ventricular coordinates and AHA segments of a biventricular mesh (``--coordinates``)."""

    coordinates: int = parameter(0, "1 adds the ventricular coordinates (after Bayer et al. 2018) as point arrays "
                                 "ApicoBasal, Transmural, Rotational, Transventricular and the Laplace solutions "
                                 "Psi, PhiEpi, PhiLV, PhiRV (.vtu, .vtk, .xdmf, .npz and .h5 keep them), and the cell "
                                 "arrays AHA (the 17 segments, 0 in the RV free wall) and Ventricle (1 LV free "
                                 "wall, 2 RV free wall, 3 septum); needs a heart mesh tagged EPI, LV_ENDO, RV_ENDO "
                                 "and BASE; 0 adds none", low=0, high=1, integer=True)


@dataclass(frozen=True, eq=False)
class Coordinates:
    """The ventricular coordinates of a mesh (n nodes, m cells).

    Attributes
    ----------
    points : name -> (n,) float64, :data:`COORDINATE_ARRAYS` and the Laplace solutions Psi, PhiEpi, PhiLV, PhiRV
    ventricle : (m,) int32, :data:`LV_FREE_WALL`, :data:`RV_FREE_WALL` or :data:`SEPTUM`
    aha : (m,) int32, the AHA segment 1-17 of each LV and septum cell, 0 in the RV free wall
    apex : (3,) the apex; axis : (3,) the unit long axis (apex to base); septum : (3,) the unit direction from the
        axis to the septum's centre, across the axis; length : the apex's distance below the LV's basal ring
        (input units)
    """

    points: dict
    ventricle: np.ndarray
    aha: np.ndarray
    apex: np.ndarray
    axis: np.ndarray
    septum: np.ndarray
    length: float


def ventricular_coordinates(mesh: Mesh) -> Coordinates:
    """The coordinates of a biventricular tetrahedral ``mesh`` (tagged EPI, LV_ENDO, RV_ENDO and BASE; input units
    mm), as the module's docstring defines them."""
    facets = surface_facets(mesh, "coordinates")
    if not len(facets["RV_ENDO"]):
        raise InvalidInputError("coordinates: the rotational coordinate and the AHA segments are measured from the "
                                "septum, and this mesh has no RV_ENDO (a left ventricle alone); mesh both ventricles")
    points, cells = np.asarray(mesh.points, np.float64), np.asarray(mesh.cells, np.int64)
    gradients, volumes = fem.basis_gradients(points, cells)
    solutions, apex_node, _ = laplace_solutions(points, cells, facets, gradients, volumes)
    psi, phi_epi, phi_lv, phi_rv = solutions
    per_cell = solutions[1:, cells].mean(axis=2)                                   # (3, m): epi, lv, rv
    ventricle = np.array([SEPTUM, RV_FREE_WALL, LV_FREE_WALL], np.int32)[np.argmin(per_cell, axis=0)]
    # a node's side by its cells' volume (at a surface the node's own values tie: 0 and 0 on EPI, say)
    right = np.bincount(cells.ravel(), np.repeat(np.where(ventricle == RV_FREE_WALL, volumes, -volumes), 4),
                        minlength=len(points)) > 0
    apex = points[apex_node]
    centre, normal = base_plane(points, facets["BASE"])
    ring = np.intersect1d(np.unique(facets["LV_ENDO"]), np.unique(facets["BASE"]))
    axis = (points[ring].mean(axis=0) if len(ring) else centre) - apex
    length = float(np.linalg.norm(axis))
    axis /= length
    centroids = points[cells].mean(axis=1)
    septal = centroids[ventricle == SEPTUM]
    if not len(septal):
        raise InvalidInputError("coordinates: no cell lies between the two endocardia (no septum found): the mesh "
                                "may not be a biventricular myocardium")
    septum = across(septal.mean(axis=0) - apex, axis)
    septum /= np.linalg.norm(septum)
    rotational = angles(points - apex, axis, septum)
    free_wall = rv_rotation(points, cells, ventricle, gradients, volumes, facets, rotational)
    rotational = np.where(right & np.isfinite(free_wall), free_wall, rotational)
    coordinates = {"ApicoBasal": apicobasal(points, apex, points[np.unique(facets["BASE"])]),
                   "Transmural": np.where(right, 1 - phi_rv, 1 - phi_lv), "Rotational": rotational,
                   "Transventricular": np.where(right, 1.0, -1.0),
                   "Psi": psi, "PhiEpi": phi_epi, "PhiLV": phi_lv, "PhiRV": phi_rv}
    endo_tip = float(((points[np.unique(facets["LV_ENDO"])] - apex) @ axis).min())
    aha = aha_segments((centroids - apex) @ axis, angles(centroids - apex, axis, septum), endo_tip, length)
    return Coordinates(coordinates, ventricle, np.where(ventricle == RV_FREE_WALL, 0, aha).astype(np.int32), apex,
                       axis, septum, length)


def rv_rotation(points: np.ndarray, cells: np.ndarray, ventricle: np.ndarray, gradients: np.ndarray,
                volumes: np.ndarray, facets: dict, rotational: np.ndarray) -> np.ndarray:
    """(n,) the RV free wall's rotational coordinate, radians from -pi/2 at its posterior septal junction to +pi/2
    at its anterior one (nan off its cells, and everywhere when it has not two junctions): UVC's Laplace problem on
    the free wall's cells, 0 on the one junction and 1 on the other, the junctions the EPI nodes below BASE that its
    cells share with the other cells, split by the sign of their angle ``rotational`` (n,) about the LV's axis.
    About that axis, a ray beyond a junction crosses the RV free wall twice where the RV wraps round the LV near
    the base; along the free wall, from junction to junction, the two crossings lie apart.  ``cells`` (m, 4),
    ``ventricle`` (m,), ``gradients`` (m, 4, 3) and ``volumes`` (m,) of every cell; ``facets`` by surface name."""
    rotation = np.full(len(points), np.nan)
    free = ventricle == RV_FREE_WALL
    nodes, local = np.unique(cells[free], return_inverse=True)
    junction = np.zeros(len(points), bool)
    junction[np.intersect1d(np.intersect1d(facets["EPI"], nodes), cells[~free])] = True
    junction[facets["BASE"]] = False
    anterior, posterior = junction & (rotational > 0), junction & (rotational <= 0)
    if not anterior.any() or not posterior.any() or junction[nodes].all():
        return rotation
    matrix = fem.assemble(fem.laplace_elements(gradients[free], volumes[free]), local.reshape(-1, 4), len(nodes))
    between, _ = fem.harmonic(matrix, junction[nodes], anterior[nodes].astype(np.float64))
    rotation[nodes] = (between - 0.5) * np.pi
    return rotation


def apicobasal(points: np.ndarray, apex: np.ndarray, base: np.ndarray) -> np.ndarray:
    """(n,) d_apex / (d_apex + d_base) at ``points`` (n, 3): 0 at the apex, 1 on the base (its nodes ``base``),
    the distances straight (as Cobiveco's apicobasal coordinate, with geodesics there: Schuler et al. 2021)."""
    to_base, _ = cKDTree(base).query(points)
    to_apex = np.linalg.norm(points - apex, axis=1)
    return to_apex / np.maximum(to_apex + to_base, 1e-12)


def across(vectors: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """``vectors`` (..., 3) without their part along the unit ``axis``."""
    return vectors - np.multiply.outer(vectors @ axis, axis)


def angles(offsets: np.ndarray, axis: np.ndarray, septum: np.ndarray) -> np.ndarray:
    """(p,) radians in (-pi, pi]: the angle of ``offsets`` (p, 3) about ``axis``, 0 towards ``septum``, +pi/2 towards
    axis x septum (anterior)."""
    anterior = np.cross(axis, septum)
    return np.arctan2(offsets @ anterior, offsets @ septum)


def aha_segments(height: np.ndarray, angle: np.ndarray, endo_tip: float, length: float) -> np.ndarray:
    """(c,) AHA segments 1-17 of points at ``height`` along the long axis above the apex and ``angle`` (radians,
    0 septal, +pi/2 anterior); ``endo_tip`` the LV cavity's tip and ``length`` the basal ring's height."""
    third = (np.clip(height, endo_tip, length) - endo_tip) / max(length - endo_tip, 1e-12) * 3
    ring = np.minimum(third.astype(np.int64), 2)                     # 0 apical, 1 mid, 2 basal
    degrees = np.degrees(angle)
    # six sectors, counter-clockwise from the septum's centre: 2 (0, 60), 1, 6, 5, 4, 3 (-60, 0)
    six = np.array([2, 1, 6, 5, 4, 3])[(np.floor(degrees / 60).astype(np.int64)) % 6]
    four = np.array([14, 13, 16, 15])[(np.floor((degrees + 45) / 90).astype(np.int64)) % 4]
    segment = np.where(ring == 2, six, np.where(ring == 1, six + 6, four))
    return np.where(height < endo_tip, 17, segment)


def lengths(mesh: Mesh) -> np.ndarray:
    """(3,) the lengths of Z, rho and phi on ``mesh``: each the inverse of the median of its gradient's length over
    the cells (about the apex-to-base length, the wall thickness and the LV's radius, input units)."""
    gradients, _ = fem.basis_gradients(mesh.points, mesh.cells)
    slopes = [np.linalg.norm(np.einsum("mai,ma->mi", gradients, mesh.point_data[name][mesh.cells]), axis=1)
              for name in ("ApicoBasal", "Transmural", "Rotational")]
    return 1 / np.maximum([np.median(slope) for slope in slopes], 1e-12)


def embedding(mesh: Mesh, scale: np.ndarray) -> np.ndarray:
    """(n, 4) the nodes of ``mesh`` placed by their coordinates: Z and rho times ``scale`` (3,) [0] and [1], phi as
    the chord (cos phi, sin phi) times [2] (the same scale for the two hearts of :func:`carry`)."""
    z, rho, phi = (mesh.point_data[name] for name in ("ApicoBasal", "Transmural", "Rotational"))
    return np.column_stack([z * scale[0], rho * scale[1], scale[2] * np.cos(phi), scale[2] * np.sin(phi)])


def affine_weights(here: np.ndarray, there: np.ndarray):
    """(w, k) indices into ``here`` (s, d) and weights summing to 1 that give each point of ``there`` (w, d): the
    least-squares affine map through its :data:`NEIGHBOURS` nearest, weighted by 1 / distance, so that a field
    linear in the coordinates is carried exactly (a round trip between two hearts: 95 % of the nodes within one
    mean edge against 92 % with the inverse-distance blend of four); that blend where the affine map extrapolates
    (a weight below -1)."""
    distance, index = cKDTree(here).query(there, k=min(NEIGHBOURS, len(here)))
    distance, index = distance.reshape(len(there), -1), index.reshape(len(there), -1)
    closeness = 1 / np.maximum(distance, 1e-12)
    design = np.concatenate([np.ones((*index.shape, 1)), here[index] - there[:, None, :]], axis=2)
    weights = np.linalg.pinv(design * closeness[..., None], rcond=1e-6)[:, 0, :] * closeness
    extrapolated = weights.min(axis=1) < -1.0
    weights[extrapolated] = (closeness / closeness.sum(axis=1, keepdims=True))[extrapolated]
    return index, weights


def carry(source: Mesh, target: Mesh, names=None) -> dict:
    """The point arrays ``names`` (default: every one but the coordinates) of ``source`` carried to the nodes of
    ``target`` through their ventricular coordinates (both meshes carry them as point data, from
    :func:`with_coordinates`): each target node takes the :func:`affine_weights` of the source nodes nearest to it
    in (Z, rho, phi) among those of its own V, Z, rho and phi scaled to lengths by the two hearts' mean
    :func:`lengths`.  Returns name -> (n_target, ...) arrays.  Carry ``Position`` (the source's node coordinates)
    to map positions."""
    for mesh, which in ((source, "source"), (target, "target")):
        missing = [name for name in COORDINATE_ARRAYS if name not in mesh.point_data]
        if missing:
            raise InvalidInputError(f"carry: the {which} mesh has no {', '.join(missing)}; add the coordinates "
                                    "first (with_coordinates, bitemesh mesh --coordinates)")
    arrays = {"Position": source.points, **source.point_data}
    names = [name for name in arrays if name not in COORDINATE_ARRAYS] if names is None else list(names)
    unknown = [name for name in names if name not in arrays]
    if unknown:
        raise InvalidInputError(f"carry: the source mesh has no point array {unknown[0]!r} (it has "
                                f"{', '.join(arrays)})")
    scale = (lengths(source) + lengths(target)) / 2
    here, there = embedding(source, scale), embedding(target, scale)
    carried = {name: np.zeros((len(target.points), *np.shape(arrays[name])[1:])) for name in names}
    for side in (-1.0, 1.0):
        chosen = np.flatnonzero(source.point_data["Transventricular"] == side)
        wanted = np.flatnonzero(target.point_data["Transventricular"] == side)
        if not len(wanted):
            continue
        if not len(chosen):
            raise InvalidInputError(f"carry: the source mesh has no node of V = {side:+g} for the target's")
        index, weights = affine_weights(here[chosen], there[wanted])
        for name in names:
            values = np.asarray(arrays[name], np.float64)[chosen][index]        # (w, k, ...)
            carried[name][wanted] = np.einsum("wk,wk...->w...", weights, values)
    return carried


def with_coordinates(mesh: Mesh) -> Mesh:
    """A copy of ``mesh`` with the point arrays of :func:`ventricular_coordinates` and the cell arrays Ventricle and
    AHA."""
    found = ventricular_coordinates(mesh)
    return mesh.with_point_data(**found.points).with_cell_data(Ventricle=found.ventricle, AHA=found.aha)
