"""A label map to the implicit grid: signed distance by SimpleITK, with the zero level between voxel centres."""
from __future__ import annotations

import numpy as np

from .core.errors import InvalidInputError
from .core.grid import ImplicitGrid

#: voxels of background added on every side, so that a label touching the image border still closes.
PAD_VOXELS = 2


def label_map_to_grid(labels: np.ndarray, origin, spacing, label: int | None = None) -> ImplicitGrid:
    """f > 0 inside the chosen label, about the signed distance to its boundary (input units).

    Parameters
    ----------
    labels : (n_x, n_y[, n_z]) integer array, indexed [i, j(, k)] with axis 0 along x
    origin : (k,) position of voxel (0, 0(, 0)); spacing : (k,) voxel size (input units)
    label : the domain's label; default every nonzero voxel

    The distance is the mean of SimpleITK's signed Maurer distances of the mask and of its complement, so f = 0
    lies halfway between an inside and an outside voxel centre (the surface of the voxelised shape).
    """
    import SimpleITK as sitk

    labels = np.asarray(labels)
    mask = labels != 0 if label is None else labels == label
    if not mask.any():
        present = np.unique(labels)[:20].tolist()
        raise InvalidInputError(f"label {label} is absent from the label map (labels present: {present})"
                                if label is not None else "the label map is empty: every voxel is 0")
    mask = np.pad(mask, PAD_VOXELS)
    spacing = np.asarray(spacing, dtype=np.float64)

    def signed_distance(region: np.ndarray) -> np.ndarray:
        image = sitk.GetImageFromArray(region.T.astype(np.uint8))  # SimpleITK arrays are indexed [z, y, x]
        image.SetSpacing(tuple(float(s) for s in spacing))
        distance = sitk.SignedMaurerDistanceMap(image, insideIsPositive=False, squaredDistance=False,
                                                useImageSpacing=True)
        return sitk.GetArrayFromImage(distance).T.astype(np.float64)

    values = 0.5 * (signed_distance(~mask) - signed_distance(mask))
    return ImplicitGrid(origin=np.asarray(origin, dtype=np.float64) - PAD_VOXELS * spacing, spacing=spacing,
                        values=values)
