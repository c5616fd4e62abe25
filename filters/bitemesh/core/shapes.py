"""Analytic shapes with known answers: the demo's die, and the shapes of the tests and benchmarks.

Each shape is an implicit function (f > 0 inside, close to signed distance near f = 0) with its bounding box,
its exact measure (volume, or area in 2D) and the Euler characteristic of its boundary.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.spatial.distance import cdist


@dataclass(frozen=True)
class Shape:
    """An analytic domain.

    Attributes
    ----------
    name : short name
    function : maps (m, k) points to (m,) values of f, f > 0 inside
    lower, upper : (k,) corners of a box holding the shape
    measure : exact volume (3D) or area (2D)
    boundary_euler : Euler characteristic of the boundary (2 per sphere-like surface, 0 per torus)
    """

    name: str
    function: Callable[[np.ndarray], np.ndarray]
    lower: tuple
    upper: tuple
    measure: float
    boundary_euler: int

    @property
    def dim(self) -> int:
        return len(self.lower)

    def gradient(self, points: np.ndarray, step: float = 1e-6) -> np.ndarray:
        """(m, k) central-difference gradient of f."""
        offsets = np.eye(self.dim) * step
        return np.stack([(self.function(points + e) - self.function(points - e)) / (2 * step) for e in offsets],
                        axis=1)


def ball_distance(points, centre, radius) -> np.ndarray:
    """Signed distance to a ball (or disk), positive inside."""
    return radius - np.linalg.norm(points - np.asarray(centre, float), axis=1)


def ellipsoid_distance(points, centre, semi_axes) -> np.ndarray:
    """Approximate signed distance to an ellipsoid, positive inside (exact on the surface, first order near it)."""
    scaled = (points - np.asarray(centre, float)) / np.asarray(semi_axes, float)
    k0 = np.linalg.norm(scaled, axis=1)
    k1 = np.maximum(np.linalg.norm(scaled / np.asarray(semi_axes, float), axis=1), 1e-300)
    return -k0 * (k0 - 1.0) / k1


def sphere(radius: float = 1.0) -> Shape:
    return Shape("sphere", lambda p: ball_distance(p, np.zeros(3), radius), (-radius,) * 3, (radius,) * 3,
                 4 / 3 * np.pi * radius**3, 2)


def torus(major: float = 1.0, minor: float = 0.4) -> Shape:
    def function(p):
        ring = np.hypot(p[:, 0], p[:, 1]) - major
        return minor - np.hypot(ring, p[:, 2])
    reach = major + minor
    return Shape("torus", function, (-reach, -reach, -minor), (reach, reach, minor),
                 2 * np.pi**2 * major * minor**2, 0)


#: the die's pips: face value -> (axis, sign), and each face's spots (u, v) in units of 0.45 x the half-side
DIE_FACES = {1: (2, 1), 6: (2, -1), 2: (0, 1), 5: (0, -1), 3: (1, 1), 4: (1, -1)}
DIE_SPOTS = {1: [(0, 0)], 2: [(-1, -1), (1, 1)], 3: [(-1, -1), (0, 0), (1, 1)],
             4: [(-1, -1), (-1, 1), (1, -1), (1, 1)], 5: [(-1, -1), (-1, 1), (0, 0), (1, -1), (1, 1)],
             6: [(-1, -1), (-1, 0), (-1, 1), (1, -1), (1, 0), (1, 1)]}


def die_pip_centres(half: float = 1.0) -> np.ndarray:
    """(21, 3) centres of the die's pips, on its faces (half-side ``half``)."""
    centres = []
    for value, (axis, sign) in DIE_FACES.items():
        others = [a for a in range(3) if a != axis]
        for u, v in DIE_SPOTS[value]:
            centre = np.zeros(3)
            centre[axis] = sign * half
            centre[others] = np.array([u, v]) * 0.45 * half
            centres.append(centre)
    return np.array(centres)


def die(half: float = 1.0, rounding: float = 0.25, pip: float = 0.16) -> Shape:
    """The synthetic die of the paper's Figure 4: a rounded cube with spherical pips (dents) 1 to 6.

    The pips are hemispheres of radius ``pip`` centred on the faces, so each takes (2/3) pi pip^3 away.
    """
    centres = die_pip_centres(half)

    def function(p):
        q = np.abs(p) - (half - rounding)
        cube = rounding - np.linalg.norm(np.maximum(q, 0), axis=1) - np.minimum(q.max(axis=1), 0)
        dents = cdist(p, centres).min(axis=1) - pip
        return np.minimum(cube, dents)
    core = 2 * (half - rounding)
    rounded_cube = core**3 + 6 * core**2 * rounding + 3 * np.pi * rounding**2 * core + 4 / 3 * np.pi * rounding**3
    return Shape("die", function, (-half,) * 3, (half,) * 3,
                 rounded_cube - len(centres) * 2 / 3 * np.pi * pip**3, 2)


def two_cavity_shell() -> Shape:
    """A heart-like two-cavity shell: half an ellipsoid (z < 0) minus two half-ellipsoidal cavities open at z = 0.

    The cavities' centres lie on the base plane z = 0, so each removes exactly half its ellipsoid; the thinnest
    walls (septum, right free wall) are 0.23 thick.
    """
    outer, lv, rv = ((0.0, 0.0, 0.0), (1.0, 0.9, 1.6)), ((0.3, 0.0, 0.0), (0.4, 0.4, 1.2)), \
        ((-0.55, 0.0, 0.0), (0.22, 0.55, 1.0))

    def function(p):
        shell = np.minimum(ellipsoid_distance(p, *outer), -p[:, 2])
        return np.minimum(shell, np.minimum(-ellipsoid_distance(p, *lv), -ellipsoid_distance(p, *rv)))

    def half_volume(axes):
        return 2 / 3 * np.pi * np.prod(axes)

    return Shape("two-cavity shell", function, (-1.0, -0.9, -1.6), (1.0, 0.9, 0.0),
                 half_volume(outer[1]) - half_volume(lv[1]) - half_volume(rv[1]), 2)


#: the two-cavity heart's ellipsoids, (centre, semi-axes), and the height of its base plane
HEART_ELLIPSOIDS = dict(lv_outer=((0.0, 0.0, 0.0), (0.62, 0.62, 1.00)), lv_inner=((0.0, 0.0, 0.0), (0.45, 0.45, 0.84)),
                        rv_outer=((-0.40, 0.0, 0.05), (0.88, 0.74, 0.88)),
                        rv_inner=((-0.40, 0.0, 0.05), (0.78, 0.64, 0.78)))
HEART_BASE = 0.40


def two_cavity_heart() -> Shape:
    """The biventricular shape of the benchmarks: the union of an LV and an RV ellipsoid minus the two cavities, cut
    by a base plane through which both cavities open.

    LV outer semi-axes (0.62, 0.62, 1.00), inner (0.45, 0.45, 0.84), at the origin; RV outer (0.88, 0.74, 0.88),
    inner (0.78, 0.64, 0.78), at (-0.40, 0, 0.05), its cavity minus the LV outer ellipsoid (the septum is the LV
    wall); kept below z = 0.40.  The RV free wall is 0.10 thick, the LV wall 0.16-0.17.  Its volume, 1.01852, is
    from quasi-Monte Carlo integration (4 x 2^24 scrambled Sobol points, standard deviation 1e-5).
    """
    lv_outer, lv_inner, rv_outer, rv_inner = (HEART_ELLIPSOIDS[name] for name in
                                              ("lv_outer", "lv_inner", "rv_outer", "rv_inner"))

    def function(p):
        outer_lv = ellipsoid_distance(p, *lv_outer)
        rv_cavity = np.minimum(ellipsoid_distance(p, *rv_inner), -outer_lv)
        walls = np.minimum(np.maximum(outer_lv, ellipsoid_distance(p, *rv_outer)), -ellipsoid_distance(p, *lv_inner))
        return np.minimum(np.minimum(walls, -rv_cavity), HEART_BASE - p[:, 2])

    return Shape("two-cavity heart", function, (-1.28, -0.74, -1.0), (0.62, 0.74, 0.40), 1.01852, 2)


def annulus(outer: float = 1.0, inner: float = 0.4) -> Shape:
    """2D: a disk with a hole."""
    return Shape("annulus", lambda p: np.minimum(ball_distance(p, (0, 0), outer), -ball_distance(p, (0, 0), inner)),
                 (-outer,) * 2, (outer,) * 2, np.pi * (outer**2 - inner**2), 0)


def sample_surface(shape: Shape, spacing: float, *, noise: float = 0.0, seed: int = 0):
    """Scattered points on the boundary of ``shape``, about ``spacing`` apart, with outward normals.

    Random points in the box are moved onto f = 0 by Newton steps, then thinned to one per cell of a grid of
    ``spacing``.  ``noise`` is the standard deviation of a Gaussian displacement (input units).

    Returns
    -------
    points : (n, k) float64
    normals : (n, k) float64, unit, outward
    """
    rng = np.random.default_rng(seed)
    lower, upper = np.array(shape.lower, float), np.array(shape.upper, float)
    extent = upper - lower
    count = int(60 * np.prod(extent / spacing) ** ((shape.dim - 1) / shape.dim)) + 1000
    points = lower - 0.05 * extent + rng.random((count, shape.dim)) * 1.1 * extent
    points = points[np.abs(shape.function(points)) < 2 * spacing]
    moving = np.arange(len(points))
    for _ in range(12):   # Newton steps on the points not yet within 1e-10 x the extent of f = 0
        value = shape.function(points[moving])
        unsettled = np.abs(value) >= 1e-10 * np.max(extent)
        moving, value = moving[unsettled], value[unsettled]
        gradient = shape.gradient(points[moving])
        points[moving] -= (value / np.maximum(np.sum(gradient**2, axis=1), 1e-12))[:, None] * gradient
    points = points[np.abs(shape.function(points)) < 1e-7 * np.max(extent)]
    _, first = np.unique(np.floor(points / spacing).astype(np.int64), axis=0, return_index=True)
    points = points[np.sort(first)]
    normals = -shape.gradient(points)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return points + rng.normal(0.0, noise, points.shape) if noise else points, normals


def die_samples():
    """The demo's die (:func:`die`, size 2) as scattered samples about 0.04 apart with Gaussian noise of sd 0.002:
    (n, 3) points and their (n, 3) outward normals (n about 14,000), the same every call."""
    return sample_surface(die(), spacing=0.04, noise=0.002, seed=1)
