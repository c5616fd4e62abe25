"""The tail of the pipeline on analytic shapes: biting, Delaunay and the valid-domain carving."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from bitemesh.core.steps.delaunay import delaunay
from bitemesh.core.steps.repair import DelaunayCells, carve_domain, enclosed_inside_voids
from bitemesh.core.grid.sampled import sample_function
from bitemesh.core.mesh.simplicial import signed_measures
from bitemesh.core.parameters import BitingParameters
from bitemesh.core.steps.spine import mesh_from_grid
from bitemesh.core.shapes import annulus, die, sphere, torus, two_cavity_shell
from bitemesh.core.steps.spurious import outside_cells

from tests.builders import PLAIN, sampled
from tests.meshcheck import assert_valid_domain


@pytest.mark.parametrize("shape, radius", [(sphere(), 0.1), (torus(), 0.09), (die(), 0.11),
                                           (two_cavity_shell(), 0.07), (annulus(), 0.05)],
                         ids=lambda v: getattr(v, "name", ""))
def test_analytic_shapes_give_valid_domains_of_the_right_topology_volume_and_quality(shape, radius):
    result = mesh_from_grid(sampled(shape, radius / 4), BitingParameters(radius=radius, seed=0), optimize=PLAIN)
    assert_valid_domain(result.mesh, euler=shape.boundary_euler if shape.dim == 3 else None,
                        measure=shape.measure, measure_tolerance=0.02, mean_quality=0.78)


def test_delaunay_cells_are_positively_oriented_and_tile_the_hull():
    rng = np.random.default_rng(0)
    nodes = rng.random((500, 3))
    cells = delaunay(nodes)
    volume = signed_measures(nodes, cells)
    assert (volume > 0).all()
    from scipy.spatial import ConvexHull
    assert volume.sum() == pytest.approx(ConvexHull(nodes).volume, rel=1e-9)


def test_the_circumcentre_test_removes_cells_outside_and_keeps_those_inside():
    """On an annulus the cells spanning the hole have their circumcentre deep in it: they must go."""
    shape = annulus()
    grid = sampled(shape, 0.02)
    angles = np.linspace(0, 2 * np.pi, 40, endpoint=False)

    def ring(r):
        return np.stack([r * np.cos(angles), r * np.sin(angles)], axis=1)

    nodes = np.concatenate([ring(1.0), ring(0.4), ring(0.7) + 1e-3])
    cells = delaunay(nodes)
    outside = outside_cells(grid, nodes, cells)
    centroid_radius = np.linalg.norm(nodes[cells].mean(axis=1), axis=1)
    assert outside[centroid_radius < 0.3].all()
    assert not outside[(centroid_radius > 0.5) & (centroid_radius < 0.9)].any()


def test_a_hollow_cavity_stays_open_and_a_stray_part_is_dropped():
    """Two disjoint balls, one 1/1000 the volume of the other: min_component drops the small one."""
    big, small = sphere(), sphere(0.12)

    def function(p):
        return np.maximum(big.function(p), small.function(p - np.array([1.6, 0, 0])))

    grid = sample_function(function, (-1, -1, -1), (1.8, 1, 1), 0.03, margin=0.1)
    result = mesh_from_grid(grid, BitingParameters(radius=0.12), optimize=PLAIN)
    assert_valid_domain(result.mesh, euler=2, components=1)
    assert result.mesh.points[:, 0].max() <= 1.01


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(radius=st.floats(0.12, 0.3), seed=st.integers(0, 2**32 - 1), threshold=st.floats(0.2, 0.6))
def test_any_radius_seed_and_threshold_give_a_valid_domain(radius, seed, threshold):
    from bitemesh.core.parameters import SpuriousParameters
    grid = sampled(torus(), 0.03)
    result = mesh_from_grid(grid, BitingParameters(radius=radius, seed=seed), SpuriousParameters(threshold=threshold),
                            optimize=PLAIN)
    assert_valid_domain(result.mesh)


def test_same_seed_gives_the_same_mesh_bit_for_bit():
    grid = sampled(die(), 0.04)
    first = mesh_from_grid(grid, BitingParameters(radius=0.16, seed=5)).mesh
    again = mesh_from_grid(grid, BitingParameters(radius=0.16, seed=5)).mesh
    assert np.array_equal(first.points, again.points) and np.array_equal(first.cells, again.cells)


def test_carving_an_empty_inside_is_a_clear_error():
    from bitemesh.core.errors import MeshingError
    grid = sampled(sphere(), 0.05)
    nodes = np.random.default_rng(0).random((50, 3)) * 0.1 + 5.0
    with pytest.raises(MeshingError, match="no cell is inside"):
        carve_domain(grid, nodes, delaunay(nodes))


def test_a_pinch_is_mended_by_the_smaller_change_and_filling_can_be_turned_off():
    """Two cubes of a 2 x 2 block meeting only along an edge: per pinch, fill the gap or drop the smaller fans,
    whichever changes less volume; without filling, cells only go."""
    from bitemesh.core.steps.repair import DelaunayCells, unpinch
    from bitemesh.core.mesh.topology import non_manifold_faces
    corners = np.array([[i, j, k] for i in range(3) for j in range(3) for k in range(2)], float)
    corners += np.random.default_rng(0).normal(0, 1e-3, corners.shape)
    cells = delaunay(corners)
    volume = signed_measures(corners, cells)
    centroid = corners[cells].mean(axis=1)
    keep = (centroid[:, 0] < 1) == (centroid[:, 1] < 1)   # the two cubes on one diagonal
    pinched = non_manifold_faces(cells[keep], len(corners))
    assert pinched
    filled = unpinch(DelaunayCells.of(corners, cells), keep, pinched, fill=True)
    removed = unpinch(DelaunayCells.of(corners, cells), keep, pinched, fill=False)
    assert (removed <= keep).all() and removed.sum() < keep.sum()
    change_with_fill = volume[filled != keep].sum()
    assert 0 < change_with_fill <= volume[removed != keep].sum() + 1e-12



@pytest.mark.parametrize("gap, filled", [(0.02, True), (0.3, False)])
def test_an_enclosed_pocket_thinner_than_half_a_cell_is_filled_and_a_cavity_is_kept(gap, filled):
    """Cells dropped between two discs of nodes ``gap`` apart inside a ball of nodes 0.1 apart, f < 0 there: a
    pocket 0.02 thick (0.3 of the edge of a regular cell of the median volume wide, yet 60 such cells in volume)
    is below the mesh's resolution and is filled; one 0.3 thick is a cavity and stays a void (see THIN_VOID)."""
    axis = np.arange(-1.0, 1.0001, 0.1)
    lattice = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    disc = lattice[(np.abs(lattice[:, 2]) < 1e-9) & (np.linalg.norm(lattice[:, :2], axis=1) < 0.45)]
    away = (np.abs(lattice[:, 2]) > gap / 2 + 0.05) | (np.linalg.norm(lattice[:, :2], axis=1) > 0.55)
    nodes = np.vstack([lattice[away & (np.linalg.norm(lattice, axis=1) <= 1.0)],
                       disc + [0, 0, gap / 2], disc - [0, 0, gap / 2]])
    nodes += np.random.default_rng(0).normal(0, 0.001, nodes.shape)   # no four nodes on a circle
    cells = delaunay(nodes)
    centroids = nodes[cells].mean(axis=1)
    pocket = (np.abs(centroids[:, 2]) < gap / 2) & (np.linalg.norm(centroids[:, :2], axis=1) < 0.4)
    delaunay_cells = DelaunayCells.of(nodes, cells)
    delaunay_cells = dataclasses.replace(delaunay_cells, centroid_values=np.where(pocket, -1.0, 1.0))
    keep = ~pocket
    assert pocket.sum() > 20 and delaunay_cells.volume[pocket].sum() > 10 * np.median(delaunay_cells.volume)
    fill = enclosed_inside_voids(delaunay_cells, keep)
    assert fill[pocket].all() == filled and fill[pocket].any() == filled
    assert not fill[keep].any()
