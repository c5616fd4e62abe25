"""The verdict on a mesh against its data: refused or kept, and why, in words a user can act on.

:func:`judge_fidelity` measures a mesh against its source's samples (:mod:`.fidelity`), leaving out the samples of
parts dropped on purpose (:func:`samples_kept`), and :func:`check_fidelity` refuses it beyond the bounds, naming the
cause found in the data: the source's suspects (outliers kept, normals that disagree), where the far samples lie
(contours: their slice; else parts of f thinner than R, :func:`thinner_than_radius`, with the radius that resolves
them), or an opening of the samples that the mesh closes (:func:`openings`: an open surface and its rim).  A mesh
kept that closes a wide area where no point is gets a note saying where.
"""
from __future__ import annotations

import logging
import warnings
from functools import cache

import numpy as np
from scipy.spatial import cKDTree

from ..errors import BitemeshWarning, MeshingError, point_text
from ..mesh.betti import on_dropped_parts
from ..mesh.simplicial import Mesh
from ..mesh.topology import boundary_facets, connected_components
from ..parameters import FidelityParameters
from ..mesh.simplicial import facet_measures
from .fidelity import Fidelity, far_from, measure_fidelity

logger = logging.getLogger("bitemesh")

#: the neighbours that tell a sample on the rim of an open surface (all on one side) from one inside it, the
#: widest angle between them that a sample inside leaves (12 neighbours around: about 30 degrees; on a rim: 180),
#: and how much farther than the samples' median they may reach on a rim (a stray point's reach far farther).
RIM_NEIGHBOURS, RIM_GAP, RIM_SPREAD = 12, 2 * np.pi / 3, 3.0


def openings(mesh: Mesh, samples: np.ndarray, bound: float) -> list:
    """Where the boundary of ``mesh`` lies farther than ``bound`` from every one of the ``samples`` (n, k), piece by
    piece (facets joined through shared edges) at least ``bound`` across (narrower: a gap of random sampling), the
    largest first: for each, (its centre (k,), its width, the samples on its rim), the rim's samples counted when
    those nearest to it are mostly on a rim (their neighbours on one side only: an open surface, a scan with a side
    missing), else 0 (samples all round it: where sampled surfaces meet); [] when there is none."""
    facets = boundary_facets(mesh.cells)
    corners = mesh.points[facets]
    centroids = corners.mean(axis=1)
    tree = cKDTree(samples)
    distance, nearest = tree.query(centroids)
    far = np.flatnonzero(distance > bound)
    if not len(far):
        return []
    area = facet_measures(corners[far])
    pieces = connected_components(facets[far])
    neighbours = min(RIM_NEIGHBOURS, len(samples) - 1)
    typical = np.median(tree.query(samples[::max(1, len(samples) // 2000)], neighbours + 1)[0][:, -1])
    found = []
    for piece in np.argsort(-np.bincount(pieces, weights=area), kind="stable"):
        mine = pieces == piece
        centre = (centroids[far[mine]] * area[mine, None]).sum(axis=0) / area[mine].sum()
        width, rim_count = 2 * float(np.linalg.norm(centroids[far[mine]] - centre, axis=1).max()), 0
        if width < bound:
            continue
        if neighbours >= samples.shape[1] + 1:
            rim = samples[np.unique(nearest[far[mine]])]
            reach, around = tree.query(rim, neighbours + 1)
            # on a rim: the neighbours on one side, and as near as elsewhere (a stray point has them on one side too)
            one_sided = (widest_gaps(rim, samples[around[:, 1:]]) > RIM_GAP) & (reach[:, -1] < RIM_SPREAD * typical)
            if one_sided.mean() >= 0.5:
                width = 2 * float(np.linalg.norm(rim[one_sided] - centre, axis=1).max())
                rim_count = int(one_sided.sum())
        found.append((centre, width, rim_count))
    return found


def widest_gaps(points: np.ndarray, neighbours: np.ndarray) -> np.ndarray:
    """(m,) the widest angle (radians) between the directions to the ``neighbours`` (m, j, k) of each of the
    ``points`` (m, k), seen in the plane of least variance of the neighbourhood (along the line, in 2D: 0 or pi):
    about 2 pi / j inside a sampled surface, about pi on its rim."""
    offsets = neighbours - points[:, None, :]
    local = np.concatenate([points[:, None, :], neighbours], axis=1)
    axes = np.linalg.svd(local - local.mean(axis=1, keepdims=True))[2]   # (m, k, k): rows by falling variance
    if points.shape[1] == 2:
        along = np.einsum("mjk,mk->mj", offsets, axes[:, 0])
        return np.where((along > 0).any(axis=1) & (along < 0).any(axis=1), 0.0, np.pi)
    angles = np.sort(np.arctan2(np.einsum("mjk,mk->mj", offsets, axes[:, 1]),
                                np.einsum("mjk,mk->mj", offsets, axes[:, 0])), axis=1)
    return np.diff(np.concatenate([angles, angles[:, :1] + 2 * np.pi], axis=1), axis=1).max(axis=1)


def check_fidelity(fidelity: Fidelity, parameters: FidelityParameters, units: str = "", where=None,
                   unsupported=None) -> list:
    """The bounds of ``parameters`` that ``fidelity`` exceeds, as messages; raise :class:`MeshingError` naming them
    unless ``parameters.allow_unfaithful``, which turns them into a :class:`BitemeshWarning`.  ``where`` and
    ``unsupported``: callables () -> a sentence saying where the far samples lie, and where the unsupported
    boundary is, each with a hint, said instead of the likely causes when not empty (each is called only when its
    bound is exceeded)."""
    problems, located = [], ""
    if fidelity.far_samples > parameters.far_samples:
        located = where() if where is not None else ""
        problems.append(
            f"{fidelity.far_samples:.1f}% of the input points lie farther than {fidelity.far_bound:.3g}{units} "
            f"(R + 3 x noise) from the mesh boundary (allowed: far_samples = {parameters.far_samples:g}%; up to "
            f"{fidelity.to_boundary_max:.3g}{units}): the mesh lost part of the shape")
    if fidelity.unsupported_area > parameters.unsupported_area:
        problems.append(
            f"{fidelity.unsupported_area:.1f}% of the boundary's area lies farther than "
            f"{fidelity.support_bound:.3g}{units} (R + half the data's gap) from every input point (allowed: "
            f"unsupported_area = {parameters.unsupported_area:g}%; up to {fidelity.from_samples_max:.3g}{units}): "
            "the mesh has surfaces the data does not support")
        opened = unsupported() if unsupported is not None else ""
        located = "; ".join(sentence for sentence in (located, opened) if sentence)
    if problems:
        causes = located[:1].upper() + located[1:] if located else (
            "Likely causes: outliers, normals that do not point outward, a wrong column layout, or parts thinner "
            "than R; check the input, lower radius")
        text = ("the mesh does not follow the data: " + "; ".join(problems) + f". {causes}; or set "
                "allow_unfaithful (--allow-unfaithful) to keep the mesh anyway")
        if not parameters.allow_unfaithful:
            raise MeshingError(text)
        warnings.warn(text, BitemeshWarning, stacklevel=2)
    return problems


def thinner_than_radius(grid, inside: np.ndarray, samples: np.ndarray, radius: float, scale: float = 1.0) -> str:
    """Where far ``samples`` (m, k) lie on parts of f > 0 thinner than R: a sentence with the radius that resolves
    them (in user units: lengths x ``scale``), from the half-thickness of f > 0 (``inside``, on the nodes of
    ``grid``: its largest inscribed distance within R of each sample); "" when most of them do not.  The radius
    given is half the parts' median thickness there: two node spacings across them, which the optimizer keeps (at
    one spacing across, its sliver removal takes the thin tips of a slender ellipsoid off)."""
    from scipy import ndimage
    if not len(samples):
        return ""
    half = ndimage.distance_transform_edt(inside, sampling=grid.spacing)
    reach = int(np.ceil(radius / float(np.min(grid.spacing))))
    thickness = ndimage.maximum_filter(half, size=2 * reach + 1)[grid.nearest_nodes(samples)]
    thin = (thickness > 0) & (thickness < radius)
    if thin.mean() < 0.5:
        return ""
    half = float(np.median(thickness[thin]))   # two node spacings across the part
    return (f"{int(thin.sum())} of those {len(samples)} points lie on parts thinner than R = {radius * scale:.4g} "
            f"(about {2 * half * scale:.3g} across there): give radius <= {half * scale:.3g}, or about "
            f"{max(2.0, (radius / half) ** inside.ndim):.0f} x the cells")


#: scattered points whose mesh closes openings of them over more than this percent of its boundary's area (a quarter
#: of the unsupported share refused by default) get a note saying where.
CAPPED_NOTE = 0.5
#: at most this many openings are named, the largest first.
MAX_NAMED = 3


def judge_fidelity(source, mesh: Mesh, grid, inside: np.ndarray, radius: float, parameters: FidelityParameters,
                   min_component: float) -> tuple:
    """Measure ``mesh`` (local frame) against the samples of ``source`` (a Source) but those of parts dropped on
    purpose (:func:`samples_kept`), and refuse it beyond the bounds of ``parameters``
    (:func:`check_fidelity`) naming where and why: the source's suspects (outliers, normals), the far samples' place
    (contours: their slice; else parts of f, ``inside`` on the nodes of ``grid``, thinner than ``radius``), an
    opening of scattered samples; a mesh of scattered points that closes more than :data:`CAPPED_NOTE` % of its
    boundary where no point is gets a note saying where.  Returns (the :class:`Fidelity` in user units, notes)."""
    frame = source.frame
    kept, notes = samples_kept(source.samples, inside, grid, mesh, min_component)
    samples = source.samples[kept]
    measured = measure_fidelity(mesh, samples, radius, source.noise, source.gap,
                                source.open_boundary).scaled(frame.scale)

    def where() -> str:   # the far samples' place, as the source (contours: their slice) or f's grid tells it
        said = source.suspects() if source.suspects is not None else ""
        if said:
            return said
        far = far_from(mesh, samples, measured.far_bound / frame.scale)
        if source.locate is not None:
            return source.locate(np.flatnonzero(kept)[far])
        return thinner_than_radius(grid, inside, samples[far], radius, frame.scale)

    @cache   # asked by the refusal (kept with allow_unfaithful) and by the note
    def opened() -> tuple:   # (where the boundary lies far from every sample, whether on a rim of them)
        found = openings(mesh, samples, measured.support_bound / frame.scale)
        if not found:
            return "", False
        said = [f"about {width * frame.scale:.3g} across around {point_text(frame.to_user(centre[None])[0])}"
                + (f", {rim} samples on its rim" if rim else ", samples all round it")
                for centre, width, rim in found[:MAX_NAMED]]
        more = f" (and {len(found) - MAX_NAMED} smaller)" if len(found) > MAX_NAMED else ""
        if not found[0][2]:
            return f"{'; '.join(said)}{more}", False
        what = "an opening" if len(found) == 1 else f"{len(found)} openings"
        return f"the samples leave {what}: {'; '.join(said)}{more}", True

    def unsupported() -> str:
        said, on_rim = opened()
        return (f"{said}: the surface is open there (a scan with a side or a patch missing) and the mesh closes "
                "it where no point is; sample the missing part") if on_rim else ""
    scattered = source.locate is None and source.open_boundary is None   # not contours: a rim means an opening
    check_fidelity(measured, parameters, where=where, unsupported=unsupported if scattered else None)
    closed = measured.capped_area + measured.unsupported_area
    said, on_rim = opened() if scattered and closed > CAPPED_NOTE else ("", False)
    if said:
        extent = "area" if mesh.points.shape[1] == 3 else "length"
        notes += ((f"{said}, which the mesh closes where no point is" if on_rim else
                   f"the mesh's boundary lies far from every point in an area {said}: a gap of the samples that the "
                   "mesh closes, or sampled surfaces that meet there (objects in contact, joined by the mesh)")
                  + f" ({closed:.1f}% of the boundary's {extent} lies farther than {measured.support_bound:.3g} "
                  f"from every point, {measured.capped_area:.1f}% of it with points all round): the surface there "
                  "is the fit's guess",)
        logger.info(notes[-1])
    return measured, notes


def samples_kept(samples: np.ndarray, inside: np.ndarray, grid, mesh: Mesh, min_component: float):
    """(n,) bool, the samples the fidelity measures: all but those of parts dropped on purpose (smaller than
    ``min_component`` x the largest, :func:`~bitemesh.core.mesh.betti.on_dropped_parts`); and a note when some are
    not."""
    dropped, parts = on_dropped_parts(grid, inside, mesh.points[mesh.cells].mean(axis=1), samples, min_component)
    if not parts:
        return ~dropped, ()
    note = f"{parts} part(s) smaller than min_component = {min_component:g} x the largest part's volume dropped; " + (
        f"their {int(dropped.sum())} samples are left out of the fidelity measure" if dropped.any() else
        "no sample lies on them (specks of the fitted surface away from the data)")
    logger.info(note)
    return ~dropped, (note,)
