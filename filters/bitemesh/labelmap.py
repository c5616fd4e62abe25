"""Label maps: turn the chosen labels into a signed distance on a grid and mesh it, with the mesh placed in the
image's physical space.  Reading the files (NRRD, NIfTI, MetaImage through SimpleITK: ``LabelMap``,
``read_label_map``) is :mod:`bitemesh.io.labelmaps`; ``bitemesh.mesh`` takes files, LabelMaps and voxel arrays.

Frames
------
index : the voxel index (i, j, k); ``labels[i, j, k]`` (axis 0 is i, the fastest axis of the file, as in ITK).
local : the index frame scaled by the voxel size, ``index * spacing``; the grid I and the mesher work here, so
        the grid is axis-aligned whatever the image's direction.
physical : ``origin + direction @ (index * spacing)``, ITK's LPS (mm) for a file; RAS on request, which is
        ``diag(-1, -1, 1)`` of LPS.  Slicer's segments give their IJK-to-RAS matrix, and land in RAS.

Sub-voxel accuracy.  The signed distance (f > 0 inside) is the mean of SimpleITK's Maurer distances of the mask and
of its complement, so that f = 0 halfway between an inside and an outside voxel centre: a staircase, off the true
surface by 0.18 voxel RMS, and, once interpolated multilinearly, inward by about h^2 / 12 per unit curvature
(a convex shape of 5 to 10 voxels radius loses 1 to 4 % of its volume).  f is therefore filtered with
``G - (sigma^2 / 2 + 1 / 12) Laplacian G``, G a Gaussian of ``smoothing`` voxels (default 1): the Gaussian averages
the staircase along the surface, the sigma^2 / 2 term cancels its second moment (a quadratic function, so a
sphere's distance, passes unchanged) and the 1 / 12 term the interpolation's mean bias.  Measured on an ellipsoid
(semi-axes 10, 8, 6 mm) at voxel sizes 2 to 0.25 mm, isotropic and 0.8 : 1 : 1.6: the error of f on the true
surface drops from 0.14-0.19 to 0.08-0.10 voxel RMS, its mean from -0.01..-0.06 to 0.000..-0.015 voxel, and the
volume of {f > 0} from -0.03..-3.9 % to within 0.1 % (-0.7 % at 2 mm voxels), so that the mesh loses no more than a
mesh of the analytic shape does.  Every voxel centre stays on its side of f = 0; a rod or plate one voxel thin
survives but thinner than the staircase makes it (``smoothing=0`` keeps the plain distance).
"""
from __future__ import annotations

import logging
import numbers

import numpy as np

from .core.mesh.betti import grid_parts
from .core.errors import InvalidInputError, check_number
from .core.grid.sampled import ImplicitGrid
from .core.mesh.interfaces import LabelRegions
from .core.parameters import (BitingParameters, FidelityParameters, ImplicitParameters, OptimizeParameters,
                              SpuriousParameters)
from .core.progress import ProgressCallback, report, sub_progress
from .core.sources.source import Frame, Source
from .core.steps.spine import MeshingResult, mesh_source, timed
from .core.mesh.tags import region_labels
from .io.labelmaps import import_simpleitk

logger = logging.getLogger("bitemesh")

#: voxels of background added on every side, so that a label touching the image border still closes.
PAD_VOXELS = 2
#: default width (standard deviation, in voxels) of the filter that takes the staircase out of the distance.
SMOOTHING_VOXELS = 1.0
#: mean of (f - its multilinear interpolant) over a cell, in units of f'' h^2 (a 1D segment: h^2 / 12).
INTERPOLATION_BIAS = 1.0 / 12.0
#: after the filter, |f| at a voxel centre is at least this fraction of its plain distance (see _remove_staircase).
CENTRE_FLOOR = 0.1
#: bytes per voxel that the distance computation holds at once (mask, two distance maps, f and its filtering).
DISTANCE_BYTES_PER_VOXEL = 48
#: a part of the labels with fewer voxels than 2^dim (a 2 x 2 x 2 block) is a speck the image cannot resolve as a
#: shape (segmentation noise): dropped with a note, or, when every part is one, refused.
SPECK_VOXELS_PER_DIM = 2


# --------------------------------------------------------------------------------------------- labels -> f


def label_mask(labels: np.ndarray, label=None):
    """The domain's voxels: (mask, labels meshed).

    Parameters
    ----------
    labels : integer array of any shape
    label : None (every nonzero voxel), one int, or an iterable of ints (their union)

    Returns
    -------
    mask : bool array like ``labels``; chosen : tuple of the labels taken (empty for None)
    """
    labels = np.asarray(labels)
    if label is None:
        mask = labels != 0
        if not mask.any():
            raise InvalidInputError("the label map is empty: every voxel is 0")
        return mask, ()
    wanted = (label,) if isinstance(label, (numbers.Integral, np.integer)) else tuple(label) \
        if not isinstance(label, (str, bytes, float)) else (label,)
    for value in wanted:
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Integral, np.integer)):
            raise InvalidInputError(f"labels must be whole numbers, got {label!r}")
    if not wanted:
        raise InvalidInputError("labels is an empty set; give one label or more, or None for every nonzero voxel")
    chosen = tuple(sorted({int(value) for value in wanted}))
    present = np.unique(labels)
    absent = [value for value in chosen if value not in present]
    if absent:
        shown = present[present != 0]
        listed = ", ".join(map(str, shown[:30].tolist())) + (f", ... ({len(shown)} labels)" if len(shown) > 30 else "")
        raise InvalidInputError(
            f"label{'s' if len(absent) > 1 else ''} {', '.join(map(str, absent))} "
            f"{'are' if len(absent) > 1 else 'is'} absent from the label map; labels present: "
            f"{listed or 'none (every voxel is 0)'}")
    return np.isin(labels, chosen), chosen


def label_map_to_grid(labels: np.ndarray, origin, spacing, label=None, *,
                      smoothing: float = SMOOTHING_VOXELS) -> ImplicitGrid:
    """f > 0 inside the chosen labels, about the signed distance to their boundary (input units).

    Parameters
    ----------
    labels : (n_x, n_y[, n_z]) integer array, indexed [i, j(, k)] with axis 0 along x
    origin : (k,) position of voxel (0, 0(, 0)); spacing : (k,) voxel size (input units)
    label : the domain: one label, a set of labels (their union), or None for every nonzero voxel
    smoothing : standard deviation (voxels) of the filter that removes the staircase; 0 keeps the plain distance

    Returns
    -------
    ImplicitGrid on the voxel centres, with PAD_VOXELS of background added on every side.

    f is the mean of SimpleITK's signed Maurer distances of the mask and of its complement (f = 0 halfway between
    an inside and an outside voxel centre), filtered with ``G - (sigma^2 / 2 + 1 / 12) Laplacian G`` where G is a
    Gaussian of ``smoothing`` voxels (see the module's docstring for why and for the measured accuracy).  Every
    voxel centre keeps its side: inside voxels keep f > 0, so that thin structures are not filtered away.
    """
    sitk = import_simpleitk()
    mask, _ = label_mask(labels, label)
    smoothing = check_number(smoothing, "smoothing", low=0, high=10, hint="in voxels; 1 is the default, 0 is off")
    # The filter reaches int(4 sigma + 0.5) voxels (scipy's truncate = 4): pad that much more background, so that
    # it sees true distances to the end, and crop it off afterwards.
    extra = _filter_padding(smoothing)
    mask = np.pad(mask, PAD_VOXELS + extra)
    spacing = np.asarray(spacing, dtype=np.float64)

    def signed_distance(region: np.ndarray) -> np.ndarray:
        image = sitk.GetImageFromArray(region.T.astype(np.uint8))  # SimpleITK arrays are indexed [z, y, x]
        image.SetSpacing(tuple(float(s) for s in spacing))
        distance = sitk.SignedMaurerDistanceMap(image, insideIsPositive=False, squaredDistance=False,
                                                useImageSpacing=True)
        return sitk.GetArrayFromImage(distance).T.astype(np.float64)

    values = 0.5 * (signed_distance(~mask) - signed_distance(mask))
    if smoothing > 0:
        inner = (slice(extra, -extra),) * mask.ndim
        values = np.ascontiguousarray(_remove_staircase(values, mask, smoothing)[inner])
    return ImplicitGrid(origin=np.asarray(origin, dtype=np.float64) - PAD_VOXELS * spacing, spacing=spacing,
                        values=values)


def _filter_padding(smoothing: float) -> int:
    """Voxels of background the filter of width ``smoothing`` needs beyond PAD_VOXELS (0 without filter)."""
    return int(4 * smoothing + 0.5) + 1 if smoothing > 0 else 0


def _remove_staircase(values: np.ndarray, mask: np.ndarray, sigma: float) -> np.ndarray:
    """(G - (sigma^2 / 2 + 1 / 12) Laplacian G) * values, sigma in voxels along every axis (Laplacian in voxel
    units); voxel centres keep their side."""
    from scipy import ndimage
    smooth = ndimage.gaussian_filter(values, sigma, mode="nearest")
    # sigma_x^2 d2/dx^2 = sigma^2 d2/di^2 (sigma in voxels, derivative per voxel).  The extra 1/12 cancels the
    # mean bias of multilinear interpolation between voxel centres (f - L averages -f'' h^2 / 12 over a cell),
    # which moves the zero level of a convex shape's distance inward by about h^2 / (12 r) per curved direction.
    weight = 0.5 * sigma**2 + INTERPOLATION_BIAS
    for axis in range(values.ndim):
        order = [0] * values.ndim
        order[axis] = 2
        smooth -= weight * ndimage.gaussian_filter(values, sigma, order=order, mode="nearest")
    # The voxel centres are data: inside ones stay inside, outside ones outside.  The floor (a tenth of the plain
    # distance, so 0.05 voxel at the border) keeps f = 0 off the centres of a one-voxel-thin structure.
    floor = CENTRE_FLOOR * np.abs(values)
    return np.where(mask, np.maximum(smooth, floor), np.minimum(smooth, -floor))


# --------------------------------------------------------------------------------------------- meshing

#: the noise level of a label map's surface, in voxels: a staircase between voxel centres (the fidelity check
#: allows R + 3 x this).
STAIRCASE_NOISE = 0.5


def mask_faces(mask: np.ndarray, origin, spacing) -> np.ndarray:
    """(n, k) the centres of the voxel faces between the mask and its outside: the label map's surface samples.

    ``origin`` is the position of ``mask[0, ..., 0]``'s centre, ``spacing`` the voxel size (local frame)."""
    padded = np.pad(mask, 1)
    faces = []
    for axis in range(mask.ndim):
        change = np.diff(padded, axis=axis) != 0
        index = np.argwhere(change).astype(np.float64) - 1.0
        index[:, axis] += 0.5
        faces.append(index)
    return np.asarray(origin) + np.vstack(faces) * np.asarray(spacing)


#: the result of :func:`mesh_label_grid`: mesh and nodes in physical space, ``implicit`` in the local frame (index x
#: spacing) that ``to_physical`` maps to physical space, ``labels`` the labels meshed.
LabelMapMeshingResult = MeshingResult


def label_grid_source(labels_ijk: np.ndarray, ijk_to_physical, *, labels=None,
                      implicit: ImplicitParameters = ImplicitParameters(), smoothing: float = SMOOTHING_VOXELS,
                      progress: ProgressCallback = None) -> Source:
    """The chosen labels of a voxel array as a :class:`~bitemesh.core.sources.source.Source`: their signed distance on
    the voxel grid (cropped to the labels' box, smoothed, :func:`label_map_to_grid`) in the local frame (index x
    spacing), the voxel faces as samples, and the frame to physical space that ``ijk_to_physical`` gives.

    See :func:`mesh_label_grid` for the parameters; ``implicit.max_memory_mb`` bounds the distance's memory.  With
    several labels each label's own distance is made too (the same filter), for the regions
    (:class:`~bitemesh.core.mesh.interfaces.LabelRegions`: the source's tagging and interfaces).
    """
    labels_ijk = np.asarray(labels_ijk)
    dim = labels_ijk.ndim
    matrix = np.asarray(ijk_to_physical, dtype=np.float64)
    if dim not in (2, 3) or matrix.shape != (dim + 1, dim + 1) or not np.isfinite(matrix).all():
        raise InvalidInputError(f"ijk_to_physical must be a finite {dim + 1} x {dim + 1} matrix for a {dim}D label "
                                f"array, got shape {matrix.shape}")
    spacing = np.linalg.norm(matrix[:dim, :dim], axis=0)
    if not (spacing > 0).all() or abs(np.linalg.det(matrix[:dim, :dim] / spacing)) < 1e-6:
        raise InvalidInputError("ijk_to_physical: its linear part must be invertible (voxel sizes > 0)")
    mask, chosen = label_mask(labels_ijk, labels)
    mask, notes = without_specks(mask)

    # Crop to the domain's bounding box: the distance and the grid need not cover empty image.
    box = [np.flatnonzero(mask.any(axis=tuple(a for a in range(dim) if a != axis))) for axis in range(dim)]
    first = np.array([b[0] for b in box])
    crop = tuple(slice(b[0], b[-1] + 1) for b in box)
    mask, cropped = mask[crop], labels_ijk[crop]
    regions = region_labels(cropped[mask])
    smoothing = check_number(smoothing, "smoothing", low=0, high=10, hint="in voxels; 1 is the default, 0 is off")
    padding = 2 * (PAD_VOXELS + _filter_padding(smoothing))
    # one distance at a time; with several labels each label's distance is kept too (8 bytes a voxel)
    per_voxel = DISTANCE_BYTES_PER_VOXEL + (8 * len(regions) if len(regions) > 1 else 0)
    needed_mb = np.prod(np.array(mask.shape, float) + padding) * per_voxel / 2**20
    if needed_mb > implicit.max_memory_mb:
        raise InvalidInputError(
            f"the labels span {' x '.join(map(str, mask.shape))} voxels; their signed distance"
            f"{f's ({len(regions)} labels and their union)' if len(regions) > 1 else ''} need about "
            f"{needed_mb:.0f} MiB, more than max_memory_mb = {implicit.max_memory_mb:g}; raise max_memory_mb, "
            "resample the label map to coarser voxels" + (" or mesh fewer labels" if len(regions) > 1 else ""))

    report(progress, 0.5, "signed distance of the labels")
    grid = label_map_to_grid(mask, first * spacing, spacing, smoothing=smoothing)
    several = None if len(regions) == 1 else LabelRegions({
        int(label): label_map_to_grid(cropped == label, first * spacing, spacing, smoothing=smoothing)
        for label in regions})
    # Local frame (index x spacing) -> physical: the unit columns of the matrix, then its translation.
    frame = Frame(matrix[:dim, :dim] / spacing[None, :], matrix[:dim, dim])
    voxel = float(np.max(spacing))
    return Source(grid, grid.origin, grid.upper, frame, grid=grid, samples=mask_faces(mask, first * spacing, spacing),
                  noise=STAIRCASE_NOISE * voxel, gap=float(np.linalg.norm(spacing)), labels=chosen,
                  tagging=LabelRegions({int(regions[0]): grid}) if several is None else several,
                  interfaces=several, notes=notes)


def without_specks(mask: np.ndarray):
    """``mask`` without its parts of fewer than 2^dim voxels (26- or 8-connected), and a note saying how many went;
    refuse a mask whose every part is such a speck."""
    parts, count = grid_parts(mask)
    sizes = np.bincount(parts.ravel())[1:]
    smallest = SPECK_VOXELS_PER_DIM ** mask.ndim
    specks = np.flatnonzero(sizes < smallest) + 1
    if len(specks) == count:
        raise InvalidInputError(
            f"the labels hold {int(sizes.sum())} voxel(s) in {count} part(s), the largest of {int(sizes.max())}: "
            f"too small for the image to resolve a shape (a part needs {smallest} voxels or more, a block of "
            f"{SPECK_VOXELS_PER_DIM} voxels a side); check the label, or resample the label map to finer voxels")
    if not len(specks):
        return mask, ()
    note = (f"dropped {len(specks)} speck(s) of the labels, part(s) of fewer than {smallest} voxels "
            f"({int(sizes[specks - 1].sum())} voxels in all): segmentation noise the image cannot resolve as a shape")
    logger.info(note)
    return mask & ~np.isin(parts, specks), (note,)


def mesh_label_grid(labels_ijk: np.ndarray, ijk_to_physical, *, labels=None,
                    implicit: ImplicitParameters | None = None, biting: BitingParameters | None = None,
                    spurious: SpuriousParameters | None = None,
                    optimize: OptimizeParameters = OptimizeParameters(), fidelity: FidelityParameters | None = None,
                    smoothing: float = SMOOTHING_VOXELS, progress: ProgressCallback = None,
                    seconds: dict | None = None) -> LabelMapMeshingResult:
    """Mesh the chosen labels of a voxel array and place the mesh with a homogeneous index-to-physical matrix.

    The one path from voxels to a mesh: ``bitemesh.mesh`` takes label map files, LabelMaps and Voxels (the Slicer
    module's segments) through it.

    Parameters
    ----------
    labels_ijk : (n_i, n_j, n_k) (or (n_i, n_j)) integer array indexed [i, j, k]
    ijk_to_physical : (k + 1, k + 1) float64, voxel index -> physical point (spacing included: its columns have
        the voxel sizes as lengths), e.g. ITK's ``[direction @ diag(spacing) | origin]`` or Slicer's IJK-to-RAS
    labels : None (every nonzero voxel), one int, or a set of ints: the domain is their union, meshed as one mesh
        with a region per label (see Returns)
    implicit : ImplicitParameters or None (defaults); its grid_spacing (the grid I; default R / 4, or the voxels
        when their largest size is between R / 8 and R / 4) and max_memory_mb are used; method, error_bound and
        margin do not apply to label maps
    biting, spurious, optimize : BitingParameters, SpuriousParameters and OptimizeParameters, as for
        :func:`~bitemesh.core.sources.points.mesh_from_grid`; None: the defaults
    fidelity : FidelityParameters, the bounds of the fidelity check against the voxel faces (default: its defaults)
    smoothing : see :func:`label_map_to_grid`

    Returns
    -------
    LabelMapMeshingResult: mesh (positively oriented cells, quality arrays) and nodes in physical space; implicit
    in the local frame (index x spacing), which ``to_physical`` maps to physical space.  The mesh's cells carry
    ``Region`` = their label (``REGION_<label>``: the label whose smoothed distance is largest at the centroid);
    its facets the tags of :func:`~bitemesh.core.mesh.tags.region_tags` (``BOUNDARY_<label>``, ``INTERFACE_<a>_<b>``).
    With several labels the regions share the nodes of their interfaces, which the biting samples and
    :func:`~bitemesh.core.mesh.interfaces.snap_interfaces` moves onto f_a = f_b.

    The grid I is axis-aligned in the local frame; the mesh is made there and then mapped to physical space, so
    the image's direction costs nothing.  A reflection (direction with negative determinant) would turn every
    cell inside out: two vertices of each cell are swapped back.
    """
    seconds = {} if seconds is None else seconds
    implicit = ImplicitParameters() if implicit is None else implicit
    with timed(seconds, "distance"):
        source = label_grid_source(labels_ijk, ijk_to_physical, labels=labels, implicit=implicit,
                                   smoothing=smoothing, progress=sub_progress(progress, 0.0, 0.1))
    return mesh_source(source, implicit, biting or BitingParameters(), spurious or SpuriousParameters(), optimize,
                       sub_progress(progress, 0.1, 1.0), seconds, fidelity or FidelityParameters())
