"""The checks every mesh that bitemesh produces must pass, shared by the tests."""
from __future__ import annotations

import numpy as np
import pytest


def assert_valid_domain(mesh, *, euler=None, components=1, measure=None, measure_tolerance=0.02,
                        mean_quality=None):
    """Fail unless ``mesh`` is a valid finite-element domain with the expected topology, measure and quality."""
    from bitemesh.core.quality import (boundary_euler_characteristic, cell_quality, check_valid_domain,
                                       connected_components)
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
    from bitemesh.core.mesh import signed_measures
    corners = mesh.points[mesh.cells]
    volumes = signed_measures(mesh.points, mesh.cells)
    return (corners.mean(axis=1) * volumes[:, None]).sum(axis=0) / volumes.sum()
