"""Labelled contours (bitemesh.core.labelled; bitemesh.core.sources.contours: .slices, .csg): slices, in-plane normals,
the CSG expression, the base plane, and a synthetic two-cavity shell sampled as sparse contours and meshed."""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh.core.sources.contours.function import boundary_surfaces
from bitemesh.core.parameters import KERNELS
from bitemesh.core.sources.contours.csg import evaluate_domain, parse_domain
from bitemesh.core.sources.contours.slices import SlicePlane, contour_normals, infer_slices, slice_planes
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.sources.contours.cardiac import BIVME_DEFAULT_DOMAIN
from bitemesh.core.sources.contours.base import fit_base_plane
from bitemesh.core.sources.contours.surface_fit import fit_contour_rbf
from bitemesh.core.sources.contours.fit import labelled_implicit
from bitemesh.core.sources.contours.run import run_labelled
from bitemesh.core.parameters import BitingParameters, OptimizeParameters
from bitemesh.core.shapes import two_cavity_shell

from tests.builders import ELLIPSOIDS, SCALE, SHELL_DOMAIN, located, sample_shell
from tests.meshcheck import assert_valid_domain

#: the shell's base plane: z = 0, the cavities open above it
BASE = ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))


@pytest.fixture(scope="module")
def shell():
    return sample_shell()


# --- the synthetic shell ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("given_slices", [True, False], ids=["slice-ids", "inferred-slices"])
def test_sparse_contours_of_a_two_cavity_shell_mesh_to_its_volume(shell, given_slices):
    points, labels, slices = shell
    # the default (optimised) with the slices given; the plain method where they are inferred (the reading differs)
    result = run_labelled(points, labels, domain=SHELL_DOMAIN, base_plane=BASE, slices=slices if given_slices else None,
                          biting=BitingParameters(cells=8000), optimize=OptimizeParameters(optimize=int(given_slices)))
    exact = two_cavity_shell().measure * SCALE ** 3
    assert_valid_domain(result.mesh, euler=2, components=1, measure=exact, measure_tolerance=0.03,
                        mean_quality=0.75)
    # both cavities are open: their centres (just below the base) are not meshed; the wall between them is
    assert not located(result.mesh, np.array([[15.0, 0, -5], [-27.5, 0, -5]]), candidates=None).any()
    assert located(result.mesh, np.array([[-5.0, 0, -20]]), candidates=None).all()
    # the boundary lies on the three ellipsoids and the base
    _, surface = boundary_surfaces(result.mesh, result.function)
    assert set(np.unique(surface)) == {0, 1, 2, 3}
    assert result.function.names == ("EPI", "LV_ENDO", "RV_ENDO", "BASE")


def test_the_shells_contours_lie_on_its_surfaces_and_in_its_slices(shell):
    points, labels, slices = shell
    shape = two_cavity_shell()
    for name, (centre, axes) in ELLIPSOIDS.items():
        scaled = (points[labels == name] - np.array(centre) * SCALE) / (np.array(axes) * SCALE)
        assert np.allclose(np.linalg.norm(scaled, axis=1), 1.0)
    assert np.allclose(shape.function(points[(labels == "EPI") & (points[:, 2] < -1)] / SCALE), 0, atol=1e-9)
    planes = slice_planes(points, slices)
    for number, plane in planes.items():
        assert np.allclose((points[slices == number] - plane.centre) @ plane.normal, 0, atol=1e-9)


def test_the_implicit_is_positive_in_the_wall_and_negative_in_the_cavities(shell):
    points, labels, slices = shell
    function, lower, upper = labelled_implicit(points, labels, SHELL_DOMAIN, BASE, slices=slices)
    wall = np.array([[-5.0, 0, -20], [0, 0, -72], [48, 0, -10]])      # septum, apex, LV free wall
    cavities = np.array([[15.0, 0, -20], [-27.5, 0, -20]])
    beyond = np.array([[-10.0, 0, 5.0], [70, 0, -20]])                  # above the base, outside the epicardium
    assert (function(wall) > 0).all()
    assert (function(cavities) < 0).all() and (function(beyond) < 0).all()
    assert (lower <= points[points[:, 2] < 0].min(axis=0)).all() and upper[2] < 10
    assert list(function.active_surface(np.vstack([cavities, beyond]))) == [1, 2, 3, 0]


# --- contours and normals -----------------------------------------------------------------------------------------

def circle(count=40, radius=10.0, z=0.0, centre=(0.0, 0.0)):
    angle = np.linspace(0, 2 * np.pi, count, endpoint=False)
    return np.column_stack([centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle),
                            np.full(count, z)])


def test_normals_of_a_closed_contour_point_out_whatever_the_order():
    points = circle()
    rng = np.random.default_rng(0)
    order = rng.permutation(len(points))
    normals = contour_normals(points[order], np.zeros(len(points), int))
    outward = points[order] / np.linalg.norm(points[order], axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", normals, outward).min() > 0.98
    assert np.allclose(normals[:, 2], 0)


def test_normals_of_an_open_u_contour_point_out_of_the_u():
    """A long-axis contour of a cavity: a U open at the valve, closed across it for the orientation."""
    angle = np.linspace(np.pi, 2 * np.pi, 25)
    arc = np.column_stack([10 * np.cos(angle), np.zeros_like(angle), 10 * np.sin(angle)])
    sides = [np.column_stack([np.full(8, x), np.zeros(8), np.linspace(3, 24, 8)]) for x in (-10.0, 10.0)]
    points = np.vstack([arc, *sides])
    normals = contour_normals(points, np.zeros(len(points), int))
    assert (normals[len(arc):len(arc) + 8, 0] < -0.95).all() and (normals[len(arc) + 8:, 0] > 0.95).all()
    assert (normals[5:20, 2] < 0).all()   # the bottom of the U points down, out of the cavity


def test_normals_of_a_crescent_from_two_labels_point_out_of_the_crescent():
    """The RV cavity in a short-axis slice: the free wall and the septum, two open arcs that close a crescent (inside
    the circle of radius 30 about 0 and outside the circle of radius 35 about (0, -15))."""
    free = np.array([[30 * np.cos(a), 30 * np.sin(a), 0] for a in np.linspace(0.15, np.pi - 0.15, 30)])
    septum = np.array([[35 * np.cos(b), 35 * np.sin(b) - 15, 0] for b in np.linspace(np.pi - 0.6, 0.6, 25)])
    points = np.vstack([free, septum])
    normals = contour_normals(points, np.zeros(len(points), int))
    expected = np.vstack([free / 30, -(septum - [0, -15, 0]) / 35])
    found = np.isfinite(normals[:, 0])
    # the tips of the horns, where the two arcs run closer than the point spacing, may get no normal
    assert found.sum() >= 0.8 * len(points) and found[[10, 20, 40, 45]].all()
    agreement = np.einsum("ij,ij->i", normals[found], expected[found])
    assert (agreement > 0.7).all() and np.count_nonzero(agreement < 0.9) <= 4   # off by up to 45 deg at the tips


def test_a_contour_nested_in_another_of_its_region_bounds_a_hole():
    outer, inner = circle(60, 20.0), circle(30, 8.0)
    normals = contour_normals(np.vstack([outer, inner]), np.zeros(90, int))
    assert (np.einsum("ij,ij->i", normals[:60], outer / 20) > 0.98).all()
    assert (np.einsum("ij,ij->i", normals[60:], inner / 8) < -0.98).all()


@pytest.mark.parametrize("arc", [(0.0, 0.5), (2.5, 3.3), (4.0, 6.0)])
def test_an_open_arc_takes_the_side_its_neighbouring_slices_show(arc):
    """A contour traced only in part (an arc of 0.5 to 2 radians, its chord on the wrong side of the region for a
    septum's row) between two closed contours of the same surface: its normals point out, as theirs do."""
    angle = np.linspace(*arc, 9)
    part = np.column_stack([10 * np.cos(angle), 10 * np.sin(angle), np.zeros_like(angle)])
    points = np.vstack([circle(40, 10.0, -8.0), part, circle(40, 10.0, 8.0)])
    slices = np.repeat([0, 1, 2], [40, 9, 40])
    planes = slice_planes(circle(40, 10.0, 0.0), np.zeros(40, int))
    planes = {0: slice_planes(points[:40], np.zeros(40, int))[0], 1: planes[0],
              2: slice_planes(points[49:], np.zeros(40, int))[0]}
    normals = contour_normals(points, slices, planes)
    outward = points[:, :2] / np.linalg.norm(points[:, :2], axis=1, keepdims=True)
    agreement = np.einsum("ij,ij->i", normals[:, :2], outward)
    assert np.nanmin(agreement[40:49]) > 0.95 and np.count_nonzero(np.isfinite(agreement[40:49])) >= 7
    assert agreement[:40].min() > 0.98 and agreement[49:].min() > 0.98


def test_a_straight_row_alone_keeps_no_normal():
    """A line of points and no other contour of the surface: nothing tells its side, so its points are samples of
    f = 0 alone."""
    line = np.column_stack([np.linspace(0, 30, 20), np.zeros(20), np.zeros(20)])
    planes = {0: SlicePlane(np.zeros(3), np.array([0, 0, 1.0]), np.array([[1.0, 0, 0], [0, 1.0, 0]]))}
    assert np.isnan(contour_normals(line, np.zeros(20, int), planes)).all()


def test_slices_are_found_from_coplanar_contours(shell):
    points, _, slices = shell
    found = infer_slices(points)
    assert (found >= 0).all() and found.max() + 1 == len(np.unique(slices))
    # each true slice is found, but for the points on lines where two slices cross (they join the larger slice)
    for number in np.unique(slices):
        assert np.bincount(found[slices == number]).max() >= 0.85 * np.count_nonzero(slices == number)
    for number, plane in slice_planes(points, found).items():
        assert np.abs((points[found == number] - plane.centre) @ plane.normal).max() < 1e-3 * 200
    assert np.array_equal(found, infer_slices(points))   # seeded: the same every time


def test_a_line_of_points_is_no_slice():
    points = np.column_stack([np.linspace(0, 1, 30), np.zeros(30), np.zeros(30)])
    assert (infer_slices(points) == -1).all()


# --- the RBF --------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kernel", KERNELS)
def test_the_rbf_interpolates_the_contours_and_is_signed(kernel):
    points = np.vstack([circle(40, 10.0, z) for z in (-8.0, 0.0, 8.0)]
                       + [circle(40, 6.0, 13.0), circle(40, 6.0, -13.0)])
    slices = np.repeat(np.arange(5), 40)
    normals = contour_normals(points, slices)
    rbf = fit_contour_rbf(points, normals, kernel=kernel, offset=2.0)
    assert np.abs(rbf(points)).max() < 1e-6
    assert rbf(np.zeros((1, 3)))[0] > 5 and rbf(np.array([[20.0, 0, 0]]))[0] < 0
    # the analytic gradient agrees with finite differences, and points outward on the surface
    x = np.array([[9.0, 1.0, 4.0], [3.0, -2.0, 1.0]])
    step = 1e-5
    numeric = np.stack([(rbf(x + e) - rbf(x - e)) / (2 * step) for e in np.eye(3) * step], axis=1)
    assert np.allclose(rbf.gradient(x), numeric, atol=1e-4)
    assert np.einsum("ij,ij->i", rbf.gradient(points[:40] * 1.05)[:, :2], points[:40, :2]).max() < 0


# --- the domain expression ------------------------------------------------------------------------------------------

def test_the_domain_expression_parses_with_precedence_and_left_association():
    known = ["EPI", "LV_ENDO", "RV_ENDO", "1"]
    assert parse_domain(BIVME_DEFAULT_DOMAIN, known) == (
        "-", ("-", ("name", "EPI"), ("name", "LV_ENDO")), ("name", "RV_ENDO"))
    assert parse_domain("EPI - (LV_ENDO + RV_ENDO)", known) == (
        "-", ("name", "EPI"), ("+", ("name", "LV_ENDO"), ("name", "RV_ENDO")))
    assert parse_domain("EPI + LV_ENDO & 1", known) == ("+", ("name", "EPI"), ("&", ("name", "LV_ENDO"), ("name", "1")))
    assert parse_domain("  EPI  ", known) == ("name", "EPI")


@pytest.mark.parametrize("expression, message", [
    ("EPI - LV", r"names the unknown surface 'LV'; known surfaces: EPI, LV_ENDO, RV_ENDO"),
    ("EPI - ", r"the expression ends too early"),
    ("(EPI - LV_ENDO", r"expected '\)'"),
    ("EPI LV_ENDO", r"unexpected 'LV_ENDO' at position 4"),
    ("EPI * LV_ENDO", r"unexpected character '\*'"),
    ("", r"domain must be a non-empty expression"),
])
def test_a_bad_domain_expression_says_what_is_wrong(expression, message):
    with pytest.raises(InvalidInputError, match=message):
        parse_domain(expression, ["EPI", "LV_ENDO", "RV_ENDO"])


def test_csg_by_min_and_max_and_the_thinnest_wall():
    values = {"A": np.array([5.0, 1.0, -1.0, 0.75, 0.5]), "B": np.array([-2.0, 3.0, -4.0, 1.0, 3.0])}
    tree = parse_domain("A - B", values)
    value, source = evaluate_domain(tree, values)
    assert value.tolist() == [2.0, -3.0, -1.0, -1.0, -3.0] and source.tolist() == [1, 1, 0, 1, 1]
    # a wall of 1: the layer 0 < f_A < 1 stays where B reaches less than 1 beyond A (point 3), attributed to B
    value, source = evaluate_domain(tree, values, min_wall=1.0)
    assert value.tolist() == [2.0, -1.0, -1.0, 0.25, -1.5] and source.tolist() == [1, 1, 0, 1, 1]
    # closed (a heart below its base): the layer stays however far B reaches (point 4: 2.5 beyond A)
    value, _ = evaluate_domain(tree, values, min_wall=1.0, closed=np.inf)
    assert value.tolist() == [2.0, 0.0, -1.0, 0.25, 0.5]
    assert evaluate_domain(parse_domain("A + B", values), values)[0].tolist() == [5.0, 3.0, -1.0, 1.0, 3.0]
    assert evaluate_domain(parse_domain("A & B", values), values)[0].tolist() == [-2.0, 1.0, -4.0, 0.75, 0.5]


# --- the base plane and bad input -----------------------------------------------------------------------------------

def test_the_base_plane_fits_the_valves_with_the_apex_inside():
    rng = np.random.default_rng(1)
    valves = np.column_stack([rng.uniform(-20, 20, (8, 2)), 0.1 * rng.normal(size=8)])
    for apex_z, expected in ((-90.0, 1.0), (90.0, -1.0)):
        base = fit_base_plane(valves, [0.0, 0.0, apex_z])
        assert base.is_plane and base.normal[2] == pytest.approx(expected, abs=0.01) and abs(base.point[2]) < 0.1
    with pytest.raises(InvalidInputError, match="lie on one line"):
        fit_base_plane(np.column_stack([np.arange(5.0), np.zeros(5), np.zeros(5)]), [0, 0, -1])


def test_a_surface_whose_labels_are_absent_is_named(shell):
    points, labels, slices = shell
    keep = labels != "RV_ENDO"
    with pytest.raises(InvalidInputError, match=r"surface RV_ENDO needs points labelled RV_ENDO, and the input has "
                                                r"none; labels present: EPI \(\d+\), LV_ENDO \(\d+\)"):
        labelled_implicit(points[keep], labels[keep], SHELL_DOMAIN, BASE, slices=slices[keep],
                          surfaces={"EPI": "EPI", "LV_ENDO": "LV_ENDO", "RV_ENDO": "RV_ENDO"})


def test_a_domain_naming_an_unknown_surface_lists_the_known_ones(shell):
    points, labels, slices = shell
    with pytest.raises(InvalidInputError, match=r"unknown surface 'RV'; known surfaces: EPI, LV_ENDO, RV_ENDO"):
        labelled_implicit(points, labels, "EPI - LV_ENDO - RV", BASE, slices=slices)


def test_several_surfaces_need_a_domain_and_labels_must_match_points(shell):
    """Unknown labels need a domain; the example the refusal gives puts the widest surface first (it gave 'BAR -
    FOO' for a FOO holding BAR, whose domain is empty), and followed, it gives the shell."""
    import re
    points, labels, slices = shell
    with pytest.raises(InvalidInputError, match=r"the points have 3 surfaces \(EPI, .*\): give domain") as refused:
        labelled_implicit(points, labels, slices=slices)
    example = re.search(r"such as '([^']+)'", str(refused.value)).group(1)
    assert example.startswith("EPI - ")
    function, lower, upper = labelled_implicit(points, labels, example, BASE, slices=slices)
    shell_function, _, _ = labelled_implicit(points, labels, "EPI - LV_ENDO - RV_ENDO", BASE, slices=slices)
    probes = np.random.default_rng(0).uniform(lower, upper, (2000, 3))
    np.testing.assert_allclose(function(probes), shell_function(probes), rtol=0, atol=1e-9)
    assert (function(probes) > 0).any()
    with pytest.raises(InvalidInputError, match=r"labels must hold one label per point"):
        labelled_implicit(points, labels[:-1], SHELL_DOMAIN)


def test_contours_in_one_plane_enclose_no_volume():
    points = np.vstack([circle(30, 10.0), circle(30, 4.0)])
    labels = np.array(["OUT"] * 30 + ["IN"] * 30)
    with pytest.raises(InvalidInputError, match=r"the contours of surface OUT all lie in one plane"):
        labelled_implicit(points, labels, "OUT - IN", slices=np.zeros(60, int))


def test_an_empty_domain_is_refused(shell):
    points, labels, slices = shell
    with pytest.raises(InvalidInputError, match=r"the domain 'LV_ENDO - EPI' is empty"):
        labelled_implicit(points, labels, "LV_ENDO - EPI", BASE, slices=slices)


def test_valves_are_needed_for_a_valve_plane(shell):
    points, labels, slices = shell
    with pytest.raises(InvalidInputError, match=r"base_plane='valves' needs at least 3 points labelled MITRAL_VALVE"):
        labelled_implicit(points, labels, SHELL_DOMAIN, "valves", slices=slices)


def test_optimize_relaxes_the_shell_without_changing_its_shape_or_topology(shell):
    points, labels, slices = shell
    plain, optimized = (run_labelled(points, labels, domain=SHELL_DOMAIN, base_plane=BASE, slices=slices,
                                     biting=BitingParameters(cells=4000), optimize=optimize)
                        for optimize in (OptimizeParameters(optimize=0), OptimizeParameters()))
    assert_valid_domain(optimized.mesh, euler=2, components=1, mean_quality=0.84,
                        measure=plain.mesh.cell_data["Volume"].sum(), measure_tolerance=0.02)
    assert optimized.mesh.cell_data["MinDihedralAngle"].min() >= 15.0 > plain.mesh.cell_data["MinDihedralAngle"].min()
    assert "optimize" in optimized.seconds


def test_labelled_contours_mesh_the_same_twice(shell):
    points, labels, slices = shell
    meshes = [run_labelled(points, labels, domain=SHELL_DOMAIN, base_plane=BASE, slices=slices,
                           biting=BitingParameters(cells=3000, seed=4)).mesh for _ in range(2)]
    assert np.array_equal(meshes[0].points, meshes[1].points) and np.array_equal(meshes[0].cells, meshes[1].cells)
    assert set(meshes[0].cell_data) == {"RadiusRatio", "MinDihedralAngle", "MaxDihedralAngle", "Volume", "Region"}


def test_every_labelled_parameter_reaches_the_fit_with_the_dataclass_default():
    """LabelledParameters is the one source of the contour fit's options: each field is a keyword of run_labelled
    or of labelled_implicit, and the fit's own defaults are the dataclass's; a length left automatic (None) is not
    passed, so that the fit's default (an adult heart's mm) stands."""
    import inspect

    from bitemesh.core.sources.contours.cardiac import RV_WALL
    from bitemesh.core.sources.contours.fit import labelled_implicit
    from bitemesh.core.sources.contours.run import labelled_keywords, run_labelled
    from bitemesh.core.sources.contours.surface_fit import OFFSET
    from bitemesh.core.parameters import LabelledParameters
    fit = inspect.signature(labelled_implicit).parameters
    run = inspect.signature(run_labelled).parameters
    keywords = labelled_keywords(LabelledParameters())
    assert all(name in fit or name in run for name in keywords)
    for name in ("kernel", "smoothing", "base_offset", "resolution", "base_plane"):
        assert fit[name].default == getattr(LabelledParameters, name), name
    assert (fit["offset"].default, fit["rv_wall"].default) == (OFFSET, RV_WALL)
    assert not {"offset", "rv_wall", "resolution", "min_wall"} & set(keywords)
    assert labelled_keywords(LabelledParameters(domain=" ", base_plane="none", allow_implausible=1)) == {
        **keywords, "domain": None, "base_plane": None, "allow_implausible": True}
    assert labelled_keywords(LabelledParameters(offset=4.0), given_only=True) == {"offset": 4.0}


@pytest.mark.parametrize("given", [{}, {"offset": 4.0, "rv_wall": 3.0}], ids=["defaults", "given-at-the-defaults"])
def test_a_small_hearts_lengths_are_its_own_when_given_even_at_the_defaults(monkeypatch, gpfile, given):
    """A heart smaller than an adult's is fitted in a frame scaled up to an adult's size: the default lengths are an
    adult's mm there (absent, the fit's own), a length the user gives is in the input's mm, even the default's
    value."""
    from bitemesh.core.sources.contours import run
    from bitemesh.io.contours import read_labelled_points

    points, labels, slices = read_labelled_points(gpfile)
    seen = {}

    def fit(*args, **keywords):
        seen.update(keywords)
        raise RuntimeError("captured")

    monkeypatch.setattr(run, "labelled_implicit", fit)
    with pytest.raises(RuntimeError, match="captured"):
        run.labelled_source(points * 0.4, labels, slices=slices, **given)
    scale = seen["reported_scale"]
    assert scale < 0.6   # the shipped heart spans 199 mm: 0.4 of it, 80 mm, is 0.57 the smallest adult's 140
    if given:
        assert seen["offset"] == pytest.approx(4.0 / scale) and seen["rv_wall"] == pytest.approx(3.0 / scale)
    else:
        assert "offset" not in seen and "rv_wall" not in seen
