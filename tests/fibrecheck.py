"""The fibre tests' heart mesh (the two-cavity shell, tagged by surface) and what they measure on heart meshes: the
cells along wall-normal lines across the LV free wall, and the helix angle of their fibres in a frame of the
geometry (the line, the LV's long axis), not in the frame of the Laplace solutions under test."""
from __future__ import annotations

from functools import cache

import numpy as np
from bitemesh.core.fem import assembly as fem, fibres
from bitemesh.core.sources.contours.run import run_labelled
from bitemesh.core.mesh.simplicial import Mesh
from bitemesh.core.parameters import BitingParameters
from scipy.spatial import cKDTree

from tests.builders import SHELL_DOMAIN, sample_shell

#: the unit length and mutual orthogonality asked of every frame (they are rotations to round-off, ~1e-15)
ROUND_OFF = 1e-6


def check_frames(fibre, sheet, normal):
    """(m, 3) each: unit, orthogonal, right-handed frames."""
    for vectors in (fibre, sheet, normal):
        assert np.abs(np.linalg.norm(vectors, axis=1) - 1).max() < ROUND_OFF
    for a, b in ((fibre, sheet), (fibre, normal), (sheet, normal)):
        assert np.abs(np.einsum("mi,mi->m", a, b)).max() < ROUND_OFF
    assert np.allclose(np.cross(fibre, sheet), normal, atol=ROUND_OFF)   # right-handed


@cache
def tagged_shell() -> Mesh:
    """The two-cavity shell from its sparse contours cut at z = 0, about 3,000 cells (the default, optimised), its
    boundary tagged EPI, LV_ENDO, RV_ENDO and BASE: the LV free wall (15 mm) is two to three cells thick.  Built
    once; the tests only read it."""
    points, labels, slices = sample_shell()
    return run_labelled(points, labels, domain=SHELL_DOMAIN, base_plane=((0.0, 0, 0), (0, 0, 1.0)), slices=slices,
                        biting=BitingParameters(cells=4000)).mesh


def tagged_nodes(mesh, name) -> np.ndarray:
    return np.unique(tagged_facets(mesh, name))


def tagged_facets(mesh, name) -> np.ndarray:
    return mesh.facets[mesh.facet_tags == mesh.tag_names[name][0]]


def doubled_normals(points, facets) -> np.ndarray:
    """(b, 3) 2 x area x unit normal of the triangles (b, 3)."""
    corners = points[facets]
    return np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])


def containing_cells(mesh, points, candidates=48) -> np.ndarray:
    """(p,) a tetrahedron holding each point (p, 3), -1 for a point outside the mesh."""
    corners = mesh.points[mesh.cells]
    _, near = cKDTree(corners.mean(axis=1)).query(points, k=candidates)
    edges = (corners[:, 1:] - corners[:, :1]).transpose(0, 2, 1)
    local = np.linalg.solve(edges[near], (points[:, None, :] - corners[near, 0])[..., None])[..., 0]
    inside = (local >= -1e-12).all(axis=2) & (local.sum(axis=2) <= 1 + 1e-12)
    return np.where(inside.any(axis=1), near[np.arange(len(points)), np.argmax(inside, axis=1)], -1)


def lv_endocardium(mesh) -> str:
    """The LV endocardium's tag name: LV_ENDO, or ENDO in a left ventricle (cardiac-geometries' name)."""
    return "LV_ENDO" if "LV_ENDO" in mesh.tag_names else "ENDO"


def long_axis(mesh):
    """The apex (the EPI node farthest below the plane of the BASE triangles) and the unit LV long axis (3,) from
    it to the centre of the LV's basal ring (the LV endocardium's nodes on BASE); also the apex's depth below the
    base."""
    points, base = mesh.points, tagged_facets(mesh, "BASE")
    normal = doubled_normals(points, base).sum(axis=0)
    normal /= np.linalg.norm(normal)
    epi = tagged_nodes(mesh, "EPI")
    depth = (points[base].mean(axis=(0, 1)) - points[epi]) @ normal
    apex = points[epi[np.argmax(depth)]]
    axis = points[np.intersect1d(tagged_nodes(mesh, lv_endocardium(mesh)), np.unique(base))].mean(axis=0) - apex
    return apex, axis / np.linalg.norm(axis)


def free_wall_lines(mesh, lines=6, heights=(0.3, 0.65), facing=0.9, smoothing=10.0, step=0.05, reach=100.0):
    """Wall-normal lines across the LV free wall, from the LV endocardium to where they leave the mesh.

    The lines start at LV_ENDO triangles between ``heights`` (fractions of the way from the apex to the base along
    the long axis) whose smoothed normal into the wall (the mean over the LV_ENDO triangles within ``smoothing``
    mm) points away from the RV (cosine > ``facing`` with the direction from the RV cavity's nodes' centre to the
    LV's, across the long axis; in a left ventricle every direction), ``lines`` of them evenly spread in height;
    each is sampled every ``step`` mm up
    to ``reach`` mm (finely: a line that leaves the mesh near a node crosses the last cell, the one on the surface,
    for a short way only).

    Returns
    -------
    lines : list of (cells, direction, exit): the cells crossed in order (each once), the unit direction (3,),
        and the name of the surface nearest to where the line leaves the mesh
    axis : (3,) the unit LV long axis
    """
    points = mesh.points
    apex, axis = long_axis(mesh)
    lv = points[tagged_nodes(mesh, lv_endocardium(mesh))]
    endo = tagged_facets(mesh, lv_endocardium(mesh))
    centroids, weighted = points[endo].mean(axis=1), -doubled_normals(points, endo)    # into the wall
    inward = np.stack([weighted[near].sum(axis=0) for near in cKDTree(centroids).query_ball_point(centroids,
                                                                                                   smoothing)])
    inward /= np.linalg.norm(inward, axis=1, keepdims=True)
    height = (centroids - apex) @ axis / ((lv - apex) @ axis).max()
    free = np.ones(len(endo), dtype=bool)
    if "RV_ENDO" in mesh.tag_names:
        away = lv.mean(axis=0) - points[tagged_nodes(mesh, "RV_ENDO")].mean(axis=0)
        away -= (away @ axis) * axis
        free = inward @ (away / np.linalg.norm(away)) > facing
    chosen = np.flatnonzero(free & (height > heights[0]) & (height < heights[1]))
    chosen = chosen[np.argsort(height[chosen], kind="stable")]
    chosen = chosen[np.linspace(0, len(chosen) - 1, lines).round().astype(int)]
    surfaces = {name: cKDTree(points[tagged_nodes(mesh, name)]) for name in ("EPI", "RV_ENDO", "BASE")
                if name in mesh.tag_names}
    found = []
    for facet in chosen:
        samples = centroids[facet] + np.arange(1, round(reach / step))[:, None] * step * inward[facet]
        cells = containing_cells(mesh, samples)
        inside = np.flatnonzero(cells >= 0)
        last = inside[np.argmax(np.diff(np.append(inside, -5)) != 1)]    # the end of the first run inside
        crossed = cells[inside[0]:last + 1]
        _, first = np.unique(crossed, return_index=True)
        leaves = min(surfaces, key=lambda name: surfaces[name].query(samples[last])[0])
        found.append((crossed[np.sort(first)], inward[facet], leaves))
    return found, axis


def geometric_helix(fibre, direction, axis) -> np.ndarray:
    """(c,) degrees in [-90, 90]: the angle of fibre lines (c, 3) against the circumferential direction e_L x e_T
    of the frame e_T = ``direction`` (the wall normal, endo to epi), e_L = the long ``axis`` (apex to base; (3,),
    or one per fibre (c, 3)) made orthogonal to it, towards e_L."""
    axis = np.broadcast_to(axis, fibre.shape)
    e_l = axis - np.outer(axis @ direction, direction)
    e_l /= np.linalg.norm(e_l, axis=1, keepdims=True)
    along, up = np.einsum("ci,ci->c", fibre, np.cross(e_l, direction)), np.einsum("ci,ci->c", fibre, e_l)
    return np.degrees(np.arctan2(np.where(along < 0, -up, up), np.abs(along)))


def ideal_wall_helix(phi, parameters) -> np.ndarray:
    """(k,) degrees: the helix angle the rule gives at transmural depths ``phi`` (k,) across an ideal LV free wall
    (d = 0 and the frames of grad psi and of every transmural gradient the same), from the core's own frame
    algebra (tested on its own in test_fibres)."""
    p = parameters
    frames = np.broadcast_to(np.eye(3), (len(phi), 3, 3))
    endo = fibres.quaternions(fibres.orient(frames, np.full(len(phi), p.alpha_endo), np.full(len(phi), p.beta_endo)))
    epi = fibres.quaternions(fibres.orient(frames, p.alpha_endo + (p.alpha_epi - p.alpha_endo) * phi,
                                           p.beta_endo + (p.beta_epi - p.beta_endo) * phi))
    return fibres.helix_angles(fibres.rotations(fibres.bislerp(endo, epi, phi))[:, :, 0], frames)


def check_free_wall(mesh, field, parameters, *, lines=6, depth=0.3, window=0.03, tolerance=8.0, step_up=4.0):
    """Along each of ``lines`` wall-normal lines across the LV free wall (:func:`free_wall_lines`): the line leaves
    through the epicardium, phi_epi rises from at most ``depth`` to at least 1 - ``depth``, the helix angle (in the
    geometry's frame) falls monotonically with phi_epi (no step up by more than ``step_up`` degrees; at equal
    phi_epi in any order: with alpha 60 / -60 the rule itself jumps from -7.5 to -52.6 degrees at phi_epi 0.76)
    and lies within ``tolerance`` degrees of the rule's on an ideal wall somewhere within ``window`` of the cell's
    phi_epi.

    The longitudinal direction e_L is each cell's grad psi (apex to base), the rule's own: where the base follows
    the annuli, tilted against the short-axis plane, grad psi tilts with it (7-25 degrees from the apex-to-base
    axis on the real heart), and so do the fibres.

    Returns the profiles: a list of (phi_epi (c,), helix angle (c,) degrees), endo to epi.
    """
    found, _ = free_wall_lines(mesh, lines)
    phi = field.laplace["PhiEpi"][mesh.cells].mean(axis=1)
    gradients, _ = fem.basis_gradients(mesh.points, mesh.cells)
    along = np.einsum("mai,ma->mi", gradients, field.laplace["Psi"][mesh.cells])
    offsets = np.linspace(-window, window, 7)
    profiles = []
    for cells, direction, leaves in found:
        helix = geometric_helix(field.fibre[cells], direction, along[cells])
        depths = phi[cells]
        assert leaves == "EPI", leaves
        assert depths[0] <= depth and depths[-1] >= 1 - depth, depths
        assert np.diff(depths).min() > -0.02, depths
        by_depth = np.lexsort((-helix, depths))   # cells at the same depth have no endo-to-epi order
        assert np.diff(helix[by_depth]).max() <= step_up, (helix, depths)
        near = ideal_wall_helix(np.clip(depths[:, None] + offsets, 0, 1).ravel(), parameters).reshape(-1, 7)
        assert ((helix >= near.min(axis=1) - tolerance) & (helix <= near.max(axis=1) + tolerance)).all(), \
            (helix.round(1), depths.round(2), near.mean(axis=1).round(1))
        profiles.append((depths, helix))
    return profiles
