"""Label map files (NRRD, NIfTI, MetaImage) read through SimpleITK, with their geometry in ITK's conventions:
:class:`LabelMap` and :func:`read_label_map`.  SimpleITK is imported on the first read (:func:`import_simpleitk`),
so this module imports without it.  Turning the labels into a signed distance and meshing them is
:mod:`bitemesh.labelmap`, which re-exports these names (``from bitemesh.labelmap import read_label_map`` works as
before).

Frames: ``labels[i, j, k]`` is indexed by the voxel index (axis 0 is i, the fastest axis of the file, as in ITK);
physical is ``origin + direction @ (index * spacing)``, ITK's LPS (mm) for a file, RAS on request (``diag(-1, -1,
1)`` of LPS).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import InvalidInputError

#: the file extensions read_label_map accepts (lower case; ``.nii.gz`` is one extension).
LABEL_MAP_EXTENSIONS = (".nrrd", ".nhdr", ".nii", ".nii.gz", ".mha", ".mhd")


@dataclass(frozen=True, eq=False)
class LabelMap:
    """An integer image with its geometry (ITK conventions).

    Attributes
    ----------
    labels : (n_i, n_j, n_k) integer array (or (n_i, n_j) for a 2D image), indexed [i, j, k]; 0 is background
    origin : (k,) float64, physical position of voxel (0, 0, 0) (mm, LPS for a file)
    spacing : (k,) float64, voxel size along i, j, k (mm, > 0)
    direction : (k, k) float64, column d is the physical direction of index axis d (ITK's direction matrix)

    ``physical = origin + direction @ (index * spacing)``; see :meth:`index_to_physical`.
    """

    labels: np.ndarray
    origin: np.ndarray = None
    spacing: np.ndarray = None
    direction: np.ndarray = None

    def __post_init__(self):
        labels = np.asarray(self.labels)
        if labels.ndim not in (2, 3):
            raise InvalidInputError(f"labels must be a 2D or 3D array, got shape {labels.shape}")
        if labels.dtype == bool:
            labels = labels.astype(np.uint8)
        if not np.issubdtype(labels.dtype, np.integer):
            raise InvalidInputError(f"labels must be an integer array (one label per voxel), got dtype "
                                    f"{labels.dtype}; see read_label_map for float images")
        k = labels.ndim
        origin = np.zeros(k) if self.origin is None else np.asarray(self.origin, dtype=np.float64).reshape(-1)
        spacing = np.ones(k) if self.spacing is None else np.asarray(self.spacing, dtype=np.float64).reshape(-1)
        direction = np.eye(k) if self.direction is None else np.asarray(self.direction, dtype=np.float64)
        if origin.shape != (k,) or not np.isfinite(origin).all():
            raise InvalidInputError(f"origin must be {k} finite numbers, got {self.origin!r}")
        if spacing.shape != (k,) or not (np.isfinite(spacing).all() and (spacing > 0).all()):
            raise InvalidInputError(f"spacing must be {k} positive numbers, got {self.spacing!r}")
        if direction.shape != (k, k) or not np.isfinite(direction).all() \
                or abs(np.linalg.det(direction)) < 1e-6:
            raise InvalidInputError(f"direction must be an invertible {k} x {k} matrix, got {self.direction!r}")
        for name, value in (("labels", labels), ("origin", origin), ("spacing", spacing),
                            ("direction", direction)):
            object.__setattr__(self, name, value)

    @property
    def dim(self) -> int:
        return self.labels.ndim

    def index_to_physical(self, ras: bool = False) -> np.ndarray:
        """(k + 1, k + 1) homogeneous matrix from the voxel index to physical space (LPS, or RAS when ``ras``)."""
        return index_to_physical_matrix(self.origin, self.spacing, self.direction, ras=ras)

    def present_labels(self) -> np.ndarray:
        """The sorted nonzero labels that occur in the map."""
        present = np.unique(self.labels)
        return present[present != 0]


def index_to_physical_matrix(origin, spacing, direction, *, ras: bool = False) -> np.ndarray:
    """(k + 1, k + 1) matrix ``[direction @ diag(spacing) | origin]``, optionally followed by LPS -> RAS."""
    origin, spacing = np.asarray(origin, float), np.asarray(spacing, float)
    k = len(origin)
    matrix = np.eye(k + 1)
    matrix[:k, :k] = np.asarray(direction, float) * spacing[None, :]
    matrix[:k, k] = origin
    if ras:
        flip = np.eye(k + 1)
        flip[0, 0] = flip[1, 1] = -1.0
        matrix = flip @ matrix
    return matrix


def read_label_map(path) -> LabelMap:
    """Read a label map (``.nrrd``, ``.nhdr``, ``.nii``, ``.nii.gz``, ``.mha``, ``.mhd``) with SimpleITK.

    Integer images are taken as they are.  A float image is accepted when every voxel holds a whole number (a
    label map saved as float, as some tools do) and refused otherwise: a probability map or an intensity image
    has no labels, and a threshold chosen here would be a guess; threshold it first.

    Raises
    ------
    InvalidInputError
        missing or unreadable file, unknown extension, vector (multi-component) or 4D image, a float image with
        fractional values, NaN or infinite values, or a map in which every voxel is 0.
    """
    path = Path(path)
    name = path.name.lower()
    if not any(name.endswith(extension) for extension in LABEL_MAP_EXTENSIONS):
        raise InvalidInputError(f"cannot read a label map from '{path}': unknown extension; supported extensions: "
                                f"{', '.join(LABEL_MAP_EXTENSIONS)}")
    if not path.exists():
        raise InvalidInputError(f"cannot read a label map from '{path}': the file does not exist")
    if not path.is_file():
        raise InvalidInputError(f"cannot read a label map from '{path}': it is not a regular file")
    sitk = import_simpleitk()
    try:
        image = sitk.ReadImage(str(path))
    except RuntimeError as error:
        detail = " ".join(re.split(r"(?:sitk|itk)::ERROR:", str(error))[-1].split())
        detail = re.sub(r"^\w+\(0x[0-9a-fA-F]+\):\s*", "", detail)   # ITK's "NrrdImageIO(0x55...): "
        detail = detail if len(detail) <= 240 else detail[:240] + " ..."
        raise InvalidInputError(f"cannot read a label map from '{path}': SimpleITK could not read it ({detail})") \
            from None
    if image.GetNumberOfComponentsPerPixel() != 1:
        raise InvalidInputError(f"'{path}' is a vector image ({image.GetNumberOfComponentsPerPixel()} components "
                                "per voxel); a label map has one integer label per voxel")
    dim = image.GetDimension()
    if dim not in (2, 3):
        raise InvalidInputError(f"'{path}' is a {dim}D image; a label map must be 2D or 3D")
    values = sitk.GetArrayViewFromImage(image)   # indexed [k, j, i]
    if not np.issubdtype(values.dtype, np.integer):
        values = _whole_numbers(values, path)
    labels = np.array(values).T                  # [i, j, k], i fastest in memory as in the file
    label_map = LabelMap(labels=labels, origin=np.array(image.GetOrigin()), spacing=np.array(image.GetSpacing()),
                         direction=np.array(image.GetDirection()).reshape(dim, dim))
    if not labels.any():
        raise InvalidInputError(f"the label map '{path}' is empty: every voxel is 0")
    return label_map


def _whole_numbers(values: np.ndarray, path) -> np.ndarray:
    """A float image's values as integers, or an error when they are not whole numbers."""
    if not np.isfinite(values).all():
        raise InvalidInputError(f"'{path}' holds NaN or infinite values; it is not a label map")
    fraction = values != np.round(values)
    if fraction.any():
        where = np.unravel_index(int(np.argmax(fraction)), values.shape)[::-1]
        raise InvalidInputError(
            f"'{path}' is a {values.dtype} image with non-integer values (e.g. {float(values[where[::-1]]):.4g} at "
            f"voxel {tuple(int(i) for i in where)}): it is not a label map; threshold it into labels first "
            "(e.g. SimpleITK: sitk.BinaryThreshold(image, lowerThreshold=0.5))")
    if values.size and (values.min() < np.iinfo(np.int32).min or values.max() > np.iinfo(np.int32).max):
        raise InvalidInputError(f"'{path}' holds values beyond the 32-bit integer range; it is not a label map")
    return values.astype(np.int32)


def import_simpleitk():
    """The SimpleITK module, imported on first use (bitemesh imports without it), or an InvalidInputError."""
    try:
        import SimpleITK
    except ImportError:
        raise InvalidInputError("label maps need SimpleITK (pip install SimpleITK)") from None
    return SimpleITK
