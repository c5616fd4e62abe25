"""The implicit function sampled on a regular grid: the paper's grid I, the contract between the steps.

Convention: f > 0 inside the domain, f < 0 outside, close to signed distance (input units) near f = 0.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Callable

import numpy as np
from scipy.ndimage import map_coordinates

from .kernels import (BRICK_SHIFT, brick_gradients, evaluate_at, fill_bricks, gradient_at, newton_to_surface,
                      node_values, plane_values)
from ..errors import InvalidInputError, check_number
from ..progress import ProgressCallback, report, sub_progress

#: bytes per grid node that the steps may hold at once, at most: a dense grid's f and gradient (32) or a banded
#: grid's coarse f (1), the biting's masks (4) and its sort (48 an Alive node); the sphere at 1M cells took 25.
BYTES_PER_NODE = 48
#: nodes a side of the bricks of a :class:`BandedGrid`; planes of nodes taken at once when a grid is swept.
BRICK, PLANES = 1 << BRICK_SHIFT, 8
#: the meshers sample f exactly within this many grid spacings of f = 0, and interpolate it from a grid twice as
#: coarse elsewhere: measured, 1.7x (10,000 cells) to 2.4x (136,000) faster, identical within 2.5 spacings.
EXACT_WITHIN = 3.0
#: a point projected onto f = 0 stops once its Newton step is shorter than this many grid spacings: each next
#: step is about 200x shorter (measured on the heart's boundary nodes), so it is left within about 1e-5 spacings.
SETTLED = 1e-3


class SampledGrid:
    """What the steps ask of a grid I, whatever keeps its f: ``origin`` (k,) and ``spacing`` (k,) float64, node
    ``index`` at ``origin + index * spacing``, and f at the nodes (:mod:`bitemesh.core.grid.kernels`)."""

    origin: np.ndarray
    spacing: np.ndarray
    shape: tuple

    @property
    def dim(self) -> int:
        return len(self.shape)

    @property
    def upper(self) -> np.ndarray:
        """(k,) coordinates of the last node."""
        return self.origin + (np.array(self.shape) - 1) * self.spacing

    def __call__(self, x) -> np.ndarray:
        """The sampled function as an implicit function: :meth:`evaluate`."""
        return self.evaluate(x)

    def nearest_nodes(self, points: np.ndarray, offset: float = 0.5) -> tuple:
        """The index arrays (one per axis, for ``array[index]``) of the node nearest each of (m, k) points, clipped
        to the grid; ``offset`` 0 gives the first node of the cell holding each point instead."""
        index = np.floor((np.asarray(points) - self.origin) / self.spacing + offset).astype(np.int64)
        return tuple(np.clip(index, 0, np.array(self.shape) - 1).T)

    def node_coordinates(self, flat_indices: np.ndarray) -> np.ndarray:
        """(m, k) coordinates of the nodes with the given C-order flat indices."""
        index = np.stack(np.unravel_index(flat_indices, self.shape), axis=1)
        return self.origin + index * self.spacing

    @cached_property
    def _shape3(self) -> np.ndarray:
        """(3,) int64 the node counts, a 2D grid's with a last axis of one node."""
        return np.array(tuple(self.shape) + (1,) * (3 - self.dim), dtype=np.int64)

    def _points(self, points: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(points, dtype=np.float64).reshape(-1, self.dim)

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        """(m,) multilinear interpolation of f at (m, k) points; outside the grid, at most minus the distance to it."""
        return evaluate_at(*self._storage, self._shape3, self._origin, self._spacing, self._points(points))

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """(m, k) multilinear interpolation of the central-difference gradient of f (numpy.gradient's)."""
        return gradient_at(*self._storage, self._gradients, self._shape3, self._origin, self._spacing,
                           self._points(points))

    def project(self, points: np.ndarray, steps: int = 4) -> np.ndarray:
        """(m, k) points moved onto f = 0 by up to ``steps`` Newton steps along grad f (as :meth:`evaluate` and
        :meth:`gradient` take them), each at most one grid spacing long; a point stops once its step is shorter
        than ``SETTLED`` spacings."""
        return newton_to_surface(*self._storage, self._gradients, self._shape3, self._origin, self._spacing,
                                 self._points(points), steps, SETTLED * float(np.min(self.spacing)))

    @cached_property
    def _origin(self) -> np.ndarray:
        return np.asarray(self.origin, np.float64)

    @cached_property
    def _spacing(self) -> np.ndarray:
        return np.asarray(self.spacing, np.float64)

    @cached_property
    def _gradients(self) -> np.ndarray:
        """The central-difference gradient on the nodes of the bricks kept (24 bytes a node of them), made when first
        asked for."""
        return brick_gradients(*self._storage, self._shape3, self._spacing)

    def node_values(self, flat_indices: np.ndarray) -> np.ndarray:
        """(m,) f at the nodes with the given C-order flat indices."""
        return node_values(*self._storage, self._shape3, np.asarray(flat_indices, np.int64).ravel())

    def planes(self, first: int, last: int) -> np.ndarray:
        """(last - first, n_1, ...) f on the nodes of planes ``first`` to ``last`` - 1 along axis 0."""
        return plane_values(*self._storage, self._shape3, first, last).reshape((last - first, *self.shape[1:]))

    def inside(self, level: float = 0.0) -> np.ndarray:
        """(n_0, ..., n_{k-1}) bool, f > ``level`` at the nodes (one byte a node)."""
        mask = np.empty(self.shape, dtype=bool)
        for first in range(0, self.shape[0], PLANES):
            mask[first:first + PLANES] = self.planes(first, min(first + PLANES, self.shape[0])) > level
        return mask

    def inside_offsets(self) -> tuple:
        """(f > -h, f > +h) at the nodes, h the largest grid spacing: the region a spacing outside and inside f = 0
        (a tunnel or cavity of the shape is in both)."""
        step = float(np.max(self.spacing))
        return self.inside(-step), self.inside(step)

    def inside_volume(self) -> float:
        """Measure (area in 2D, volume in 3D) of {f > 0}, counted on the nodes."""
        count = sum(np.count_nonzero(self.planes(first, min(first + PLANES, self.shape[0])) > 0)
                    for first in range(0, self.shape[0], PLANES))
        return float(count * np.prod(self.spacing))


@dataclass(frozen=True, eq=False)
class ImplicitGrid(SampledGrid):
    """f sampled at ``origin + index * spacing``, every node kept.

    Attributes
    ----------
    origin : (k,) float64, coordinates of node (0, ..., 0)
    spacing : (k,) float64, distance between nodes along each axis (> 0)
    values : (n_0, ..., n_{k-1}) float64, f at the nodes, indexed [i, j(, l)] (axis 0 is x)
    """

    origin: np.ndarray
    spacing: np.ndarray
    values: np.ndarray

    @property
    def shape(self) -> tuple:
        return self.values.shape

    @cached_property
    def _storage(self) -> tuple:
        """The kernels' (coarse, slots, bricks): the values as one brick."""
        values = np.ascontiguousarray(self.values, dtype=np.float64).reshape(tuple(self._shape3))
        return np.zeros((1, 1, 1)), np.zeros((1, 1, 1), np.int32), values[None]

    def planes(self, first: int, last: int) -> np.ndarray:
        return self.values[first:last]

    def scaled(self, origin: np.ndarray, factor: float) -> ImplicitGrid:
        """This grid moved to ``origin`` with its spacing and f times ``factor``."""
        return ImplicitGrid(origin=origin, spacing=self.spacing * factor, values=self.values * factor)


@dataclass(frozen=True, eq=False)
class BandedGrid(SampledGrid):
    """f at ``origin + index * spacing`` kept where it matters: its nodes cut into bricks of :data:`BRICK` nodes a
    side; the bricks that meet the band |f| < exact_within around f = 0 hold f exactly, the others take the
    multilinear refinement of a grid twice as coarse.  Memory: 8 bytes a node of the coarse grid (1/8 of the nodes)
    and of the bricks kept (they follow the surface).

    Attributes
    ----------
    origin, spacing : (k,) float64, as :class:`ImplicitGrid`'s
    shape : (n_0, ..., n_{k-1}) the node counts
    coarse : (c_0, c_1, c_2) float64, f at ``origin + index * 2 spacing`` (c_i = (n_i + 2) // 2; 2D: c_2 = 1)
    slots : (b_0, b_1, b_2) int32, brick -> its row of ``bricks``, or -1 where the coarse grid's refinement holds
    bricks : (m, B_0, B_1, B_2) float64, f on the nodes of the bricks kept
    """

    origin: np.ndarray
    spacing: np.ndarray
    shape: tuple
    coarse: np.ndarray
    slots: np.ndarray
    bricks: np.ndarray

    @property
    def _storage(self) -> tuple:
        return self.coarse, self.slots, self.bricks

    @property
    def values(self) -> np.ndarray:
        """(n_0, ..., n_{k-1}) float64, f at every node: a new array of 8 bytes a node (for a picture or a file)."""
        return self.planes(0, self.shape[0])

    def scaled(self, origin: np.ndarray, factor: float) -> BandedGrid:
        """This grid moved to ``origin`` with its spacing and f times ``factor``."""
        return BandedGrid(origin=origin, spacing=self.spacing * factor, shape=self.shape,
                          coarse=self.coarse * factor, slots=self.slots, bricks=self.bricks * factor)


@dataclass(frozen=True, eq=False)
class FunctionGrid(SampledGrid):
    """The grid I of a function kept as the function: f evaluated at the points the steps ask for (in more than
    three dimensions the grid's nodes are too many to hold f at each: the steps keep the biting's masks, one byte a
    node).  At the nodes, f comes from the function itself, or, banded (:func:`sample_function` with
    ``exact_within``), from the values kept where the grid twice as coarse, interpolated, gives |f| < exact_within
    and from that interpolation elsewhere, as :class:`BandedGrid` keeps it in 3-D.  Any dimension k.

    Attributes
    ----------
    function : maps (m, k) points to (m,) values, f > 0 inside
    origin, spacing : (k,) float64, as :class:`ImplicitGrid`'s; shape : (n_0, ..., n_{k-1}) the node counts
    coarse : (c_0, ..., c_{k-1}) float64, f at the nodes of the grid twice as coarse, or None (not banded)
    band, band_values : (b,) int64 sorted C-order flat indices of the nodes where f is kept, and (b,) f there
    """

    function: Callable[[np.ndarray], np.ndarray]
    origin: np.ndarray
    spacing: np.ndarray
    shape: tuple
    coarse: np.ndarray | None = None
    band: np.ndarray | None = None
    band_values: np.ndarray | None = None

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        """(m,) f at (m, k) points."""
        return np.asarray(self.function(self._points(points)), dtype=np.float64)

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """(m, k) central differences of f, a thousandth of a grid spacing apart."""
        points = self._points(points)
        step = 1e-3 * self._spacing
        return np.stack([(self.evaluate(points + step[d] * axis) - self.evaluate(points - step[d] * axis))
                         / (2.0 * step[d]) for d, axis in enumerate(np.eye(self.dim))], axis=1)

    def project(self, points: np.ndarray, steps: int = 4) -> np.ndarray:
        """As :meth:`SampledGrid.project`: Newton steps along grad f onto f = 0, each at most a grid spacing."""
        points = self._points(points).copy()
        reach, settled = float(np.min(self.spacing)), SETTLED * float(np.min(self.spacing))
        moving = np.arange(len(points))
        for _ in range(steps):
            gradient = self.gradient(points[moving])
            squared = np.maximum(np.einsum("ij,ij->i", gradient, gradient), 1e-300)
            step = -(self.evaluate(points[moving]) / squared)[:, None] * gradient
            length = np.linalg.norm(step, axis=1)
            points[moving] += step * np.minimum(1.0, reach / np.maximum(length, 1e-300))[:, None]
            moving = moving[length >= settled]
        return points

    def node_values(self, flat_indices: np.ndarray) -> np.ndarray:
        flat = np.asarray(flat_indices, np.int64).ravel()
        if self.coarse is None:
            return self.evaluate(self.node_coordinates(flat))
        values = refined(self.coarse, self.shape, flat)
        at = np.minimum(np.searchsorted(self.band, flat), max(len(self.band) - 1, 0))
        kept = self.band[at] == flat if len(self.band) else np.zeros(len(flat), bool)
        values[kept] = self.band_values[at[kept]]
        return values

    def planes(self, first: int, last: int) -> np.ndarray:
        plane = int(np.prod(self.shape[1:]))
        return self.node_values(np.arange(first * plane, last * plane)).reshape((last - first, *self.shape[1:]))


def grid_shape_unchecked(lower, upper, spacing) -> tuple:
    """Node counts of a grid with the given spacing from ``lower`` that reaches ``upper`` (to rounding)."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    spacing = np.broadcast_to(np.asarray(spacing, float), lower.shape)
    return tuple(int(n) for n in np.floor((upper - lower) / spacing + 1e-9).astype(np.int64) + 1)


def available_memory_mb() -> float | None:
    """MiB of memory the system can give without swapping (Linux: MemAvailable), or None where unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as stream:
            for line in stream:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return None


def grid_shape(lower, upper, spacing, *, max_memory_mb: float) -> tuple:
    """Node counts of a grid with the given spacing covering [lower, upper]; refuse one that would need more
    memory than ``max_memory_mb`` or than the system has available.

    Parameters
    ----------
    lower, upper : (k,) float64, corners of the box to cover
    spacing : (k,) float64 or float, grid spacing h
    max_memory_mb : the memory the grid may take, in MiB
    """
    shape = grid_shape_unchecked(lower, upper, spacing)
    needed_mb = np.prod(np.array(shape, dtype=np.float64)) * BYTES_PER_NODE / 2**20
    available = available_memory_mb()
    limit = min(max_memory_mb, available or np.inf)
    if needed_mb > limit:
        spacing = np.broadcast_to(np.asarray(spacing, float), np.shape(lower))
        suggested = float(np.max(spacing) * (needed_mb / limit) ** (1 / len(shape)))
        which = (f"max_memory_mb = {max_memory_mb:g}" if limit == max_memory_mb
                 else f"the {available:.0f} MiB of memory this machine has free")
        raise InvalidInputError(
            f"grid_spacing {float(np.min(spacing)):.4g} needs a grid of {' x '.join(map(str, shape))} nodes "
            f"(about {needed_mb:.0f} MiB), more than {which}; use grid_spacing >= {suggested:.4g}"
            + (" or raise max_memory_mb" if limit == max_memory_mb else ""))
    return shape


def sample_function(function: Callable[[np.ndarray], np.ndarray], lower, upper, spacing, *,
                    margin: float = 0.0, max_memory_mb: float = 4096.0, chunk: int = 1 << 18,
                    exact_within: float | None = None, levels: int = 1,
                    progress: ProgressCallback = None) -> SampledGrid:
    """Sample ``function`` on a grid over [lower - margin, upper + margin]; in more than three dimensions, the grid
    of the function itself (:class:`FunctionGrid`).

    Parameters
    ----------
    function : maps (m, k) points to (m,) values, f > 0 inside
    lower, upper : (k,) float64, the box to cover
    spacing : float or (k,) float64, grid spacing h (> 0)
    margin : float, added on every side of the box
    exact_within : evaluate ``function`` only at the nodes where a grid twice as coarse, interpolated, gives
        |f| < exact_within (input units), and keep the interpolation elsewhere: a :class:`BandedGrid`, which keeps
        the exact values in the bricks around f = 0 only; None evaluates every node: an :class:`ImplicitGrid`.
        The steps downstream need f exactly only near f = 0 (its sign and the projection onto it).
    levels : with exact_within, how many grids, each twice as fine as the one before, lead to this one: the first is
        evaluated everywhere, each next one exactly only within exact_within x (its spacing / h) of f = 0.  Each
        level saves about half the evaluations of the one before; a bubble of f smaller than the coarser
        spacings may be missed.
    progress : callable(fraction, message), optional, called once per chunk of ``chunk`` points
    """
    lower = np.asarray(lower, float) - margin
    upper = np.asarray(upper, float) + margin
    spacing_array = np.broadcast_to(np.asarray(spacing, float), lower.shape).copy()
    for value in spacing_array:
        check_number(value, "grid_spacing", low=0, low_open=True)
    shape = grid_shape(lower, upper, spacing_array, max_memory_mb=max_memory_mb)
    if len(shape) > 3:
        if exact_within is None:
            return FunctionGrid(function, lower, spacing_array, shape)
        return _banded_function(function, lower, spacing_array, shape, exact_within, chunk, progress)
    if exact_within is None:
        values = np.empty(int(np.prod(shape)))
        _evaluate_nodes(function, lower, spacing_array, shape, range(len(values)), values, chunk, progress)
        return ImplicitGrid(origin=lower, spacing=spacing_array, values=values.reshape(shape))
    coarse_shape = tuple((n + 2) // 2 for n in shape)  # reaches the fine grid's last node
    coarse = sample_function(function, lower, lower + (np.array(coarse_shape) - 1) * 2 * spacing_array,
                             2 * spacing_array, max_memory_mb=max_memory_mb, chunk=chunk,
                             exact_within=2 * exact_within if levels > 1 else None, levels=levels - 1)
    grid, band = _banded(lower, spacing_array, shape, coarse.values, exact_within)
    values = np.empty(len(band))
    _evaluate_nodes(function, lower, spacing_array, shape, band, values, chunk, progress)
    x, y, z = np.unravel_index(band, tuple(grid._shape3))
    b = grid.bricks.shape[1:]
    grid.bricks[grid.slots[x // b[0], y // b[1], z // b[2]], x % b[0], y % b[1], z % b[2]] = values
    return grid


def _evaluate_nodes(function, lower, spacing, shape, nodes, out, chunk: int, progress: ProgressCallback) -> None:
    """``out[nodes] = function(coordinates of nodes)`` (C-order flat indices, a range or an array) in chunks."""
    axes = [lower[d] + np.arange(n) * spacing[d] for d, n in enumerate(shape)]
    for start in range(0, len(nodes), chunk):
        report(progress, start / len(nodes), f"sampling f on {' x '.join(map(str, shape))} nodes")
        flat = np.asarray(nodes[start:start + chunk])
        index = np.unravel_index(flat, shape)
        out[start:start + len(flat)] = function(np.stack([axes[d][index[d]] for d in range(len(shape))], axis=1))
    report(progress, 1.0, "sampling f: done")


def refined(coarse: np.ndarray, shape: tuple, flat: np.ndarray) -> np.ndarray:
    """(m,) f at the nodes ``flat`` (C-order flat indices) of the grid of ``shape``, multilinear from ``coarse``,
    f on the grid twice as coarse (fine node i lies at coarse index i / 2)."""
    index = np.stack(np.unravel_index(flat, shape)) / 2.0
    return map_coordinates(coarse, index, order=1, mode="nearest")


def _banded_function(function, lower, spacing, shape, exact_within: float, chunk: int,
                     progress: ProgressCallback) -> FunctionGrid:
    """The banded :class:`FunctionGrid` (see :func:`sample_function`): f evaluated on the grid twice as coarse, then
    at the nodes where its interpolation gives |f| < exact_within; the rest is that interpolation."""
    coarse_shape = tuple((n + 2) // 2 for n in shape)   # reaches the fine grid's last node
    coarse = np.empty(int(np.prod(coarse_shape)))
    _evaluate_nodes(function, lower, 2 * spacing, coarse_shape, range(len(coarse)), coarse, chunk,
                    sub_progress(progress, 0.0, 0.3))
    coarse = coarse.reshape(coarse_shape)
    nodes = int(np.prod(shape))
    band = np.concatenate([first + np.flatnonzero(np.abs(refined(coarse, shape, np.arange(
        first, min(first + chunk, nodes)))) < exact_within) for first in range(0, nodes, chunk)])
    values = np.empty(len(band))
    _evaluate_nodes(function, lower, spacing, shape, band, values, chunk, sub_progress(progress, 0.3, 1.0))
    return FunctionGrid(function, lower, spacing, shape, coarse, band, values)


def _banded(origin, spacing, shape, coarse, exact_within: float):
    """(grid, band): the BandedGrid whose bricks are those that meet |f| < exact_within on the refinement of
    ``coarse``, filled with that refinement, and the (m,) int64 C-order flat indices of the band's nodes, where f is
    to be evaluated."""
    shape3 = tuple(shape) + (1,) * (3 - len(shape))
    coarse = np.ascontiguousarray(coarse, np.float64).reshape(tuple(coarse.shape) + (1,) * (3 - len(shape)))
    brick = (BRICK, BRICK, BRICK if len(shape) == 3 else 1)
    counts = tuple(-(-n // b) for n, b in zip(shape3, brick))
    refinement = BandedGrid(origin, spacing, shape, coarse, np.full(counts, -1, np.int32), np.empty((0, *brick)))
    band = np.concatenate([np.flatnonzero(np.abs(refinement.planes(first, min(first + PLANES, shape3[0])))
                                          < exact_within) + first * shape3[1] * shape3[2]
                           for first in range(0, shape3[0], PLANES)])
    x, y, z = np.unravel_index(band, shape3)
    kept = np.unique(np.ravel_multi_index((x // brick[0], y // brick[1], z // brick[2]), counts))
    slots = np.full(counts, -1, np.int32)
    slots.ravel()[kept] = np.arange(kept.size, dtype=np.int32)
    bricks = np.empty((kept.size, *brick))
    fill_bricks(coarse, bricks, np.stack(np.unravel_index(kept, counts), axis=1), np.array(shape3, np.int64))
    return BandedGrid(origin, spacing, tuple(shape), coarse, slots, bricks), band


def inside_extents(mask: np.ndarray) -> np.ndarray:
    """(k,) int64, along each axis the last index minus the first of the nodes where ``mask`` (n_0, ..., n_{k-1})
    bool is set (none set: zeros)."""
    spans = []
    for axis in range(mask.ndim):
        hit = np.flatnonzero(mask.any(axis=tuple(a for a in range(mask.ndim) if a != axis)))
        spans.append(hit[-1] - hit[0] if hit.size else 0)
    return np.array(spans, dtype=np.int64)


def bounding_box(points: np.ndarray):
    """(lower (k,), upper (k,), diagonal) of the points' box."""
    lower, upper = points.min(axis=0), points.max(axis=0)
    return lower, upper, float(np.linalg.norm(upper - lower))


def box_depth(x: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """(m,) signed distance of (m, k) points to the boundary of the box [lower, upper], > 0 inside."""
    return box_depth_gradient(x, lower, upper)[0]


def box_depth_gradient(x: np.ndarray, lower: np.ndarray, upper: np.ndarray):
    """(m,) :func:`box_depth` and its (m, k) gradient."""
    beyond = x - np.clip(x, lower, upper)
    distance_out = np.linalg.norm(beyond, axis=1)
    to_faces = np.concatenate([x - lower, upper - x], axis=1)
    nearest_face = np.argmin(to_faces, axis=1)
    outside = distance_out > 0
    depth = np.where(outside, -distance_out, to_faces[np.arange(len(x)), nearest_face])
    dim = x.shape[1]
    inward = np.zeros_like(x)
    inward[np.arange(len(x)), nearest_face % dim] = np.where(nearest_face < dim, 1.0, -1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        away = -beyond / distance_out[:, None]
    return depth, np.where(outside[:, None], away, inward)
