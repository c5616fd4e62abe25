"""A shape that moves through a cycle as one shape in space-time: f(x, tau) from the implicit functions of its
frames (a cine's), meshed in k + 1 dimensions and cut back into the frames (issue 36).

Frame j stands at tau = j * step (``step`` in the input's length unit, so that R means the same along tau as across
x); between two frames f is linear in tau, and the frame after the last is the first (a cardiac cycle).  The
space-time domain is the slab of {f > 0} from ``beyond`` before the first frame to as far past the last.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError, check_number
from ..mesh.simplicial import Mesh
from ..mesh.slicing import slice_mesh


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
        weight = position - first
        count = len(self.frames)
        value = np.zeros(len(y))
        for j, frame in enumerate(self.frames):
            left, right = first % count == j, (first + 1) % count == j   # frame j begins or ends the interval
            either = left | right
            if either.any():
                share = np.where(left[either], 1.0 - weight[either], weight[either])
                value[either] += share * np.asarray(frame(x[either]), dtype=np.float64)
        lo, hi = self.slab
        return np.minimum(value, np.minimum(tau - lo, hi - tau))


def frame_instants(mesh: Mesh, shape: SpaceTime) -> list:
    """The k-D meshes of each frame's instant: the space-time ``mesh`` of ``shape`` (k + 1 dimensions) cut at
    tau = j * step."""
    return [slice_mesh(mesh, j * shape.step) for j in range(len(shape.frames))]
