"""Rule-based myocardial fibres (bitemesh.core.fem.fibres, Bayer et al. 2012): the frames' algebra, the four Laplace
problems, and the helix angle across the LV free wall of the two-cavity shell and (slow) the real heart, measured
in the geometry's frame (tests/fibrecheck.py)."""
from __future__ import annotations

import re

import numpy as np
import pytest
from bitemesh.core.sources.contours.run import run_labelled
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.fem.fibres import (FIBRE_ARRAYS, LAPLACE_ARRAYS, SURFACES, FibreParameters, axis, bislerp,
                                  fibre_field, helix_angles, orient, quaternions, rotations, with_fibres)
from bitemesh.core.mesh.simplicial import Mesh
from bitemesh.core.parameters import BitingParameters
from bitemesh.io import read_labelled_points

from tests.builders import cube_mesh
from tests.cardiac_variants import LEFT_VENTRICLE
from tests.fibrecheck import check_frames, check_free_wall, tagged_nodes, tagged_shell


@pytest.fixture(scope="module")
def shell():
    return tagged_shell()


@pytest.fixture(scope="module")
def shell_fibres(shell):
    return fibre_field(shell)


def random_rotations(count, seed=0):
    q = np.random.default_rng(seed).normal(size=(count, 4))
    return rotations(q / np.linalg.norm(q, axis=1, keepdims=True))


# --- the frames' algebra --------------------------------------------------------------------------------------------

def test_quaternions_and_rotation_matrices_round_trip():
    # random rotations, and half turns about each axis (1 + trace = 0: Shepperd's other rows)
    frames = np.concatenate([random_rotations(500), np.diag([1.0, -1, -1])[None], np.diag([-1.0, 1, -1])[None],
                             np.diag([-1.0, -1, 1])[None]])
    q = quaternions(frames)
    assert np.allclose(np.linalg.norm(q, axis=1), 1)
    assert np.allclose(rotations(q), frames, atol=1e-12)


def test_orient_turns_the_fibre_by_alpha_and_the_sheet_by_beta():
    frames = random_rotations(50)
    alpha, beta = np.linspace(-80, 80, 50), np.linspace(70, -70, 50)
    turned = orient(frames, alpha, beta)
    assert np.allclose(helix_angles(turned[:, :, 0], frames), alpha)
    e_c, e_l, e_t = (frames[:, :, k] for k in range(3))
    a, b = np.radians(alpha)[:, None], np.radians(beta)[:, None]
    assert np.allclose(turned[:, :, 1], np.cos(b) * (np.cos(a) * e_l - np.sin(a) * e_c) - np.sin(b) * e_t)
    check_frames(*(turned[:, :, k] for k in range(3)))


def test_axis_makes_a_right_handed_frame_even_from_parallel_or_zero_directions():
    longitudinal = np.array([[0.0, 0, 2], [0, 0, 1], [0, 0, 0], [1, 1, 0]])
    transmural = np.array([[3.0, 0, 1], [0, 0, 5], [1, 0, 0], [0, 0, 0]])
    frames = axis(longitudinal, transmural)
    assert np.allclose(frames[0], [[0, 0, 1], [1, 0, 0], [0, 1, 0]])   # e_C = e_L x e_T, e_T made orthogonal
    check_frames(*(frames[:, :, k] for k in range(3)))


def test_bislerp_runs_from_one_frame_to_the_other_and_ignores_the_axes_signs():
    a, b = quaternions(random_rotations(40, seed=1)), quaternions(random_rotations(40, seed=2))
    zeros, ones = np.zeros(40), np.ones(40)

    def lines(q):   # each axis as a line: the outer products of the columns
        frame = rotations(q)
        return np.einsum("mik,mjk->mkij", frame, frame)

    assert np.allclose(lines(bislerp(a, b, zeros)), lines(a)) and np.allclose(lines(bislerp(a, b, ones)), lines(b))
    w, x, y, z = a.T
    flipped = np.stack([-x, w, z, -y], axis=1)          # a i: the sheet and the sheet normal reversed
    assert np.allclose(lines(bislerp(a, flipped, np.full(40, 0.5))), lines(a))
    halfway = rotations(bislerp(a, b, np.full(40, 0.5)))
    check_frames(*(halfway[:, :, k] for k in range(3)))


# --- the Laplace problems -----------------------------------------------------------------------------------------

def test_the_laplace_solutions_take_their_dirichlet_values_and_stay_within_0_and_1(shell, shell_fibres):
    solutions = shell_fibres.laplace
    nodes = {name: tagged_nodes(shell, name) for name in SURFACES}
    owner = np.full(len(shell.points), -1)
    for number, name in enumerate(SURFACES[:3]):   # a node on two surfaces is the later one's
        owner[nodes[name]] = number
    for number, array in enumerate(LAPLACE_ARRAYS[1:]):
        assert np.array_equal(solutions[array][owner >= 0], (owner[owner >= 0] == number).astype(float)), array
    psi = solutions["Psi"]
    assert (psi[nodes["BASE"]] == 1).all() and psi[shell_fibres.apex] == 0
    # P1 keeps the maximum principle only on meshes without obtuse dihedral angles; a mesh's few obtuse cells may
    # let a solution overshoot by up to about half a percent (0.55 % on the 30k-cell plain heart)
    for values in solutions.values():
        assert -0.01 <= values.min() and values.max() <= 1.01
    total = solutions["PhiEpi"] + solutions["PhiLV"] + solutions["PhiRV"]
    assert np.abs(total - 1).max() < 1e-8   # the three transmural problems sum to 1 (CG to 1e-10)
    # the apex: the EPI node farthest below the base, the bottom of the outer ellipsoid (0, 0, -80)
    assert shell_fibres.apex in nodes["EPI"]
    assert np.linalg.norm(shell.points[shell_fibres.apex] - [0, 0, -80]) < 5.0
    assert all(solve.residual < 1e-9 for solve in shell_fibres.solves)


# --- the fibres ---------------------------------------------------------------------------------------------------

def test_the_fibre_frames_are_unit_orthogonal_and_right_handed(shell_fibres):
    check_frames(shell_fibres.fibre, shell_fibres.sheet, shell_fibres.sheet_normal)
    assert np.isfinite(shell_fibres.helix_angle).all() and np.abs(shell_fibres.helix_angle).max() <= 90


@pytest.mark.parametrize("angles", [{}, dict(alpha_endo=60.0, alpha_epi=-60.0, beta_endo=0.0, beta_epi=0.0)],
                         ids=["paper", "60-60-no-sheet-angle"])
def test_the_helix_angle_falls_from_endo_to_epi_across_the_lv_free_wall(shell, angles):
    """Six wall-normal lines across the LV free wall, two to three cells each (their phi_epi from at most 0.3 to
    at least 0.7); the helix angle within 8 degrees of the rule's (the geometry's frame, straight lines and the
    long axis, differs from the Laplace one by up to 6 degrees, measured on this shell and the real heart)."""
    parameters = FibreParameters(**angles)
    profiles = check_free_wall(shell, fibre_field(shell, parameters), parameters)
    assert len(profiles) == 6 and all(len(depths) >= 3 for depths, _ in profiles)


def test_the_same_mesh_gives_the_same_fibres_bit_for_bit(shell, shell_fibres):
    again = fibre_field(Mesh(shell.points.copy(), shell.cells.copy(), {}, shell.facets.copy(),
                             shell.facet_tags.copy(), dict(shell.tag_names)))
    for name in ("fibre", "sheet", "sheet_normal", "helix_angle"):
        assert np.array_equal(getattr(again, name), getattr(shell_fibres, name)), name
    assert all(np.array_equal(again.laplace[name], shell_fibres.laplace[name]) for name in LAPLACE_ARRAYS)


def test_with_fibres_adds_the_cell_arrays_and_keeps_the_tags(shell, shell_fibres):
    mesh, seconds = with_fibres(shell)
    m = len(shell.cells)
    assert [mesh.cell_data[name].shape for name in FIBRE_ARRAYS] == [(m, 3), (m, 3), (m, 3), (m,)]
    for name in LAPLACE_ARRAYS:   # the Laplace solutions, as point arrays (bitemesh mesh --fibres writes them)
        np.testing.assert_array_equal(mesh.point_data[name], shell_fibres.laplace[name])
    assert mesh.facets is shell.facets and mesh.tag_names == shell.tag_names and seconds > 0


# --- refusals -------------------------------------------------------------------------------------------------------

def test_a_mesh_without_the_heart_surfaces_is_refused_naming_them(shell):
    with pytest.raises(InvalidInputError, match=r"needs? the boundary surfaces EPI, LV_ENDO, RV_ENDO, BASE \(a "
                                                r"biventricular heart\) or EPI, ENDO and BASE \(a left ventricle\) "
                                                r".* it has no EPI, LV_ENDO, RV_ENDO, BASE \(its facet tags: none\); "
                                                r"mesh labelled heart contours"):
        fibre_field(cube_mesh())
    keep = shell.facet_tags != shell.tag_names["RV_ENDO"][0]
    names = {name: value for name, value in shell.tag_names.items() if name != "RV_ENDO"}
    with pytest.raises(InvalidInputError, match=r"has no RV_ENDO \(its facet tags: BASE, EPI, LV_ENDO\)"):
        fibre_field(shell.with_tags(shell.facets[keep], shell.facet_tags[keep], names))
    with pytest.raises(InvalidInputError, match="tetrahedral mesh; this mesh is 2D"):
        fibre_field(Mesh(np.zeros((3, 2)), np.array([[0, 1, 2]])))


@pytest.mark.parametrize("name", ["alpha_endo", "alpha_epi", "beta_endo", "beta_epi"])
def test_an_angle_beyond_a_quarter_turn_is_refused_naming_it(name):
    with pytest.raises(InvalidInputError, match=name):
        FibreParameters(**{name: 91.0})


# --- the real heart -------------------------------------------------------------------------------------------------

def test_a_left_ventricle_is_tagged_as_cardiac_geometries_tags_it_and_gets_fibres(gpfile):
    """biv-me patient 1's LV contours alone (about 6,000 cells): cardiac-geometries' LV names and numbers (what
    ldrb and fenicsx-pulse read: EPI 7, ENDO 6, BASE 5, MYOCARDIUM 8), three Laplace problems (phi_rv = 0), and
    across the free wall all around the LV the helix angle falls from endo to epi as the rule says (the shell's
    bounds: the geometry's frame)."""
    points, labels, slices = read_labelled_points(gpfile)
    lv = np.isin(labels, LEFT_VENTRICLE)
    mesh = run_labelled(points[lv], labels[lv], slices=slices[lv], biting=BitingParameters(cells=8000)).mesh
    assert mesh.tag_names == {"EPI": (7, 2), "ENDO": (6, 2), "BASE": (5, 2), "MYOCARDIUM": (8, 3)}
    assert sorted(np.unique(mesh.facet_tags)) == [5, 6, 7] and (mesh.cell_data["Region"] == 8).all()
    field = fibre_field(mesh)
    assert len(field.solves) == 3 and not field.laplace["PhiRV"].any()
    check_frames(field.fibre, field.sheet, field.sheet_normal)
    profiles = check_free_wall(mesh, field, FibreParameters(), depth=0.35)
    # R about 4.4 mm, the LV wall two or three cells across: a line crosses two cells at least (137.7 ml of wall)
    assert len(profiles) == 6 and all(len(depths) >= 2 for depths, _ in profiles)


@pytest.mark.slow
def test_a_wall_one_cell_thick_is_warned_with_a_hint_that_clears_it(gpfile):
    """biv-me patient1 at 20,000 cells (R about 3.7 mm): most cells on RV_ENDO reach the epicardium (the RV free
    wall is 3-4 mm), so --fibres warns, naming the wall and the radius; at the hint's radius it does not."""
    import warnings

    from bitemesh import BitemeshWarning, mesh

    with pytest.warns(BitemeshWarning, match=r"--fibres: the wall under RV_ENDO is about one cell thick") as found:
        mesh(gpfile, cells=20000, optimize=0, fibres=1)
    message = next(str(item.message) for item in found if "one cell thick" in str(item.message))
    hint = float(re.search(r"--radius (\d+\.?\d*)", message).group(1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mesh(gpfile, radius=hint, optimize=0, fibres=1)
    assert not [w for w in caught if "one cell thick" in str(w.message)]
