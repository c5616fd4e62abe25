"""Implicit reconstruction (section 4.1): MPU and RBF signs and distances, normal estimation and checks, the step."""
from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from bitemesh.core.errors import Cancelled, InvalidInputError
from bitemesh.core.implicit.rbf import MAX_RBF_POINTS, RBFImplicit, fit_rbf
from bitemesh.core.implicit.mpu_function import MPUImplicit
from bitemesh.core.implicit.normals import check_normals, estimate_normals
from bitemesh.core.implicit.fit import fit_implicit
from bitemesh.core.implicit.mpu import fit_mpu
from bitemesh.core.sources.points import points_to_implicit
from bitemesh.core.shapes import sample_surface, torus


def sphere_sample(count, *, radius=1.0, noise=0.0, seed=0):
    """Points uniform on a sphere, their outward normals, and the noise-free points."""
    rng = np.random.default_rng(seed)
    normals = rng.normal(size=(count, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    clean = radius * normals
    return clean + noise * radius * rng.normal(size=clean.shape), normals, clean


def torus_sample(count, *, major=1.0, minor=0.35, seed=0):
    """Points uniform on a torus around the z axis (rejection on the area element) and outward normals."""
    rng = np.random.default_rng(seed)
    u, v = rng.uniform(0, 2 * np.pi, (2, 4 * count))
    keep = rng.uniform(size=4 * count) < (major + minor * np.cos(v)) / (major + minor)
    u, v = u[keep][:count], v[keep][:count]
    normals = np.stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)], axis=1)
    centre = major * np.stack([np.cos(u), np.sin(u), np.zeros_like(u)], axis=1)
    return centre + minor * normals, normals


def rounded_cube_sample(count, *, rounding=0.05, seed=0):
    """Points on the cube [-1, 1]^3 with edges and corners rounded by ``rounding``, and outward normals."""
    rng = np.random.default_rng(seed)
    face = rng.integers(0, 6, count)
    on_cube = rng.uniform(-1, 1, (count, 3))
    on_cube[np.arange(count), face % 3] = np.where(face < 3, -1.0, 1.0)
    core = np.clip(on_cube, -1 + rounding, 1 - rounding)
    normals = on_cube - core
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return core + rounding * normals, normals


def agreement(estimated, true):
    return np.mean(np.einsum("ij,ij->i", estimated, true) > 0.9)


@pytest.fixture(scope="module", params=["given normals", "estimated normals", "noisy"])
def sphere_fit(request):
    points, normals, clean = sphere_sample(3000, noise=0.002 if request.param == "noisy" else 0.0)
    if request.param != "given normals":
        normals = estimate_normals(points)
    return fit_mpu(points, normals), clean


# --- MPU -----------------------------------------------------------------------------------------------------------

def test_sphere_is_signed_distance_near_the_surface(sphere_fit):
    f, clean = sphere_fit
    assert np.abs(f(clean)).max() < 0.01
    centre = f(np.zeros((1, 3)))[0]
    assert 0.9 < centre < 1.1
    directions = sphere_sample(50, seed=5)[1]
    assert np.allclose(f(1.2 * directions), -0.2, atol=0.04)
    assert np.allclose(f(0.8 * directions), 0.2, atol=0.04)
    far = np.array([[10.0, 0, 0], [0, -10, 0], [3, 3, 3], [0, 0, 1.5]])
    assert (f(far) < 0).all()
    assert f(far)[0] < -8


def test_sphere_gradient_matches_finite_differences(sphere_fit):
    f, _ = sphere_fit
    rng = np.random.default_rng(1)
    directions = sphere_sample(40, seed=2)[1]
    # Stay clear of the bounding-box faces, where f is clamped by the (kinked) box depth.
    directions = directions[np.abs(directions).max(axis=1) < 0.8]
    x = rng.uniform(0.3, 1.05, (len(directions), 1)) * directions
    step = 1e-6
    numeric = np.stack([(f(x + step * e) - f(x - step * e)) / (2 * step) for e in np.eye(3)], axis=1)
    assert np.allclose(f.gradient(x), numeric, atol=1e-4)
    # Near the surface the gradient is the inward unit normal (f is about the signed distance).
    surface = 0.99 * directions
    assert np.allclose(f.gradient(surface), -directions, atol=0.1)


def test_torus_signs():
    points, normals = torus_sample(4000)
    f = fit_mpu(points, normals)
    tube, hole, above, beside = f(np.array([[1.0, 0, 0], [0, 0, 0], [0, 0, 1.0], [0, 1.5, 0]]))
    assert 0.3 < tube < 0.4
    assert -0.75 < hole < -0.55
    assert above < 0 and beside < 0


def test_rounded_cube_signs_at_centre_and_corners():
    points, normals = rounded_cube_sample(5000)
    f = fit_mpu(points, normals)
    assert 0.9 < f(np.zeros((1, 3)))[0] < 1.1
    corners = 0.999 * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    assert (f(corners) < 0).all()                    # 0.035 outside the rounded corner
    assert (f(0.9 * corners) > 0).all()
    assert np.abs(f(points)).max() < 0.02            # error bound 0.005 x diagonal = 0.017


def test_fit_mpu_refuses_bad_arguments():
    points, normals, _ = sphere_sample(100)
    with pytest.raises(InvalidInputError, match="normals"):
        fit_mpu(points, normals[:50])
    with pytest.raises(InvalidInputError, match="error_bound"):
        fit_mpu(points, normals, error_bound=0)
    with pytest.raises(InvalidInputError, match="points"):
        fit_mpu(points[:, :2], normals[:, :2])


# --- normals -------------------------------------------------------------------------------------------------------

def test_estimated_normals_point_outward_on_sphere_and_torus():
    points, normals, _ = sphere_sample(3000)
    assert agreement(estimate_normals(points), normals) > 0.98
    points, normals = torus_sample(4000)
    assert agreement(estimate_normals(points), normals) > 0.98


def test_hollow_shell_inner_normals_point_into_the_cavity():
    outer, outer_normals, _ = sphere_sample(3000, seed=1)
    inner, inner_normals, _ = sphere_sample(1000, radius=0.5, seed=2)
    estimated = estimate_normals(np.vstack([outer, inner]))
    assert agreement(estimated[:3000], outer_normals) > 0.98
    assert agreement(estimated[3000:], -inner_normals) > 0.98
    f = fit_mpu(np.vstack([outer, inner]), estimated)
    cavity, wall, outside = f(np.array([[0, 0, 0], [0.75, 0, 0], [0, 0, 1.3]]))
    assert cavity < 0 < wall and outside < 0


def test_ball_in_the_hole_of_a_torus_is_not_a_cavity():
    torus, torus_normals = torus_sample(4000)
    ball, ball_normals, _ = sphere_sample(500, radius=0.25, seed=3)
    estimated = estimate_normals(np.vstack([torus, ball]))
    assert agreement(estimated[:4000], torus_normals) > 0.98
    assert agreement(estimated[4000:], ball_normals) > 0.98


def test_two_spheres_in_contact_take_their_signs_from_their_own_sides():
    """Two unit spheres touching at the origin: their neighbour graphs join at the contact, where the sheets cannot
    be told apart; each sphere is oriented from its own part of the hull, so only points within a few sample
    spacings of the contact may be wrong (at most 2 %; before, one whole sphere pointed inward)."""
    points, normals, _ = sphere_sample(3000, seed=4)
    pair = np.vstack([points - [1, 0, 0], points + [1, 0, 0]])
    agree = np.einsum("ij,ij->i", estimate_normals(pair), np.vstack([normals, normals])) > 0
    assert agree.mean() > 0.98
    assert np.linalg.norm(pair[~agree], axis=1).max() < 0.4


def test_estimate_normals_refuses_what_it_cannot_orient():
    rng = np.random.default_rng(0)
    flat = np.c_[rng.uniform(size=(100, 2)), np.zeros(100)]
    with pytest.raises(InvalidInputError, match="points.*plane"):
        estimate_normals(flat)
    with pytest.raises(InvalidInputError, match="too few.*normals"):
        estimate_normals(rng.uniform(size=(12, 3)))
    line_pieces = np.repeat(rng.uniform(size=(4, 3)), 40, axis=0)
    line_pieces[:, 0] += np.tile(np.linspace(0, 0.01, 40), 4)
    with pytest.raises(InvalidInputError, match="one line"):
        estimate_normals(line_pieces)


def test_check_normals_flips_inward_normals_back_with_a_warning(caplog):
    points, normals, _ = sphere_sample(500)
    with caplog.at_level(logging.WARNING, logger="bitemesh"):
        fixed = check_normals(points, -3.0 * normals)
    assert np.allclose(fixed, normals)
    assert "inward" in caplog.text


def test_check_normals_accepts_sharp_cube_edges_and_thin_walls():
    # An exact cube: across its edges neighbouring normals differ by 90 degrees.
    points, normals = rounded_cube_sample(3000, rounding=1e-9)
    assert np.allclose(check_normals(points, normals), normals)
    # A slab 0.05 thick sampled at about 0.04: neighbours across the wall point the other way.
    rng = np.random.default_rng(0)
    top = np.c_[rng.uniform(-1, 1, (1500, 2)), np.full(1500, 0.025)]
    slab = np.vstack([top, top * [1, 1, -1]])
    slab_normals = np.repeat([[0, 0, 1.0], [0, 0, -1.0]], 1500, axis=0)
    assert np.allclose(check_normals(slab, slab_normals), slab_normals)


def test_check_normals_refuses_inconsistent_and_invalid_normals():
    points, normals, _ = sphere_sample(1000)
    random_signs = normals * np.random.default_rng(0).choice([-1.0, 1.0], size=(1000, 1))
    with pytest.raises(InvalidInputError, match="inconsistent.*omit normals"):
        check_normals(points, random_signs)
    broken = normals.copy()
    broken[17] = np.nan
    with pytest.raises(InvalidInputError, match="normals.*row 17"):
        check_normals(points, broken)
    broken[17] = 0.0
    with pytest.raises(InvalidInputError, match="normals.*zero-length.*row 17"):
        check_normals(points, broken)
    with pytest.raises(InvalidInputError, match="normals.*shape"):
        check_normals(points, normals[:, :2])


# --- RBF -----------------------------------------------------------------------------------------------------------

def annulus_contours():
    angle = np.linspace(0, 2 * np.pi, 80, endpoint=False)
    circle = np.c_[np.cos(angle), np.sin(angle)]
    return np.vstack([circle, 0.5 * circle[::2]]), np.vstack([circle, -circle[::2]])


def test_rbf_annulus_signs_with_and_without_normals():
    points, normals = annulus_contours()
    probes = np.array([[0, 0], [0.75, 0], [0, -0.75], [1.2, 0], [5, 5]])
    for given_normals in (normals, None):
        grid = points_to_implicit(points, given_normals, method="rbf", grid_spacing=0.02, cells=1000)
        assert np.array_equal(np.sign(grid.evaluate(probes)), [-1, 1, 1, -1, -1])
    f = fit_rbf(points, normals)
    assert np.abs(f(points)).max() < 1e-6
    assert np.array_equal(np.sign(f(probes)), [-1, 1, 1, -1, -1])
    assert f(np.array([[0.0, 30.0]]))[0] == pytest.approx(-29.0)   # clamped: minus the distance to the box


def test_rbf_on_patches_interpolates_and_follows_the_distance_in_2d_and_3d():
    """Beyond PATCH_CENTRES constraints (400 points) the RBF is fitted on patches, a quadtree's in 2D and an octree's
    in 3D, blended by the partition of unity.  Each patch interpolates the constraints in its ball, so the blend
    does: f = 0 at the points (to the solve's residual); near the surface f is about the signed distance (its
    values at the off-surface points are +/- their distance), and the gradient is f's."""
    from bitemesh.core.shapes import annulus, sample_surface
    points, normals, _ = sphere_sample(3000)
    calls = []
    f = fit_rbf(points, normals, progress=lambda fraction, message: calls.append(fraction))
    assert len(f.patches) > 8 and np.abs(f(points)).max() < 1e-6
    assert calls[-1] == 1.0 and calls == sorted(calls)
    directions = sphere_sample(500, seed=1)[1]
    for radius in (0.9, 0.98, 1.02, 1.1):
        np.testing.assert_allclose(f(radius * directions), 1 - radius, rtol=0, atol=0.005)
    shape = annulus()
    flat_points, flat_normals = sample_surface(shape, 0.005, seed=1)
    flat = fit_rbf(flat_points, flat_normals)
    assert len(flat.patches) > 1 and np.abs(flat(flat_points)).max() < 1e-6
    probes = np.random.default_rng(2).uniform(-1, 1, (4000, 2))
    distance = shape.function(probes)
    near = np.abs(distance) < 0.05   # ten point spacings, twenty off-surface offsets (0.0025)
    assert np.all(np.abs(flat(probes[near]) - distance[near]) <= 0.15 * np.abs(distance[near]) + 2e-4)
    for function, x in ((f, 0.7 * directions[:40]), (f, 1.5 * directions[:40]), (flat, probes[:40])):
        step = np.eye(x.shape[1]) * 1e-6
        central = np.stack([(function(x + e) - function(x - e)) / 2e-6 for e in step], axis=1)
        np.testing.assert_allclose(function.gradient(x), central, rtol=0, atol=1e-4)

    def cancel(fraction, message):
        if fraction > 0.5:
            raise Cancelled("stop")
    with pytest.raises(Cancelled):
        fit_rbf(points, normals, progress=cancel)


def test_rbf_refuses_too_many_points():
    points, normals, _ = sphere_sample(MAX_RBF_POINTS + 1)
    with pytest.raises(InvalidInputError, match="method.*mpu"):
        fit_rbf(points, normals)


# --- the step ------------------------------------------------------------------------------------------------------

def test_points_to_implicit_grid_follows_the_documented_defaults():
    """The grid I of run: spacing R / 4 for R chosen for the cells (at least 1/40 of the box's side), and a
    margin of 3 spacings around the points' box."""
    from bitemesh.core.sources.points import run
    points, normals, _ = sphere_sample(2000)
    lower, upper = points.min(axis=0), points.max(axis=0)
    grid = points_to_implicit(points, normals)
    radius = run(points, normals).radius
    spacing = min(radius / 4, float(np.max(upper - lower)) / 40)
    assert np.allclose(grid.spacing, spacing, rtol=1e-9)
    assert np.allclose(grid.origin, lower - 3 * spacing, rtol=0, atol=1e-9)
    assert grid.evaluate(np.zeros((1, 3)))[0] > 0.9
    assert (grid.values[0] < 0).all() and (grid.values[-1] < 0).all()
    custom = points_to_implicit(points, normals, grid_spacing=0.05, margin=0.25)
    assert np.allclose(custom.spacing, 0.05) and np.allclose(custom.origin, lower - 0.25)


def test_points_to_implicit_drops_duplicates_and_reports_progress():
    points, normals, _ = sphere_sample(1000)
    calls = []
    grid = points_to_implicit(points, normals, grid_spacing=0.1, cells=1000,
                              progress=lambda f, m: calls.append(f))
    doubled = points_to_implicit(np.vstack([points, points[:300]]), np.vstack([normals, normals[:300]]),
                                 grid_spacing=0.1, cells=1000)
    assert np.array_equal(grid.values, doubled.values)
    assert calls[-1] == 1.0 and calls == sorted(calls)

    def cancel(fraction, message):
        if fraction > 0.5:
            raise Cancelled("stop")
    with pytest.raises(Cancelled):
        points_to_implicit(points, normals, grid_spacing=0.02, progress=cancel)


def test_fit_implicit_returns_the_function_that_points_to_implicit_samples():
    points, normals, _ = sphere_sample(1000)
    f = fit_implicit(np.vstack([points, points[:10]]), method="mpu")
    assert isinstance(f, MPUImplicit) and len(f.points) == 1000
    grid = points_to_implicit(points, normals, grid_spacing=0.1, cells=1000)
    nodes = grid.node_coordinates(np.arange(grid.values.size))
    exact = fit_implicit(points, normals)(nodes)
    near = np.abs(exact) < 0.2  # sampled exactly near f = 0 (EXACT_WITHIN grid spacings), interpolated beyond
    np.testing.assert_allclose(grid.values.ravel()[near], exact[near], rtol=0, atol=1e-12)
    signed = np.abs(exact) > 1e-12   # a node on a sample has f = 0 to rounding (the grid fits centred points)
    assert np.array_equal(grid.values.ravel()[signed] > 0, exact[signed] > 0)
    contours, contour_normals = annulus_contours()
    assert isinstance(fit_implicit(contours, contour_normals, method="rbf"), RBFImplicit)


@pytest.mark.parametrize("points, words", [
    (np.zeros((0, 3)), "points.*at least 10"),
    (np.eye(5, 3), "points.*at least 10"),
    (np.r_[np.eye(3), [[np.nan, 0, 0]], np.ones((20, 3))], "points.*NaN"),
    (np.c_[np.random.default_rng(0).uniform(size=(50, 2)), np.full(50, 2.0)], "points.*plane"),
    (np.c_[np.linspace(0, 1, 50), np.linspace(1, 3, 50)], "one line"),
], ids=["empty", "5 points", "NaN", "coplanar", "a line in 2D"])
def test_points_to_implicit_refuses_bad_points(points, words):
    with pytest.raises(InvalidInputError, match=words):
        points_to_implicit(points)


def test_mpu_given_for_2d_points_is_refused_and_auto_fits_them():
    """MPU is 3D only: given for a circle's points, refused naming rbf; the default (auto) fits them by RBFs."""
    angle = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    circle = np.c_[np.cos(angle), np.sin(angle)]
    with pytest.raises(InvalidInputError, match="method 'mpu' needs 3D points.*rbf"):
        points_to_implicit(circle, method="mpu")
    assert isinstance(fit_implicit(circle), RBFImplicit)


def test_points_to_implicit_refuses_collinear_2d_points_and_bad_options():
    line = np.c_[np.linspace(0, 1, 50), np.linspace(1, 3, 50)]
    with pytest.raises(InvalidInputError, match="points.*line"):
        points_to_implicit(line, method="rbf")
    points, normals, _ = sphere_sample(200)
    with pytest.raises(InvalidInputError, match="method"):
        points_to_implicit(points, normals, method="poisson")
    with pytest.raises(InvalidInputError, match="grid_spacing.*max_memory_mb"):
        points_to_implicit(points, normals, grid_spacing=0.001, max_memory_mb=64)
    with pytest.raises(InvalidInputError, match="margin"):
        points_to_implicit(points, normals, margin=-1)


@settings(max_examples=10, deadline=None)
@given(rotation=st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1),
       shift=st.lists(st.floats(-100, 100), min_size=3, max_size=3))
def test_rigid_motions_keep_the_signs(rotation, shift):
    points, _, _ = sphere_sample(1500, seed=4)
    moved = Rotation.from_quat(rotation).apply(points) + shift
    f = fit_mpu(moved, estimate_normals(moved))
    far = np.array(shift) + [[5.0, 0, 0], [0, 0, -5], [-3, 3, 3]]
    assert f(np.array([shift], dtype=float))[0] > 0.9
    assert (f(far) < 0).all()


@pytest.mark.parametrize("jitter", [1e-5, 1e-4])
def test_copies_of_a_scan_give_the_normals_of_one(jitter):
    """A torus scan repeated 5 times, each copy moved by a Gaussian jitter of ``jitter`` x its size (scans merged
    from several passes): the estimated normals are the outward ones wherever one copy's are (every point's 12
    neighbours had been copies of two or three positions, and the normals across the hole came out at random:
    meshes with a filled hole or two handles).  At 1e-3 of the size (6 % of the sample spacing) the copies are
    noise more than copies: a third of them are grouped, 99 % of the normals agree, and the mesh is the torus."""
    points, normals = sample_surface(torus(), 0.05)
    rng = np.random.default_rng(5)
    copies = np.vstack([points + rng.normal(scale=jitter * 2.8, size=points.shape) for _ in range(5)])
    alone = np.einsum("ij,ij->i", estimate_normals(points), normals) > 0.5
    agree = np.einsum("ij,ij->i", estimate_normals(copies), np.tile(normals, (5, 1))) > 0.5
    assert agree.mean() >= alone.mean() - 0.01, (agree.mean(), alone.mean())


def test_rbf_near_points_solves_only_their_patches_and_gives_the_whole_functions_values():
    """fit_partition(near=q) solves only the patches the evaluation at q takes (the balls holding a point of q, and
    each point's nearest patch): f there is the whole function's, bit for bit (the contradicted contours' refits
    need f at one slice only)."""
    from bitemesh.core.implicit.rbf import fit_partition
    points, normals, _ = sphere_sample(3000)
    constraints = np.vstack([points, 0.9 * points, 1.1 * points])
    values = np.r_[np.zeros(3000), np.full(3000, 0.1), np.full(3000, -0.1)]
    whole = fit_partition(constraints, values, kernel="linear", frame=(np.zeros(3), 2.0), what="test")
    cap = points[points[:, 2] > 0.9]
    beyond = np.array([[0.0, 0.0, -30.0]])   # beyond every ball, below: its nearest patch alone
    near = np.vstack([cap, beyond])
    part = fit_partition(constraints, values, kernel="linear", frame=(np.zeros(3), 2.0), what="test", near=near)
    assert 0 < len(part.patches) < len(whole.patches) / 2
    assert np.array_equal(part(near), whole(near)) and np.array_equal(part.gradient(near), whole.gradient(near))
