"""The shape modes of a cohort of fitted templates (one connectivity, node i the same point on every heart):
generalised Procrustes alignment, then principal component analysis of the node positions (Cootes et al. 1995)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from .alignment import similarity

#: the rounds of generalised Procrustes alignment, and the change of the mean shape (RMS, in its size) that ends them.
ALIGN_ROUNDS, ALIGN_TOLERANCE = 100, 1e-10


@dataclass(frozen=True, eq=False)
class ShapeModes:
    """A cohort's mean shape and main modes.

    Attributes
    ----------
    mean : (n, 3) the mean node positions, in the first shape's frame (input units)
    modes : (k, n, 3) the modes, unit vectors of the 3 n node coordinates, orthogonal
    deviations : (k,) the standard deviation of the cohort along each mode (input units, over the 3 n space)
    explained : (k,) the share of the total variance each mode explains, decreasing
    aligned : (c, n, 3) every shape after the alignment
    """

    mean: np.ndarray
    modes: np.ndarray
    deviations: np.ndarray
    explained: np.ndarray
    aligned: np.ndarray

    def shape(self, weights) -> np.ndarray:
        """(n, 3) the mean moved by ``weights`` (k',) standard deviations along the first k' modes."""
        weights = np.asarray(weights, dtype=np.float64)
        return self.mean + np.einsum("k,k,kni->ni", weights, self.deviations[:len(weights)],
                                     self.modes[:len(weights)])


def shape_modes(shapes, *, scale: bool = False) -> ShapeModes:
    """Align ``shapes`` (c, n, 3), c >= 2 meshes' node positions with one connectivity, by rotations and
    translations (and a common size with ``scale``) onto their mean, then their principal modes."""
    shapes = np.asarray(shapes, dtype=np.float64)
    if shapes.ndim != 3 or shapes.shape[2] != 3 or len(shapes) < 2:
        raise InvalidInputError(f"shapes: (c, n, 3) node positions of at least 2 meshes are needed, got shape "
                                f"{shapes.shape}")
    aligned, mean = shapes.copy(), shapes[0]
    for _ in range(ALIGN_ROUNDS):
        for index, shape in enumerate(shapes):
            size, rotation, _ = similarity(shape, mean)
            turned = (size if scale else 1.0) * shape @ rotation.T
            aligned[index] = turned + mean.mean(axis=0) - turned.mean(axis=0)
        previous, mean = mean, aligned.mean(axis=0)
        spread = np.sqrt(np.mean((mean - mean.mean(axis=0)) ** 2))
        if np.sqrt(np.mean((mean - previous) ** 2)) <= ALIGN_TOLERANCE * spread:
            break
    centred = (aligned - mean).reshape(len(shapes), -1)
    _, singular, vt = np.linalg.svd(centred, full_matrices=False)
    variances = singular ** 2 / (len(shapes) - 1)
    keep = variances > 1e-20 * np.sum((mean - mean.mean(axis=0)) ** 2)   # above rounding
    signs = np.sign(vt[keep][np.arange(keep.sum()), np.abs(vt[keep]).argmax(axis=1)])   # a sign per mode, fixed
    return ShapeModes(mean, (signs[:, None] * vt[keep]).reshape(-1, *shapes.shape[1:]), np.sqrt(variances[keep]),
                      variances[keep] / variances.sum(), aligned)
