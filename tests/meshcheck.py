"""The checks every mesh that bitemesh produces must pass, shared by the tests."""
from __future__ import annotations

import numpy as np
import pytest

#: the unit k-ball's measure: pi^2 / 2 in 4-D, 8 pi^2 / 15 in 5-D.
BALL = {4: np.pi**2 / 2, 5: 8 * np.pi**2 / 15}


def assert_valid_domain(mesh, *, euler=None, components=1, measure=None, measure_tolerance=0.02,
                        mean_quality=None):
    """Fail unless ``mesh`` is a valid finite-element domain with the expected topology, measure and quality."""
    from bitemesh.core.mesh.validity import boundary_euler_characteristic, check_valid_domain
    from bitemesh.core.mesh.quality import cell_quality
    from bitemesh.core.mesh.topology import connected_components
    problems = check_valid_domain(mesh)
    assert problems == [], problems
    assert connected_components(mesh.cells).max() + 1 == components
    if euler is not None:
        assert boundary_euler_characteristic(mesh) == euler
    arrays = cell_quality(mesh)
    if measure is not None:
        assert arrays["Volume"].sum() == pytest.approx(measure, rel=measure_tolerance)
    if mean_quality is not None:
        assert np.mean(arrays["RadiusRatio"]) >= mean_quality


def centroid(mesh) -> np.ndarray:
    """The centre of mass of the meshed solid (each cell weighed by its signed measure)."""
    from bitemesh.core.mesh.simplicial import signed_measures
    corners = mesh.points[mesh.cells]
    volumes = signed_measures(mesh.points, mesh.cells)
    return (corners.mean(axis=1) * volumes[:, None]).sum(axis=0) / volumes.sum()


def oriented_rows(facets) -> set:
    """The facets (b, k) as a set of tuples that keeps their orientation: each triangle turned (cyclically) to start
    at its smallest vertex; edges (2D) as they are."""
    facets = np.asarray(facets)
    if facets.shape[1] == 3:
        start = np.argmin(facets, axis=1)
        facets = facets[np.arange(len(facets))[:, None], (start[:, None] + np.arange(3)) % 3]
    return set(map(tuple, facets.tolist()))


def assert_tagged(mesh):
    """Fail unless ``mesh`` carries tags as :class:`bitemesh.core.mesh.simplicial.Mesh` says: every boundary facet once,
    oriented out of the domain, and every interface facet (cells of two regions on its sides) once, oriented out of
    the region with the lower tag; tags > 0, each named (dimension k - 1); every cell in a named region (dimension k).

    Returns the interface facets' rows (a set of oriented tuples)."""
    from bitemesh.core.mesh.topology import boundary_facets, facet_table
    assert mesh.facets is not None and mesh.facet_tags is not None
    assert mesh.facet_tags.dtype == np.int32 and mesh.facets.shape == (len(mesh.facet_tags), mesh.dim)
    assert (mesh.facet_tags > 0).all()
    regions = mesh.cell_data["Region"]
    assert regions.dtype == np.int32 and (regions > 0).all()
    facets, inverse, _ = facet_table(mesh.cells)
    side = np.repeat(regions, mesh.cells.shape[1])
    order = np.argsort(inverse, kind="stable")
    same = np.flatnonzero(inverse[order[1:]] == inverse[order[:-1]])   # the two rows of each interior facet
    a, b = order[same], order[same + 1]
    lower = np.where(side[a] < side[b], a, b)[side[a] != side[b]]
    interfaces = facets[lower]
    expected = oriented_rows(boundary_facets(mesh.cells)) | oriented_rows(interfaces)
    assert oriented_rows(mesh.facets) == expected and len(mesh.facets) == len(expected)
    named = {(tag, dim) for tag, dim in mesh.tag_names.values()}
    assert {(int(tag), mesh.dim - 1) for tag in np.unique(mesh.facet_tags)} <= named
    assert {(int(tag), mesh.dim) for tag in np.unique(regions)} <= named
    return oriented_rows(interfaces)


def largest_facet_circumradius(corners: np.ndarray) -> float:
    """The largest circumradius of the (f, k, k) facets, each within its own (k-1)-plane."""
    offsets = corners[:, 1:] - corners[:, :1]
    gram = np.einsum("fik,fjk->fij", offsets, offsets)
    centre = np.linalg.solve(2 * gram, np.einsum("fii->fi", gram)[:, :, None])[:, :, 0]
    return float(np.linalg.norm(np.einsum("fi,fik->fk", centre, offsets), axis=1).max())
