"""Real hearts as they come (issue 30): frames of biv-me patient1's cine and the classes of variation built on them
(tests/cardiac_variants.py) meshed as ``bitemesh mesh GPFile -o heart.vtu`` meshes them (no flag but --frame for
two frames in one file), the plain method (the optimizer moves nodes on the same domain: benchmarks/cine.py has
the default's figures), and judged by the issue's targets: one valid part bounded by one surface (Euler
characteristic 2: no void, no handle), cavities open (else the heart check refuses), every wall guide point
counted, 1.0 mm from the boundary on average and 3.0 mm at the 95th percentile."""
from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from bitemesh.meshing import mesh
from bitemesh.core.steps.fidelity import distances_to_facets
from bitemesh.core.mesh.validity import count_boundary_components
from bitemesh.core.mesh.topology import boundary_facets
from bitemesh.core.mesh.tags import enclosed_volume
from bitemesh.core.sources.contours.cardiac import opening_beside_base
from bitemesh.io import read_labelled_points
from bitemesh.core.sources.contours.cardiac import heart_scale
from bitemesh.core.sources.contours import function as function_module
from bitemesh.core.errors import MeshingError
from tests.cardiac_variants import class_file, read_frame, read_surface, write_gpfile
from tests.conftest import DATA
from tests.meshcheck import assert_valid_domain

CINE = DATA / "bivme_patient1_cine" / "guidepoints"
#: the words of the wall guide points' labels (every endocardial, epicardial, free-wall and septal point)
WALL = ("ENDOCARDIAL", "EPICARDIAL", "FREEWALL", "SEPTUM")
#: every case meshes a real frame at R = 2 mm: 15-20 s each on CI's 2 cores
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def meshed(tmp_path_factory):
    """meshed(frame, variant=""): the mesh of a frame (or its variant), the guide points as meshed (short-axis slices
    where the registration moved them) and their labels, each meshed once for the module; the variants' files in
    the module's temporary folder."""
    if not (CINE / "GPFile_000.txt").is_file():
        pytest.skip(f"no biv-me cine in {CINE}")
    folder = tmp_path_factory.mktemp("variants")
    once = cache(lambda frame, variant: meshed_in(folder, frame, variant))
    return lambda frame, variant="": once(frame, variant)


def meshed_in(folder, frame: int, variant: str):
    path, time_frame = (CINE / f"GPFile_{frame:03d}.txt", None) if not variant else \
        class_file(CINE, frame, variant, folder)
    result = mesh(path, {"optimize": 0, **({} if time_frame is None else {"frame": time_frame})})
    points, labels, slices = read_labelled_points(path, frame=time_frame)
    for number, shift in result.function.shifts.items():
        points[slices == number] += shift
    return result, points, labels


def wall_distances(result, points, labels) -> np.ndarray:
    wall = np.array([any(word in label for word in WALL) for label in labels])
    mesh = result.mesh
    return distances_to_facets(points[wall], mesh.points[boundary_facets(mesh.cells)])


@pytest.mark.parametrize("frame, variant", [
    (0, ""),                            # end-diastole, the shipped case (once a handle: the outflow ring's fold)
    (8, ""),                            # end-systole
    (0, "open arcs"),                   # 40 % of the contours traced in part
    (0, "short arcs"),                  # 4-10 points on the basal and apical slices
    (0, "slices shifted 5 mm"),         # breath-holds
    (0, "long-axis view shifted 5 mm"),
    (0, "sparse base"),                 # no RV long-axis contour above the basal slice, no outflow valves
    (0, "sparser 3x"),
    (0, "frames merged"),               # two frames in one file, --frame 0
    (0, "base tilted 30 deg"),          # the annuli and the basal half sheared across the axis
    # no RV epicardium: tests/cli/test_cardiac_variants.py
])
def test_every_class_meshes_as_one_closed_myocardium_that_follows_the_guide_points(meshed, frame, variant):
    result, points, labels = meshed(frame, variant)
    assert_valid_domain(result.mesh, euler=2, components=1)
    assert count_boundary_components(result.mesh) == 1
    distance = wall_distances(result, points, labels)
    assert distance.mean() <= 1.0 and np.percentile(distance, 95) <= 3.0, (distance.mean(), np.percentile(distance,
                                                                                                          95))


def test_shifted_slices_mesh_as_the_unshifted_frame(meshed):
    """Slices shifted by up to 5 mm: the shifts found undo them (within 1 mm, tests/core/sources/test_real_hearts.py),
    so the mesh has the unshifted frame's figures: its volume within 1 %, its guide points as near."""
    plain, points, labels = meshed(0)
    shifted, shifted_points, shifted_labels = meshed(0, "slices shifted 5 mm")
    volume, shifted_volume = (result.mesh.cell_data["Volume"].sum() for result in (plain, shifted))
    assert shifted_volume == pytest.approx(volume, rel=0.01)
    near, shifted_near = wall_distances(plain, points, labels), wall_distances(shifted, shifted_points,
                                                                                shifted_labels)
    assert abs(shifted_near.mean() - near.mean()) < 0.1
    assert any("slices moved in their planes" in note for note in shifted.notes)


@pytest.mark.parametrize("frame, variant", [(0, ""), (7, ""), (23, ""), (0, "open arcs"), (0, "frames merged"),
                                            (0, "sparser 3x"), (0, "base tilted 30 deg")])
def test_the_mitral_and_tricuspid_points_lie_on_the_mesh(meshed, frame, variant):
    """The base follows the annuli: every mitral and tricuspid point within 3 mm of the boundary (10-16 mm with the
    plane through the valves' centres; 4.2 mm on frame 23 before the mitral points had their normals: its
    3-chamber view has no LV endocardial contour; 4.6 mm on frame 7 before the epicardium held the rings: its wall
    tapered to nothing at a 4-chamber view's mitral point; 3.3-8.1 mm on the four classes before the base stayed
    as high a wall around each anchor: it fell in a cliff beside the point, leaving a wedge thinner than a cell).
    The variants of tests/cli/test_cardiac_variants.py (no RV epicardium among them) are held to the same there."""
    result, points, labels = meshed(frame, variant)
    mesh = result.mesh
    for valve in ("MITRAL_VALVE", "TRICUSPID_VALVE"):
        distance = distances_to_facets(points[labels == valve], mesh.points[boundary_facets(mesh.cells)])
        assert distance.max() <= 3.0, (valve, distance)


def test_a_valve_point_off_the_annulus_is_named_and_the_mesh_follows_the_walls(meshed):
    """A mitral point 12 mm inside the LV cavity (biv-me's patient_1 has one 11 mm from its view's contours' ends,
    13 mm from biv-me's own fit): the mesh follows the walls, as near the guide points as the issue's targets ask,
    the other ring points within 3 mm; a note names the stray point, its slice and how far its slice's contours end
    from it (beyond R + the tracing noise, the plausibility check's 95 % bound); the shipped frame has no such
    note."""
    result, points, labels = meshed(0, "stray mitral point")
    plain, _, _ = meshed(0)
    assert_valid_domain(result.mesh, euler=2, components=1)
    distance = wall_distances(result, points, labels)
    assert distance.mean() <= 1.0 and np.percentile(distance, 95) <= 3.0
    rings = np.flatnonzero(np.isin(labels, ("MITRAL_VALVE", "TRICUSPID_VALVE")))
    near = distances_to_facets(points[rings], result.mesh.points[boundary_facets(result.mesh.cells)])
    stray = rings[0]
    assert near[rings != stray].max() <= 3.0
    notes = [note for note in result.notes if "MITRAL_VALVE point" in note]
    assert len(notes) == 1 and f"({', '.join(f'{value:.1f}' for value in points[stray])})" in notes[0], notes
    assert "contours end" in notes[0] and "trace the contours up to it" in notes[0]
    assert not any("VALVE point" in note for note in plain.notes)


def test_a_basal_contour_closed_across_the_outflow_tract_is_left_where_the_long_axis_views_contradict_it(meshed):
    """The basal slice's LV endocardial contour closed by a chord 40 % of its width in from the aortic side (as exports
    trace a basal slice that cuts the valves at end-systole: biv-me patient1's frame 13): the long-axis views cross
    that slice up to 21 mm from the chord, and the points they contradict are left out with a note naming the slice
    and the surface, so the LV cavity keeps the frame's volume within 2 % (following the chord: 4.6 % smaller, its
    endocardium 2.2 mm from biv-me's against 0.9) and the guide points, the chord's included, meet the issue's
    bounds; the frame as traced has no such note."""
    result, points, labels = meshed(0, "basal contour closed by a chord")
    plain, _, _ = meshed(0)
    assert_valid_domain(result.mesh, euler=2, components=1)
    notes = [note for note in result.notes if "LV_ENDO contour" in note]
    assert len(notes) == 1 and "left out" in notes[0] and "outflow tract" in notes[0], result.notes
    cavity, frame_cavity = (enclosed_volume(heart.mesh.points, heart.mesh.facets[
        heart.mesh.facet_tags == heart.mesh.tag_names["LV_ENDO"][0]]) for heart in (result, plain))
    assert cavity == pytest.approx(frame_cavity, rel=0.02)
    distance = wall_distances(result, points, labels)
    assert distance.mean() <= 1.0 and np.percentile(distance, 95) <= 3.0
    assert not any("contour:" in note and "left out" in note for note in plain.notes)


def test_a_systolic_frame_keeps_its_thin_rv_free_wall_whole(meshed):
    """End-systole (frame 14), the RV free wall about one cell thick at R = 2 mm: the handle repair cut a strip of
    1,300 cells along it from the base to the apex, leaving the RV cavity open along a slit (its endocardium met the
    epicardium along 1.9 m of edges, the cavity closed across the slit 63 ml against biv-me's 148), valid, Euler 2
    and exit 0.  No cut or fill larger than a handle's cross-section is taken now (handles.MAX_CELLS): a fill of
    111 cells removes that handle, the RV's endocardium meets the epicardium more than 2 R below the base along at
    most 5 R (the lips of a hole a cell across at most; 8.5 mm here, three edges), and its cavity is at least 70 %
    of biv-me's (frame 0: 87 %; the rest is the outflow tract up to the pulmonary ring, which biv-me's surface runs
    on to)."""
    result, _, _ = meshed(14)
    assert_valid_domain(result.mesh, euler=2, components=1)
    mesh = result.mesh
    assert opening_beside_base(mesh, result.function.base.below, 2 * result.radius, ("RV_ENDO",)) <= 5 * result.radius
    rv = mesh.facets[mesh.facet_tags == mesh.tag_names["RV_ENDO"][0]]
    vertices, triangles = read_surface(CINE.parent / "fitted" / "patient1_RV_ENDOCARDIAL_014.vtk")
    assert enclosed_volume(mesh.points, rv) >= 0.7 * enclosed_volume(vertices, triangles)


@pytest.mark.parametrize("frame", [5, 15])
def test_no_cavity_opens_through_its_wall_below_the_base(meshed, frame):
    """Frames 5 and 15: the RV endocardium's fit runs up to 7 mm beyond the epicardium's over 5 ml (frame 5), and a
    handle's cut ran from there to the base: the cavity opened through its free wall, its endocardium meeting the
    epicardium along 278 and 202 mm of edges more than 4 mm below the base, valid, Euler 2, exit 0.  Below the rim
    of the cavities' openings (BASE_RIM thinnest walls) a cavity is now closed by a wall min_wall thick however far
    its fit crosses the epicardium, and no cut that removes a handle joins two surfaces: no endocardium meets the
    epicardium more than the rim and a cell below the base along more than 5 R (the lips of a hole a cell across)."""
    result, _, _ = meshed(frame)
    assert_valid_domain(result.mesh, euler=2, components=1)
    function = result.function
    assert opening_beside_base(result.mesh, function.base.below, function.rim + result.radius) <= 5 * result.radius


def test_a_cavity_open_through_its_wall_is_refused_naming_where(monkeypatch):
    """The check behind the test above, on the case it was written for: frame 5 meshed as before the cavities were
    closed below the rim (function.CLOSING 0: the RV endocardium's fit runs through the epicardium's, open) is
    refused, naming the cavity, the length of its lips, where and how deep, and the contours to check."""
    if not (CINE / "GPFile_005.txt").is_file():
        pytest.skip(f"no biv-me cine in {CINE}")
    monkeypatch.setattr(function_module, "CLOSING", 0.0)
    with pytest.raises(MeshingError, match=r"the RV_ENDO cavity opens through its wall beside the base: its "
                                           r"endocardium meets the epicardium along \d+ mm more than 7.0 mm below the "
                                           r"base, around \(.*\), down to \d+ mm \(allowed 20 mm, 10 R\); check the "
                                           r"RV_ENDO and epicardial contours"):
        mesh(CINE / "GPFile_005.txt", {"optimize": 0})   # the opening is the carving's


@pytest.mark.parametrize("size", [0.4, 0.1])
def test_a_small_heart_meshes_at_its_own_scale(tmp_path, size):
    """Frame 0 shrunk to 0.4 of its size (a young child's heart, 178 ml -> 11 ml) and to 0.1 (a mouse's, 0.2 ml of
    walls 0.1-0.4 mm thick): fitted and meshed in a frame scaled to an adult's size (heart_scale: its span over
    140 mm), so that R, the thinnest wall, the valves' clearances and the base's reach are the same share of it as
    of an adult's: one closed myocardium whose guide points lie as near relative to its size (the issue's 1.0 / 3.0
    mm times the size), R = 2 mm times heart_scale, the notes' lengths in the input's mm, and the plausibility bounds
    shrink with it.  Before: R = 2 mm and
    walls kept 2.5 mm thick, refused at 0.3 of the size as 8.3 ml of myocardium, below an adult's 10 ml, with a hint
    that did not help; with R and the thinnest wall alone scaled, the mouse's refused by fidelity (the valves'
    clearances stayed 2 mm)."""
    if not (CINE / "GPFile_000.txt").is_file():
        pytest.skip(f"no biv-me cine in {CINE}")
    gp = read_frame(CINE, 0)
    centre = gp["points"].mean(axis=0)
    path = write_gpfile({**gp, "points": centre + size * (gp["points"] - centre)}, tmp_path / "GPFile_000.txt")
    result = mesh(path, {"optimize": 0})
    scale = heart_scale(read_labelled_points(path)[0])
    assert result.radius == pytest.approx(2.0 * scale) and scale == pytest.approx(size * 199.2 / 140, rel=0.01)
    assert any(f"a heart {scale:.2g} the size of an adult's" in note for note in result.notes)
    moved = next(note for note in result.notes if note.startswith("slices moved"))   # its lengths in the input's mm
    number, shift = next(iter(result.function.shifts.items()))
    assert f"slice {number} by {np.linalg.norm(shift):.1f} mm" in moved
    assert_valid_domain(result.mesh, euler=2, components=1)
    points, labels, slices = read_labelled_points(path)
    for number, shift in result.function.shifts.items():
        points[slices == number] += shift
    distance = wall_distances(result, points, labels)
    assert distance.mean() <= size * 1.0 and np.percentile(distance, 95) <= size * 3.0


def test_walls_thickened_by_a_coarse_mesh_are_said(meshed):
    """At 10,000 cells (R about 4.6 mm) the thinnest wall kept is 1.25 R, about 5.7 mm, so the RV free wall
    (3 mm traced) is thicker in the mesh and the myocardium some 38 % larger than at R = 2 mm: a note says so and
    gives the radius for walls as traced (R <= 2, where the thinnest wall kept is MIN_WALL, 2.5 mm); at the
    default R = 2 mm, no such note."""
    result, _, _ = meshed(0)
    assert not any("thinnest wall kept" in note for note in result.notes)
    coarse = mesh(CINE / "GPFile_000.txt", cells=10000, optimize=0)
    note = next(note for note in coarse.notes if "thinnest wall kept" in note)
    assert f"at R = {coarse.radius:.3g} the thinnest wall kept is {1.25 * coarse.radius:.3g}" in note
    assert "give radius <= 2 " in note


def test_the_optimised_end_systolic_heart_has_no_sliver(recwarn):
    """Cine frame 6 with the defaults (the optimizer on): a valid myocardium whose smallest dihedral angle is above
    5 degrees, the usual bound of a sliver (a cap of 1.4 degrees, three facets on the surface, was left by the last
    round's flips and smoothing; the final passes of peel and collapse take it)."""
    from bitemesh.core.optimize.measures import smallest_angles
    if not (CINE / "GPFile_006.txt").is_file():
        pytest.skip(f"no biv-me cine in {CINE}")
    result = mesh(CINE / "GPFile_006.txt")
    assert_valid_domain(result.mesh, components=1)
    assert smallest_angles(result.mesh.points, result.mesh.cells).min() > 5.0
