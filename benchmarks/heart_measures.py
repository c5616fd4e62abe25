"""What a cardiac modeller measures on a heart mesh made from guide points, against the data and against biv-me's
own fitted surfaces of the same frame (``benchmarks/cine.py``).

- every guide point of every label to the mesh's boundary (none excluded), and the valve points; the wall guide
  points to biv-me's own surfaces too (the peer's fit of the same points);
- the mesh's EPI / LV_ENDO / RV_ENDO against biv-me's EPICARDIAL / LV_ENDOCARDIAL / RV_ENDOCARDIAL, both ways: each
  reference vertex to the mesh's surface of that name, each mesh facet (by area) to the reference triangles;
- apart, the mesh's facets more than 10 mm below the base and within 1 mm of a wall guide point against biv-me's
  surfaces: at the data itself the two fits can disagree no less than biv-me's own distance from it;
- the cavity volumes, each cavity's surface closed across its openings by a fan from each rim's centroid (the
  mesh's cavity is closed where its endocardium meets the base; biv-me's at its valve rings), and how far the LV
  cavity's surface lies outward of the LV endocardial guide points more than 10 mm below the base on average (signed:
  > 0 where a point is inside the cavity), the mesh's and biv-me's: a fit biased outward has a larger cavity than its
  contours;
- topology: components, boundary surfaces, the boundary's Euler characteristic, and how long the cavities'
  endocardium meets the epicardium more than 4 mm (2 R) below the base (the lips of holes through a wall; 0 on a whole
  heart).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "filters"))

from bitemesh.core.mesh.simplicial import facet_measures
from bitemesh.core.steps.fidelity import distances_to_facets
from bitemesh.core.mesh.validity import boundary_euler_characteristic, check_valid_domain, count_boundary_components
from bitemesh.core.mesh.topology import connected_components
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.core.mesh.tags import closed_by_fans, enclosed_volume
from bitemesh.core.sources.contours.cardiac import (CARDIAC_RADIUS, ENDOCARDIAL_TAGS, EPICARDIAL_TAGS,
                                                    opening_beside_base)
from bitemesh.core.sources.contours.function import BASE_RIM
from bitemesh.core.sources.contours.run import thinnest_wall

#: biv-me's fitted surfaces (patient1_<NAME>_<frame>.vtk) and the mesh tags that correspond to each.
REFERENCE_SURFACES = {"EPICARDIAL": EPICARDIAL_TAGS, "LV_ENDOCARDIAL": ENDOCARDIAL_TAGS["LV_ENDO"],
                      "RV_ENDOCARDIAL": ENDOCARDIAL_TAGS["RV_ENDO"]}
#: the guide-point labels of the walls (every one measured), and the valves (mitral and tricuspid held to 3 mm).
WALL_WORDS = ("ENDOCARDIAL", "EPICARDIAL", "FREEWALL", "SEPTUM")
VALVES = ("MITRAL_VALVE", "TRICUSPID_VALVE", "AORTA_VALVE", "PULMONARY_VALVE")
#: mm below the base: above it, between the basal short-axis slice and the valve rings, the guide points are few and
#: biv-me's template shape lies 1.3-2.9 mm from them (the mesh 0.2-0.5 mm; patient1, frame 0), so the surfaces are
#: compared below it too.
BASAL_BAND = 10.0
#: mm below the base: an opening of a cavity deeper than this is no part of its opening through the base.  Above it lie
#: the rim of the openings (BASE_RIM thinnest walls, 5 mm at R = 2 mm: a cavity's fit may run through the
#: epicardium's there and a handle's cut may notch it; the wall's top meets the base cap in a knife edge here and
#: there) and a cell.
OPENING_DEPTH = BASE_RIM * thinnest_wall(CARDIAC_RADIUS) + CARDIAC_RADIUS
#: mm: the mesh's facets this near a wall guide point are where the data holds the surface; their distance to biv-me's
#: surfaces is what the two fits disagree on at the data itself.
NEAR_DATA = 1.0


def tagged(mesh, names) -> np.ndarray:
    """(b, 3) the mesh's facets tagged with any of ``names``."""
    tags = [mesh.tag_names[name][0] for name in names if name in mesh.tag_names and mesh.tag_names[name][1] == 2]
    return mesh.facets[np.isin(mesh.facet_tags, tags)]


def surface_distances(mesh, names, vertices, triangles, below=None):
    """(mean reference -> mesh, mean mesh -> reference by area, 95 % of both pooled, mean mesh -> reference of the
    facets more than :data:`BASAL_BAND` below the base, given ``below``: (m, 3) -> (m,) mm below it) in mm; NaN
    without facets."""
    facets = tagged(mesh, names)
    if not len(facets):
        return np.nan, np.nan, np.nan, np.nan
    corners = mesh.points[facets]
    to_mesh = distances_to_facets(vertices, corners)
    area = facet_measures(corners)
    centroids = corners.mean(axis=1)
    to_reference = distances_to_facets(centroids, vertices[triangles])
    deep = np.nan
    if below is not None:
        weight = area * (below(centroids) > BASAL_BAND)
        deep = float((to_reference * weight).sum() / max(weight.sum(), 1e-300))
    return (float(to_mesh.mean()), float((to_reference * area).sum() / area.sum()),
            float(np.percentile(np.r_[to_mesh, to_reference], 95)), deep)


def winding_inside(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(n,) bool, which of (n, 3) points the closed triangle surface (vertices, triangles) winds around (the solid
    angles of its triangles, Van Oosterom and Strackee 1983, summed: 4 pi inside, 0 outside; any orientation)."""
    inside = np.zeros(len(points), bool)
    for start in range(0, len(points), 256):
        corners = vertices[triangles][None] - points[start:start + 256, None, None]   # (p, t, 3, 3)
        a, b, c = corners[:, :, 0], corners[:, :, 1], corners[:, :, 2]
        la, lb, lc = (np.linalg.norm(v, axis=2) for v in (a, b, c))
        top = np.einsum("ptk,ptk->pt", a, np.cross(b, c))
        bottom = la * lb * lc + np.einsum("ptk,ptk->pt", a, b) * lc + np.einsum("ptk,ptk->pt", a, c) * lb \
            + np.einsum("ptk,ptk->pt", b, c) * la
        inside[start:start + 256] = np.abs((2 * np.arctan2(top, bottom)).sum(axis=1)) > 2 * np.pi
    return inside


def cavity_offset(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray) -> float:
    """The mean over (n, 3) points of their distance to a cavity's surface (vertices, triangles), + where the point
    is inside the cavity closed across its openings (the surface passes outward of it), - outside (mm)."""
    distance = distances_to_facets(points, vertices[triangles])
    return float(np.where(winding_inside(points, *closed_by_fans(vertices, triangles)), distance, -distance).mean())


def measure_heart(mesh, points, labels, reference: dict | None = None, below=None) -> dict:
    """Every measure of the module docstring on ``mesh`` (a tagged bitemesh heart, mm) of the guide ``points``
    (n, 3) with their ``labels`` (n,); ``reference``: biv-me surface name -> (vertices, triangles); ``below``: (m, 3)
    -> (m,) the depth below the mesh's base (mm)."""
    facets = boundary_facets(mesh.cells)
    corners = mesh.points[facets]
    distance = distances_to_facets(points, corners)
    wall = np.array([any(word in label for word in WALL_WORDS) for label in labels])
    row = {"cells": len(mesh.cells), "valid": not check_valid_domain(mesh),
           "components": int(connected_components(mesh.cells).max() + 1),
           "boundaries": count_boundary_components(mesh), "euler": boundary_euler_characteristic(mesh),
           "myocardium_ml": float(mesh.cell_data["Volume"].sum()) / 1000,
           "wall_mean": float(distance[wall].mean()), "wall_p95": float(np.percentile(distance[wall], 95)),
           "wall_max": float(distance[wall].max()),
           "labels": {label: (float(distance[labels == label].mean()), float(distance[labels == label].max()))
                      for label in np.unique(labels)}}
    row["lips_mm"] = opening_beside_base(mesh, below, OPENING_DEPTH) if below is not None else np.nan
    for valve in VALVES:
        if (labels == valve).any():
            row[valve] = float(distance[labels == valve].max())
    for cavity in ("LV_ENDO", "RV_ENDO"):
        facets = tagged(mesh, (cavity,))
        row[f"{cavity}_ml"] = enclosed_volume(mesh.points, facets) / 1000 if len(facets) else np.nan
    lv_points = points[np.char.endswith(labels.astype(str), "LV_ENDOCARDIAL")]
    if below is not None:
        lv_points = lv_points[below(lv_points) > BASAL_BAND]
    facets = tagged(mesh, ENDOCARDIAL_TAGS["LV_ENDO"])
    row["lv_offset"] = cavity_offset(lv_points, mesh.points, facets) if len(facets) and len(lv_points) else np.nan
    row["surfaces"] = {}
    if reference:   # the peer: biv-me's own fit against the same guide points
        offsets = np.cumsum([0] + [len(vertices) for vertices, _ in reference.values()])
        vertices = np.vstack([vertices for vertices, _ in reference.values()])
        triangles = np.vstack([triangles + offset for (_, triangles), offset in zip(reference.values(), offsets)])
        every_reference = vertices[triangles]
        peer = distances_to_facets(points[wall], every_reference)
        row["bivme_wall_mean"], row["bivme_wall_p95"] = float(peer.mean()), float(np.percentile(peer, 95))
    for name, (vertices, triangles) in (reference or {}).items():
        row["surfaces"][name] = surface_distances(mesh, REFERENCE_SURFACES[name], vertices, triangles, below)
        if name != "EPICARDIAL":
            row[f"bivme_{REFERENCE_SURFACES[name][0]}_ml"] = enclosed_volume(vertices, triangles) / 1000
        if name == "LV_ENDOCARDIAL" and len(lv_points):
            row["bivme_lv_offset"] = cavity_offset(lv_points, vertices, triangles)
    if reference and below is not None:
        corners = mesh.points[boundary_facets(mesh.cells)]
        centroids, area = corners.mean(axis=1), facet_measures(corners)
        near = (below(centroids) > BASAL_BAND) & (cKDTree(points[wall]).query(centroids)[0] < NEAR_DATA)
        row["to_bivme_near_data"] = float((distances_to_facets(centroids[near], every_reference) * area[near]).sum()
                                          / max(area[near].sum(), 1e-300))
    if row["surfaces"]:
        row["from_bivme"] = float(np.nanmean([means[0] for means in row["surfaces"].values()]))
        row["to_bivme"] = float(np.nanmean([means[1] for means in row["surfaces"].values()]))
        row["to_bivme_deep"] = float(np.nanmean([means[3] for means in row["surfaces"].values()]))
    return row
