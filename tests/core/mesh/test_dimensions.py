"""Simplicial meshes in any dimension k = 2..5 (issue 36): the measures, circumspheres, quality and validity of the
2-D and 3-D code, by the general formulas where the closed forms stop, checked against analytic values."""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull
from scipy.stats import special_ortho_group

from bitemesh.core.errors import InvalidInputError
from bitemesh.core.mesh.quality import (dihedral_angles, dihedral_angles_any, radius_ratio, radius_ratios_any,
                                        signed_radius_ratio)
from bitemesh.core.mesh.simplicial import Mesh, _circumspheres_any, circumspheres, signed_measures
from bitemesh.core.mesh.topology import non_manifold_faces
from bitemesh.core.mesh.validity import (boundary_euler_characteristic, check_valid_domain,
                                         count_boundary_components)
from bitemesh.core.steps.delaunay import delaunay


def regular_simplex(k: int):
    """The regular k-simplex with unit circumradius, positively oriented: points (k + 1, k), cell (1, k + 1)."""
    centred = np.eye(k + 1) - 1.0 / (k + 1)
    points = centred @ np.linalg.svd(centred)[2][:k].T
    points /= np.linalg.norm(points[0])
    cell = np.arange(k + 1)
    if np.linalg.det(points[1:] - points[0]) < 0:
        cell[:2] = cell[1::-1]
    return points, cell[None]


@lru_cache(maxsize=None)
def ball_delaunay(k: int):
    """The Delaunay cells of n points on the unit sphere S^(k-1) and n inside (n = 600, 300 in 5-D): a
    triangulated ball."""
    rng = np.random.default_rng(k)
    count = 300 if k == 5 else 600
    surface = rng.normal(size=(count, k))
    surface /= np.linalg.norm(surface, axis=1, keepdims=True)
    points = np.vstack([surface, rng.uniform(-0.4, 0.4, (count, k)) / np.sqrt(k)])
    return points, delaunay(points)


@pytest.mark.parametrize("k", [2, 3, 4, 5])
def test_the_regular_simplex_has_quality_one_and_its_dihedral_angles(k):
    """Q = k r_in / R_circ = 1, every dihedral angle arccos(1 / k) (60, 70.53, 75.52, 78.46 degrees), the
    circumradius the one it was built with, the volume sqrt(k + 1) / k! (k + 1)^(k/2) / k^(k/2) of unit
    circumradius."""
    points, cell = regular_simplex(k)
    assert signed_radius_ratio(points, cell)[0] == pytest.approx(1.0, abs=1e-12)
    assert dihedral_angles(points, cell)[0] == pytest.approx(np.degrees(np.arccos(1.0 / k)), abs=1e-9)
    assert dihedral_angles(points, cell).shape == (1, (k + 1) * k // 2)
    centre, radius = circumspheres(points, cell)
    assert radius[0] == pytest.approx(1.0, abs=1e-12) and np.allclose(centre, 0.0, atol=1e-12)
    edge = np.sqrt(2.0 * (k + 1) / k)   # of the regular simplex of unit circumradius
    volume = edge**k / np.prod(np.arange(1, k + 1)) * np.sqrt((k + 1) / 2.0**k)
    assert signed_measures(points, cell)[0] == pytest.approx(volume, rel=1e-12)


@pytest.mark.parametrize("k", [2, 3])
def test_the_general_formulas_are_the_closed_forms_of_2d_and_3d(k):
    """One formula: radius ratio, dihedral angles and circumspheres of any k equal the compiled closed forms on 2-D
    and 3-D Delaunay cells to rounding."""
    points, cells = ball_delaunay(k)
    assert np.allclose(radius_ratios_any(points, cells), signed_radius_ratio(points, cells), atol=1e-12)
    assert np.allclose(dihedral_angles_any(points, cells), dihedral_angles(points, cells), atol=1e-9)
    for general, closed in zip(_circumspheres_any(points, cells), circumspheres(points, cells)):
        assert np.allclose(general, closed, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("k", [4, 5])
def test_a_triangulated_ball_is_a_valid_domain_with_a_sphere_for_boundary(k):
    """The Delaunay cells of points on and in the unit k-ball: positively oriented, their measures summing to the
    hull's (scipy's own volume), a valid domain whose boundary is one sphere S^(k-1): Euler characteristic
    1 + (-1)^(k-1) (0 for S^3, 2 for S^4)."""
    points, cells = ball_delaunay(k)
    measures = signed_measures(points, cells)
    assert (measures > 0).all()
    assert measures.sum() == pytest.approx(ConvexHull(points).volume, rel=1e-9)
    mesh = Mesh(points, cells)
    assert check_valid_domain(mesh) == []
    assert boundary_euler_characteristic(mesh) == 1 + (-1) ** (k - 1)
    assert count_boundary_components(mesh) == 1
    quality = radius_ratio(points, cells)
    assert 0 < quality.min() and quality.max() <= 1.0


@pytest.mark.parametrize("k", [4, 5])
def test_the_checks_name_what_is_wrong_in_any_dimension(k):
    """A repeated cell, an inverted one and a domain cut to a shell of cells whose boundary pinches are named."""
    points, cells = ball_delaunay(k)
    problems = check_valid_domain(Mesh(points, np.vstack([cells, cells[:1]])))
    assert any("same vertices" in p for p in problems) and any("more than two cells" in p for p in problems)
    inverted = cells.copy()
    inverted[0, :2] = inverted[0, 1::-1]
    assert any("inverted" in p for p in check_valid_domain(Mesh(points, inverted)))
    shell = cells[np.linalg.norm(points[cells].mean(axis=1), axis=1) > 0.35]
    assert any("non-manifold boundary" in p for p in check_valid_domain(Mesh(points, shell)))


@pytest.mark.parametrize(("k", "shared"), [(3, 1), (4, 1), (4, 2), (5, 1), (5, 2), (5, 3)])
def test_two_cells_that_share_a_face_below_a_ridge_alone_are_pinched_there(k, shared):
    """Two k-simplices with ``shared`` vertices in common (a vertex, an edge or a triangle, below the ridges: their
    link is two balls, Euler characteristic 2 where a boundary face's is 1): that face is found, and nothing in a
    triangulated ball."""
    cells = np.array([np.arange(k + 1), np.r_[np.arange(shared), np.arange(k + 1, 2 * k + 2 - shared)]])
    assert [faces.tolist() for faces in non_manifold_faces(cells, 2 * k + 2 - shared)] == [[list(range(shared))]]
    points, ball = ball_delaunay(k)
    assert non_manifold_faces(ball, len(points)) == []


def test_a_vertex_whose_link_is_a_disk_and_an_annulus_is_pinched():
    """Tetrahedra around vertex 0 over a triangle and over a triangulated annulus apart from it: the link's Euler
    characteristic is 1 + 0, a boundary vertex's, but its boundary triangles form three fans (in 4-D, a ball and a
    solid torus around a space-time heart's vertex): found, by the validity check's test of stars."""
    outer, inner = [4, 5, 6], [7, 8, 9]
    annulus = [[outer[i], outer[(i + 1) % 3], inner[i]] for i in range(3)] + \
        [[outer[(i + 1) % 3], inner[(i + 1) % 3], inner[i]] for i in range(3)]
    cells = np.array([[0, 1, 2, 3]] + [[0, *triangle] for triangle in annulus])
    assert [faces.tolist() for faces in non_manifold_faces(cells, 10)] == [[[0]]]


def test_a_mesh_of_more_than_five_dimensions_is_refused_by_name():
    with pytest.raises(InvalidInputError, match="k = 2 to 5"):
        check_valid_domain(Mesh(np.zeros((7, 6)), np.arange(7)[None]))
    with pytest.raises(InvalidInputError, match="nodes must be an"):
        delaunay(np.random.default_rng(0).normal(size=(20, 6)))


@settings(max_examples=10, deadline=None)
@given(st.integers(4, 5), st.floats(-3, 3), st.integers(0, 2**31 - 1))
def test_quality_does_not_change_with_rigid_motion_and_scale(k, exponent, seed):
    """Q and the dihedral angles of k-D cells are the same after a rotation, a translation and a scaling."""
    points, cells = ball_delaunay(k)
    cells = cells[:500]
    rotation = special_ortho_group.rvs(k, random_state=seed)
    moved = (points @ rotation.T + np.arange(k)) * 10.0**exponent
    assert np.allclose(radius_ratio(moved, cells), radius_ratio(points, cells), atol=1e-8)
    assert np.allclose(dihedral_angles(moved, cells), dihedral_angles(points, cells), atol=1e-6)
