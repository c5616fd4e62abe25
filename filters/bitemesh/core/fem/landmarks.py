"""A heart mesh's landmarks as tags of lower dimension, as cardiac-geometries tags its left ventricle and
fenicsx-pulse's examples hold it by them: the base rings (the edges where BASE meets the epicardium and each
endocardium) and the apex points (the node of the epicardium, and of the LV endocardium, farthest below the base).

A left ventricle (tagged EPI, ENDO, BASE) gets cardiac-geometries' names and numbers: ENDOPT 1 and EPIPT 2
(vertices), EPIRING 3 and ENDORING 4 (edges).  Both ventricles: EPIRING 5, LV_ENDORING 6, RV_ENDORING 7 (edges),
EPIPT 8, LV_ENDOPT 9 (vertices), numbers no surface or region of theirs has.
"""
from __future__ import annotations

import numpy as np

from ..mesh.simplicial import Mesh
from ..mesh.topology import first_rows
from .fibres import lowest_node, surface_facets

#: (tag name, tag, dimension, what): the landmarks of a left ventricle and of both ventricles.
LEFT_VENTRICLE = (("ENDOPT", 1, 0, "ENDO"), ("EPIPT", 2, 0, "EPI"), ("EPIRING", 3, 1, "EPI"),
                  ("ENDORING", 4, 1, "ENDO"))
BIVENTRICULAR = (("EPIRING", 5, 1, "EPI"), ("LV_ENDORING", 6, 1, "LV_ENDO"), ("RV_ENDORING", 7, 1, "RV_ENDO"),
                 ("EPIPT", 8, 0, "EPI"), ("LV_ENDOPT", 9, 0, "LV_ENDO"))


def edges_of(triangles: np.ndarray) -> np.ndarray:
    """(3 t, 2) the edges of triangles (t, 3), each with its smaller node first."""
    return np.sort(triangles[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)


def shared_edges(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """(e, 2) the edges that a triangle of ``first`` and one of ``second`` share, sorted."""
    edges = np.unique(edges_of(first), axis=0)
    return edges[first_rows(edges_of(second), edges) >= 0]


def landmarks(mesh: Mesh):
    """The landmarks of a heart ``mesh`` (a left ventricle or both ventricles: :func:`~.fibres.surface_facets`).

    Returns
    -------
    edges : (e, 2) int64 and edge_tags (e,) int32, the base rings; vertices : (v,) int64 and vertex_tags (v,) int32,
    the apex points; names : name -> (tag, dimension)
    """
    facets = surface_facets(mesh, "landmarks")
    left = "ENDO" in mesh.tag_names and not len(facets["RV_ENDO"])
    table = LEFT_VENTRICLE if left else BIVENTRICULAR
    source = {"ENDO": "LV_ENDO"}
    edges, edge_tags, vertices, vertex_tags = [], [], [], []
    for _, tag, dimension, surface in table:
        triangles = facets[source.get(surface, surface)]
        if dimension == 1:
            ring = shared_edges(triangles, facets["BASE"])
            edges.append(ring)
            edge_tags.append(np.full(len(ring), tag, np.int32))
        else:
            vertices.append(lowest_node(mesh.points, np.unique(triangles), facets["BASE"]))
            vertex_tags.append(tag)
    names = {name: (tag, dimension) for name, tag, dimension, _ in table}
    return (np.vstack(edges).astype(np.int64), np.concatenate(edge_tags), np.array(vertices, np.int64),
            np.array(vertex_tags, np.int32), names)
