"""A shape that moves through a cycle as one shape in space-time: f(x, tau) from the implicit functions of its
frames (a cine's), meshed in k + 1 dimensions and cut back into the frames (issue 36).

Frame j stands at tau = j * step (``step`` in the input's length unit, so that R means the same along tau as across
x); between two frames f is Catmull-Rom's cubic in tau through the four frames around (each frame's f at its
instant, smooth across it: linear in tau, the mesh cut the corners of the motion at the frames, 10 % of a ball's
volume where it turned from growing to shrinking), and the frame after the last is the first (a cardiac cycle).  The
space-time domain is the slab of {f > 0} from ``beyond`` before the first frame to as far past the last.
:func:`space_time_source` makes the frames' sources (each in its own local frame) one source of one more dimension
for the spine.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Optional, Sequence

import numpy as np

from ..errors import InvalidInputError, check_number
from ..grid.sampled import sample_function
from ..mesh.simplicial import Mesh
from ..mesh.slicing import slice_mesh
from ..parameters import Parameters, parameter
from ..steps.spine import CELLS_PER_VOLUME
from .source import Frame, Source

#: the space-time cells aimed for when neither radius nor cells is given: R = 8.3 mm for the 25 frames of biv-me
#: patient1 (a heart's thin walls give about 1.7 times the cells of a relaxed ball of its volume, so about 600,000;
#: at 7 mm the 4-D grid passes 4 GB; benchmarks/spacetime.md)
SPACE_TIME_CELLS = 350_000
#: the default distance along time between frames, in node spacings R: Catmull-Rom's cubic in time, sampled by
#: nodes R apart, cuts the corners of the motion by about f'' R^2 / 8 at the frames, a quarter as much two R a frame
#: as one (a ball breathing by 5-10 % a frame: each instant's volume within 1.2-2.4 % of its frame's 3-D mesh, 4-6
#: % at one R a frame; three R: 0.2-1.4 % for 1.3 times the cells)
FRAME_STEP = 2.0
#: nodes along the longest side of the coarse grid that measures each frame's volume (for R from a cell count)
_VOLUME_GRID_NODES = 48


@dataclass(frozen=True)
class SpaceTimeParameters(Parameters):
    """Space-time: the inputs as the frames of one cycle, meshed as one mesh of one more dimension."""

    space_time: int = parameter(
        0, "1 meshes the inputs (the frames of one cycle in its order, in one coordinate frame: e.g. GPFile_000.txt "
        "to GPFile_024.txt) as one space-time mesh of one more dimension, time its last coordinate (.npz or .h5), "
        "and cuts each frame's instant out of it (STEM_NNN.vtu beside it and the time series STEM.pvd); radius "
        f"and cells are the space-time mesh's (default about {SPACE_TIME_CELLS:,} cells); 0 meshes one input",
        low=0, high=1, integer=True)
    frame_step: Optional[float] = parameter(
        None, f"with space_time: the distance along time from one frame to the next; default {FRAME_STEP:g} R "
        "(node spacings a frame)", unit="input units", low=0, low_open=True)


@dataclass(frozen=True, eq=False)
class SpaceTime:
    """f(x, tau) of a periodic sequence of implicit functions, callable (m, k + 1) -> (m,), tau the last column.

    Attributes
    ----------
    frames : tuple of F callables (m, k) -> (m,), f > 0 inside, frame j at tau = j * step
    step : float > 0, input units a frame
    beyond : float >= 0, input units: how far the slab reaches past the first and the last frame (see :attr:`slab`)
    """

    frames: tuple
    step: float
    beyond: float = 0.0

    def __post_init__(self):
        if len(self.frames) < 2:
            raise InvalidInputError(f"a space-time shape needs at least 2 frames, got {len(self.frames)}")
        check_number(self.step, "step", low=0, low_open=True)
        check_number(self.beyond, "beyond", low=0)

    @property
    def slab(self) -> tuple:
        """(tau_lo, tau_hi): the span of tau meshed, ``beyond`` (at least half a step) past the first and the last
        frame, the cycle continued there; give two mesh radii or more, so that the slab's ends do not cut into
        the first and the last frame's sections."""
        reach = max(0.5 * self.step, self.beyond)
        return -reach, (len(self.frames) - 1) * self.step + reach

    def __call__(self, y) -> np.ndarray:
        y = np.asarray(y, dtype=np.float64)
        x, tau = y[:, :-1], y[:, -1]
        position = tau / self.step
        first = np.floor(position).astype(np.int64)
        u = (position - first)[:, None]
        shares = np.hstack([(-u**3 + 2 * u**2 - u) / 2, (3 * u**3 - 5 * u**2 + 2) / 2,   # Catmull-Rom's weights
                            (-3 * u**3 + 4 * u**2 + u) / 2, (u**3 - u**2) / 2])           # of frames j - 1 .. j + 2
        frames = (first[:, None] + np.arange(-1, 3)) % len(self.frames)
        value = np.zeros(len(y))
        for j, frame in enumerate(self.frames):
            hit = frames == j
            rows = hit.any(axis=1)
            if rows.any():
                value[rows] += (shares[rows] * hit[rows]).sum(axis=1) * np.asarray(frame(x[rows]), dtype=np.float64)
        lo, hi = self.slab
        return np.minimum(value, np.minimum(tau - lo, hi - tau))


def frame_instants(mesh: Mesh, step: float, frames: int) -> list:
    """The k-D meshes of each of ``frames`` instants of a space-time ``mesh`` (user coordinates), cut at
    tau = j * ``step`` (user units)."""
    return [slice_mesh(mesh, j * step) for j in range(frames)]


def space_time_radius(frames: Sequence[Source], cells: int, step: Optional[float] = None) -> float:
    """R (user units) for about ``cells`` cells in the space-time mesh of ``frames`` a ``step`` apart (None:
    :data:`FRAME_STEP` R), from each frame's volume counted on a coarse grid and the slab
    :func:`space_time_source` makes."""
    volumes = []
    for source in frames:
        spacing = source.size / _VOLUME_GRID_NODES
        grid = sample_function(source.function, source.lower, source.upper, spacing, margin=2 * spacing)
        volumes.append(grid.inside_volume() * source.frame.scale ** len(source.lower))
    measure, dim = float(np.mean(volumes)), len(frames[0].lower) + 1
    radius = (CELLS_PER_VOLUME[dim] * measure * len(frames) / cells) ** (1 / (dim - 1))
    for _ in range(20):   # the slab's span grows with R (the step and the ends): a contraction, settled in a few
        between = step or FRAME_STEP * radius
        span = (len(frames) - 1) * between + 2 * max(0.5 * between, 2 * radius)
        radius = (CELLS_PER_VOLUME[dim] * measure * span / cells) ** (1 / dim)
    return float(radius)


def space_time_source(frames: Sequence[Source], radius: float, step: Optional[float] = None) -> Source:
    """The sources of a cycle's frames (in its order; each in its own local frame, their user coordinates shared) as
    one source of one more dimension, tau its last coordinate: f the :class:`SpaceTime` of the frames' functions at
    ``radius`` R (user units), a frame ``step`` apart (user units; None: :data:`FRAME_STEP` R), the slab two R past
    the ends; the frames' samples at their instants."""
    if len(frames) < 2:
        raise InvalidInputError(f"space_time: a cycle needs at least 2 frames, got {len(frames)}")
    dims = {len(source.lower) for source in frames}
    if len(dims) > 1:
        raise InvalidInputError(f"space_time: the frames have different dimensions {sorted(dims)}; give frames of "
                                "one kind of data")
    for number, source in enumerate(frames):
        if not np.allclose(source.frame.linear, source.frame.scale * np.eye(len(source.lower)), rtol=0,
                           atol=1e-12 * source.frame.scale) or source.grid is not None:
            raise InvalidInputError(f"space_time: frame {number} is not scattered points or labelled contours (a "
                                    "label map's frames are not supported yet); give point or contour files")
    scale = frames[0].frame.scale
    corners = np.vstack([source.frame.to_user(np.array([source.lower, source.upper])) for source in frames])
    centre = 0.5 * (corners.min(axis=0) + corners.max(axis=0))
    space = Frame(scale * np.eye(len(centre)), centre)
    radius, step = radius / scale, (step or FRAME_STEP * radius) / scale
    moved = tuple(_InSpace(source, space, radius) for source in frames)
    shape = SpaceTime(moved, step, beyond=2 * radius)
    lower, upper = space.to_local(corners).min(axis=0), space.to_local(corners).max(axis=0)
    samples = [np.column_stack([space.to_local(source.frame.to_user(source.samples)), np.full(len(source.samples),
                                                                                              j * step)])
               for j, source in enumerate(frames) if source.samples is not None]
    return Source(function=shape, lower=np.r_[lower, shape.slab[0]], upper=np.r_[upper, shape.slab[1]],
                  frame=Frame(scale * np.eye(len(centre) + 1), np.r_[centre, 0.0]),
                  samples=np.vstack(samples) if samples else None,
                  noise=max(source.noise * source.frame.scale for source in frames) / scale,
                  gap=max(step, *(source.gap * source.frame.scale / scale for source in frames)),
                  open_boundary=_OpenAt(moved, step),
                  notes=tuple(f"frame {j}: {note}" for j, source in enumerate(frames) for note in source.notes))


@dataclass(frozen=True, eq=False)
class _InSpace:
    """One frame's f at R in the space-time's spatial frame (its local units): callable (m, k) -> (m,)."""

    source: Source
    space: Frame
    radius: float

    def local(self, y: np.ndarray) -> np.ndarray:
        """(m, k) points of the spatial frame in the source's local frame."""
        return self.source.frame.to_local(self.space.to_user(y))

    @cached_property
    def ratio(self) -> float:
        """The source's local units per spatial-frame unit."""
        return self.source.frame.scale / self.space.scale

    @cached_property
    def function(self):
        """The source's f at R (its thinnest wall follows R), in its local frame."""
        source = self.source
        return source.function if source.at_radius is None else source.at_radius(self.radius / self.ratio)

    def __call__(self, y) -> np.ndarray:
        return np.asarray(self.function(self.local(np.asarray(y, dtype=np.float64))), dtype=np.float64) * self.ratio


@dataclass(frozen=True, eq=False)
class _OpenAt:
    """Where the boundary is the method's in space-time: before the first frame and after the last (the slab's
    ends, the cycle continued to them), else the nearest frame's open boundary (a heart's base)."""

    frames: tuple
    step: float

    def __call__(self, y) -> np.ndarray:
        y = np.asarray(y, dtype=np.float64)
        nearest = np.rint(y[:, -1] / self.step).astype(np.int64)
        out = (y[:, -1] < 0) | (y[:, -1] > (len(self.frames) - 1) * self.step)
        for j, frame in enumerate(self.frames):
            chosen = (nearest == j) & ~out
            if chosen.any() and frame.source.open_boundary is not None:
                out[chosen] = frame.source.open_boundary(frame.local(y[chosen, :-1]))
        return out
