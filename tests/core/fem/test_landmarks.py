"""A heart's landmarks (bitemesh.core.fem.landmarks): on the two-cavity shell (mm; the outer ellipsoid's bottom at
z = -80, the LV cavity's at z = -60, the base plane z = 0), each base ring is a closed loop of edges on both BASE and
its surface, near z = 0; the apex points are the lowest nodes of the epicardium and of the LV endocardium; a left
ventricle gets cardiac-geometries' names and numbers."""
from __future__ import annotations

import numpy as np
from bitemesh.core.fem.landmarks import landmarks
from bitemesh.core.optimize.measures import mean_edge_length

from tests.fibrecheck import tagged_nodes, tagged_shell
from tests.solvers.test_solvers import left_ventricle


def test_the_rings_are_closed_loops_on_the_base_and_the_apexes_are_the_lowest_nodes():
    mesh = tagged_shell()
    edges, edge_tags, vertices, vertex_tags, names = landmarks(mesh)
    assert names == {"EPIRING": (5, 1), "LV_ENDORING": (6, 1), "RV_ENDORING": (7, 1), "EPIPT": (8, 0),
                     "LV_ENDOPT": (9, 0)}
    base, edge = tagged_nodes(mesh, "BASE"), mean_edge_length(mesh.points, mesh.cells)
    for ring, surface in (("EPIRING", "EPI"), ("LV_ENDORING", "LV_ENDO"), ("RV_ENDORING", "RV_ENDO")):
        chosen = edges[edge_tags == names[ring][0]]
        degree = np.bincount(chosen.ravel())
        assert len(chosen) >= 10 and set(degree[degree > 0]) == {2}, ring      # closed loops
        assert np.isin(chosen, base).all() and np.isin(chosen, tagged_nodes(mesh, surface)).all(), ring
        assert np.abs(mesh.points[chosen][..., 2]).max() < edge, ring   # BASE's nodes: near z = 0
    apex = dict(zip(vertex_tags.tolist(), vertices.tolist()))
    assert abs(mesh.points[apex[names["EPIPT"][0]], 2] + 80) < edge
    assert abs(mesh.points[apex[names["LV_ENDOPT"][0]], 2] + 60) < edge


def test_a_left_ventricle_has_cardiac_geometries_names():
    _, edge_tags, _, vertex_tags, names = landmarks(left_ventricle())
    assert names == {"ENDOPT": (1, 0), "EPIPT": (2, 0), "EPIRING": (3, 1), "ENDORING": (4, 1)}
    assert sorted(set(edge_tags.tolist())) == [3, 4] and sorted(vertex_tags.tolist()) == [1, 2]
