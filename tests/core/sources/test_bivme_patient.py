"""The real patient meshed as the two-cavity myocardium (bitemesh.core.labelled on biv-me's GPFile of
../shared/data/bivme_patient1, read with bitemesh.io, which loads no VTK for it), and the real input made bad."""
from __future__ import annotations

import warnings
from functools import cache
from pathlib import Path

import bitemesh
import numpy as np
import pytest
from bitemesh.core.sources.contours.cardiac import BIVME_DEFAULT_DOMAIN, BIVME_SURFACES
from bitemesh.core.sources.contours.fit import labelled_implicit
from bitemesh.core.sources.contours.function import boundary_surfaces
from bitemesh.core.sources.contours.run import run_labelled
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.fem.fibres import FibreParameters, fibre_field
from bitemesh.core.steps.fidelity import distances_to_facets
from bitemesh.core.parameters import BitingParameters, SpuriousParameters, OptimizeParameters
from bitemesh.core.steps.spine import mesh_from_grid
from bitemesh.core.mesh.validity import count_boundary_components
from bitemesh.io import read_labelled_points

from tests.builders import PLAIN, located
from tests.fibrecheck import check_frames, check_free_wall, tagged_nodes
from tests.meshcheck import assert_valid_domain

PACKAGED = Path(bitemesh.__file__).resolve().parent / "data" / "bivme_patient1"


# --- the real heart ------------------------------------------------------------------------------------------------

def distance_to_surface(points, vertices, facets):
    """(m,) exact distance from each point to the nearest of the triangles ``vertices[facets]``."""
    return distances_to_facets(points, vertices[facets])


@cache
def heart(path: str, cells: int, optimize: int = 1):
    points, labels, slices = read_labelled_points(path)
    return run_labelled(points, labels, slices=slices, biting=BitingParameters(cells=cells),
                                 optimize=OptimizeParameters(optimize=optimize))


def guide_point_distances(result):
    """Per surface, each of its contour points below the base plane to the boundary triangles of that surface; a
    point within R of the base (on the rim where the surface meets the base cap, which the base is fitted through)
    to the boundary."""
    function = result.function
    facets, surface = boundary_surfaces(result.mesh, function)
    distances = {}
    for number, (name, points) in enumerate(function.points.items()):
        height = function.base.below(points)
        inner, rim = points[height >= result.radius], points[(height > 0) & (height < result.radius)]
        distances[name] = np.r_[distance_to_surface(inner, result.mesh.points, facets[surface == number]),
                                distance_to_surface(rim, result.mesh.points, facets)]
    return distances


def check_heart(result, source, *, mean_bound, max_bound):
    function = result.function
    assert function.expression == BIVME_DEFAULT_DOMAIN
    assert function.names == ("EPI", "LV_ENDO", "RV_ENDO", "BASE")
    assert_valid_domain(result.mesh, euler=2, components=1, mean_quality=0.75)   # one closed boundary surface
    assert count_boundary_components(result.mesh) == 1
    distances = guide_point_distances(result)
    every = np.concatenate(list(distances.values()))
    print(f"{len(result.mesh.cells)} cells: guide points mean {every.mean():.3f} mm, max {every.max():.3f} mm")
    assert len(every) > 1600   # of 1,702 distinct contour points, those below the valve plane
    assert every.mean() <= mean_bound and every.max() <= max_bound, (every.mean(), every.max())
    # the myocardium (not the blood pools): deep inside each cavity (the centre of its short-axis contour in the
    # third short-axis slice, frameID 4) is outside the mesh
    volume = result.mesh.cell_data["Volume"].sum()
    assert 140e3 < volume < 210e3   # mm^3
    points, labels, slices = read_labelled_points(source)
    for name in ("LV_ENDO", "RV_ENDO"):
        centre = points[np.isin(labels, BIVME_SURFACES[name]) & (slices == 4)].mean(axis=0)
        assert function.surfaces[name](centre[None])[0] > 4 and function(centre[None])[0] < 0
        assert not located(result.mesh, centre).any()   # of the 64 tetrahedra with the nearest centroids


def test_the_patient_meshes_as_one_valid_myocardium_near_its_contours(gpfile):
    """40,000 cells (R about 2.8 mm), the plain method: valid, one part, the contour points within 1 mm on average
    (the default, optimised, at 136,000 cells below)."""
    check_heart(heart(str(gpfile), 40000, optimize=0), gpfile, mean_bound=1.0, max_bound=6.0)


def test_the_myocardium_is_one_closed_surface_whatever_the_seed():
    """At 30,000 cells seeds 7, 8 and 13 gave Euler characteristics -2, 0 and 0 (a hole punched through the RV wall
    where it is about one cell thick, a one-cell void at the RV cavity's tip) before the repair weighed topology.
    A heart's handles are removed (handles 'auto'): at this size (R about 3 mm) the top of the septum, where the
    base cuts it between the tricuspid and the aortic annuli, is a bridge about a cell thick for most seeds."""
    points, labels, slices = read_labelled_points(PACKAGED / "GPFile_000.txt")
    first = run_labelled(points, labels, slices=slices, biting=BitingParameters(cells=30000, seed=7),
                                  optimize=PLAIN)
    for seed in (7, 8, 13):
        biting = BitingParameters(radius=first.radius, seed=seed)
        mesh = first.mesh if seed == 7 else mesh_from_grid(first.implicit, biting, SpuriousParameters(handles="remove"),
                                                           optimize=PLAIN).mesh
        assert_valid_domain(mesh, euler=2, components=1)
        assert count_boundary_components(mesh) == 1


@pytest.mark.slow
def test_the_patient_at_136000_cells_meets_the_goals(gpfile):
    """The paper's heart size: contour points within 0.5 mm of their surface on average (issue 10's bound) and
    within the fidelity check's far bound R + 3 x noise at most.  (The farthest point, 2.9-3.1 mm over seeds, lies
    at the RV cavity's apical tip, thinner than a cell.)  The default is FEM-grade (issue 12): mean radius ratio at
    least gmsh + Netgen's on the two-cavity heart (0.837, benchmarks/peers.md), and min dihedral >= 20 degrees or
    a warning that gives the figures (a wall a cell or two thick can leave a cell below it)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = heart(str(gpfile), 136000)
    far = result.radius + 3 * result.function.tracing_noise()
    check_heart(result, gpfile, mean_bound=0.5, max_bound=far)
    assert result.mesh.cell_data["RadiusRatio"].mean() >= 0.837
    assert len(result.mesh.cells) > 110000
    if result.mesh.cell_data["MinDihedralAngle"].min() < 20.0:
        assert any("could not meet its bounds" in str(warning.message) for warning in caught)


@pytest.mark.slow
def test_the_patient_at_136000_cells_has_monotonic_helix_angles_across_its_lv_free_wall(gpfile):
    """The same mesh (about the paper's size, the default optimised mesh) with its fibres: unit orthogonal frames;
    twelve wall-normal lines across the LV free wall, at least five cells each (phi_epi from at most 0.15 to at
    least 0.85); the apex is the LV's."""
    mesh = heart(str(gpfile), 136000).mesh
    field = fibre_field(mesh)
    check_frames(field.fibre, field.sheet, field.sheet_normal)
    for values in field.laplace.values():
        assert -0.01 <= values.min() and values.max() <= 1.01
    profiles = check_free_wall(mesh, field, FibreParameters(), lines=12, depth=0.15)
    assert all(len(depths) >= 5 for depths, _ in profiles)
    apex = mesh.points[field.apex]
    nearest = {name: np.linalg.norm(mesh.points[tagged_nodes(mesh, name)] - apex, axis=1).min()
               for name in ("LV_ENDO", "RV_ENDO")}
    assert nearest["LV_ENDO"] < nearest["RV_ENDO"], nearest


# --- bad real input -------------------------------------------------------------------------------------------------

def test_a_gpfile_without_rv_labels_names_the_missing_surface(gpfile):
    points, labels, slices = read_labelled_points(gpfile)
    keep = ~np.isin(labels, ["SAX_RV_FREEWALL", "LAX_RV_FREEWALL", "SAX_RV_SEPTUM", "LAX_RV_SEPTUM"])
    with pytest.raises(InvalidInputError, match=r"surface RV_ENDO needs points labelled SAX_RV_FREEWALL or "
                                                r"LAX_RV_FREEWALL or SAX_RV_SEPTUM or LAX_RV_SEPTUM or .*, and the "
                                                r"input has none; labels present: AORTA_VALVE \(2\)"):
        labelled_implicit(points[keep], labels[keep], BIVME_DEFAULT_DOMAIN, slices=slices[keep])
    # by default, without RV contours, the domain is the LV's
    function, _, _ = labelled_implicit(points[keep], labels[keep], slices=slices[keep])
    assert function.expression == "LV_EPI - LV_ENDO"
    assert any("meshed as the left ventricle" in note for note in function.notes)
    # an LV-only domain needs none of them
    lv_only = ~np.isin(labels, ["SAX_RV_FREEWALL", "LAX_RV_FREEWALL"])
    function, _, _ = labelled_implicit(points[lv_only], labels[lv_only], "LV_EPI - LV_ENDO",
                                                slices=slices[lv_only])
    assert function.names == ("LV_EPI", "LV_ENDO", "BASE")


def test_a_domain_naming_an_unknown_surface_lists_the_biv_me_surfaces(gpfile):
    points, labels, _ = read_labelled_points(gpfile)
    with pytest.raises(InvalidInputError, match=r"names the unknown surface 'RV'; known surfaces: EPI, LV_ENDO, "
                                                r"RV_ENDO, LV_EPI"):
        labelled_implicit(points, labels, "EPI - LV_ENDO - RV")


def test_a_contour_that_encloses_nothing_is_a_sample_not_a_refusal(gpfile):
    """The LV endocardium of slice 4 traced only along 8 points of its wall (about 17 mm), as a straight line of
    points between the first and the eighth: an arc that does not tell its side (issue 30: a refusal before).  Its
    points are samples of the LV endocardium all the same.  (A line across the cavity is another matter: the long-axis
    views contradict it, tests/cli/test_real_heart_meshes.py.)"""
    points, labels, slices = read_labelled_points(gpfile)
    contour = np.flatnonzero((labels == "SAX_LV_ENDOCARDIAL") & (slices == 4))
    line, rest = contour[:8], contour[8:]
    points[line] = points[line[0]] + np.linspace(0, 1, len(line))[:, None] * (points[line[-1]] - points[line[0]])
    keep = ~np.isin(np.arange(len(points)), rest)
    points, labels, slices = points[keep], labels[keep], slices[keep]
    function, _, _ = labelled_implicit(points, labels, slices=slices)
    row = function.slices["LV_ENDO"] == 4
    assert row.sum() == len(line)
    assert not any("contour:" in note and "left out" in note for note in function.notes)
    # on its zero level, but for the sampled surface's interpolation: within its 1 mm spacing (the line's ends, where
    # it meets the slices around at a kink, are where trilinear interpolation errs most)
    assert np.abs(function.surfaces["LV_ENDO"](function.points["LV_ENDO"][row])).max() < 1.0
