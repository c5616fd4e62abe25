"""The elastic template's front door: a tagged bitemesh mesh moved onto new data with the same cells
(:mod:`bitemesh.core.fem.template`), one frame or a cycle.

The data are read as :func:`bitemesh.mesh` reads an input (:func:`~bitemesh.meshing.read_input`): labelled guide
points, their slices registered as the mesher registers them, pull each of the template's surfaces to their own
contours (EPI to the epicardial, LV_ENDO and RV_ENDO to the endocardial, BASE to the valve points and to the base
the mesher puts on the frame, through the wall points below it carried onto it; a left ventricle's EPI, ENDO and
BASE to the LV's own), scattered points pull the whole boundary, a label map its boundary voxels.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from .core.errors import InvalidInputError
from .core.fem.template import TemplateFit, fit_template
from .core.mesh.quality import quality_summary
from .core.mesh.simplicial import Mesh
from .core.mesh.tags import cavity_volumes
from .core.progress import ProgressCallback, sub_progress
from .core.sources.contours.base import annulus_surface
from .core.sources.contours.cardiac import BIVME_OUTLETS, BIVME_SURFACES, BIVME_VALVES, canonical_labels
from .core.sources.contours.contradicted import without_contradicted
from .core.sources.contours.registration import registered
from .core.sources.contours.slices import infer_slices, slice_planes
from .io import read_mesh
from .meshing import Samples, Voxels, read_input
from .options import as_options

logger = logging.getLogger("bitemesh")

#: the template's surfaces and the guide-point labels that pull each (BASE: the valve annuli); a left ventricle's
#: (tagged EPI, ENDO, BASE as cardiac-geometries tags an LV): its epicardium and septum, its endocardium, its valves.
SURFACE_LABELS = {**BIVME_SURFACES, "BASE": BIVME_VALVES}
LV_SURFACE_LABELS = {"EPI": BIVME_SURFACES["LV_EPI"], "ENDO": BIVME_SURFACES["LV_ENDO"],
                     "BASE": BIVME_OUTLETS["LV_ENDO"]}
#: mm below the frame's base: the wall guide points this near it, carried along its normal onto it, pull the
#: template's BASE with the valve points, so that the fitted walls end where the mesher's base (the annulus surface)
#: puts them; pulled by the valve points alone, the free walls' tops rode up to 12 mm above it at end-systole (biv-me
#: patient1, frame 10: 18 cm2 of EPI, the surfaces 3-4 mm from biv-me's in the top 10 mm).
ANNULUS_BAND = 10.0


@dataclass(frozen=True)
class CycleFit:
    """Frames of a cycle fitted one after the other: ``fits`` (a TemplateFit each, the same cells), ``volumes``
    (f, 2) the LV and RV cavity volumes (ml, closed across the base; NaN without that cavity)."""

    fits: list
    volumes: np.ndarray

    @property
    def end_diastole(self) -> int:
        """The frame of the largest LV volume."""
        return int(np.nanargmax(self.volumes[:, 0]))

    @property
    def end_systole(self) -> int:
        """The frame of the smallest LV volume."""
        return int(np.nanargmin(self.volumes[:, 0]))

    @property
    def ejection_fraction(self) -> float:
        """(EDV - ESV) / EDV of the LV in percent, EDV and ESV the largest and smallest volume of the cycle."""
        lv = self.volumes[:, 0]
        return float(100 * (lv[self.end_diastole] - lv[self.end_systole]) / lv[self.end_diastole])


def template_mesh(template) -> Mesh:
    """A path to a bitemesh mesh, a Mesh, or a MeshingResult -> the tetrahedral Mesh with its tags."""
    if isinstance(template, Mesh):
        return template
    if hasattr(template, "mesh"):
        return template.mesh
    try:
        return read_mesh(template)
    except InvalidInputError as error:
        raise InvalidInputError(f"template: {error} (the template is a bitemesh mesh with its tags, e.g. "
                                "from bitemesh mesh)") from None


def fit_data(template: Mesh, data, frame=None):
    """(measured, carried): the points that pull the template, a mapping of its surface names to points for
    labelled data (its slices registered as :func:`bitemesh.mesh` registers them, a slice no other agrees with left
    out, and the points of a contour the other slices contradict, each with a note on the "bitemesh" logger), an
    (n, 3) array for scattered points or a label map's boundary voxels; and for a template with a BASE, the wall
    points carried onto the base (:func:`on_the_base`) as {"BASE": (k, 3)}, else None."""
    samples = read_input(data, as_options(None if frame is None else {"frame": frame}))
    if isinstance(samples, Voxels):
        return boundary_voxels(samples), None
    if samples.labels is None:
        return samples.points, None
    labels = canonical_labels(samples.labels)[0]
    slices = infer_slices(samples.points) if samples.slices is None else np.asarray(samples.slices)
    points, labels, slices, registration = registered(samples.points, labels, slices, BIVME_SURFACES)
    points, labels, slices, left_out = without_contradicted(points, labels, slices, registration.contradicted,
                                                       BIVME_SURFACES)
    for note in registration.notes() + left_out:
        logger.info(note)
    surfaces = LV_SURFACE_LABELS if is_left_ventricle(template) else SURFACE_LABELS
    pulled = {name: points[np.isin(labels, surfaces[name])] for name in template.tag_names if name in surfaces}
    if not any(len(points) for points in pulled.values()):
        raise InvalidInputError(f"data: none of its labels ({', '.join(sorted(set(labels))[:6])}, ...) samples a "
                                f"surface of the template ({', '.join(sorted(template.tag_names))}); give biv-me "
                                "labels (SAX_LV_ENDOCARDIAL, ...) or scattered points of the whole boundary")
    if "BASE" not in pulled:
        return pulled, None
    walls = [label for name, members in surfaces.items() if name != "BASE" for label in members]
    return pulled, {"BASE": on_the_base(points, labels, slices, walls)}


def frame_base(points, labels, slices):
    """The base the mesher puts on biv-me guide points (registered; canonical labels): the
    :class:`~bitemesh.core.sources.contours.base.BaseSurface` of
    :func:`~bitemesh.core.sources.contours.base.annulus_surface`, or None."""
    return annulus_surface(points, labels, slices, slice_planes(points, slices))[0]


def on_the_base(points, labels, slices, walls) -> np.ndarray:
    """(k, 3) the points labelled with one of ``walls`` within :data:`ANNULUS_BAND` below the base the mesher puts
    on these guide points (:func:`frame_base`), carried along its normal onto it; none without a base."""
    base = frame_base(points, labels, slices)
    if base is None:
        return np.empty((0, 3))
    wall = points[np.isin(labels, walls)]
    depth = base.below(wall)
    near = (depth >= 0) & (depth <= ANNULUS_BAND)
    return wall[near] + depth[near, None] * base.outward(wall[near])


def is_left_ventricle(mesh: Mesh) -> bool:
    """Tagged as an LV alone: ENDO (cardiac-geometries' name), no RV_ENDO."""
    return "ENDO" in mesh.tag_names and "RV_ENDO" not in mesh.tag_names


def boundary_voxels(voxels: Voxels) -> np.ndarray:
    """(n, 3) physical centres of the voxel faces between a labelled and an unlabelled voxel (mm): the label
    region's boundary, not half a voxel inside it."""
    inside = np.pad(voxels.labels != 0, 1)
    faces = []
    for axis in range(3):
        for side in (-1, 1):
            outside = ~np.roll(inside, -side, axis=axis)
            ijk = np.argwhere(inside & outside).astype(np.float64) - 1.0   # the padding's offset
            ijk[:, axis] += 0.5 * side
            faces.append(ijk)
    ijk = np.vstack(faces)
    return ijk @ voxels.ijk_to_physical[:3, :3].T + voxels.ijk_to_physical[:3, 3]


def fit(template, data, *, frame=None, pull: float = 3.0, rest=None,
        progress: ProgressCallback = None) -> TemplateFit:
    """Move ``template`` (a bitemesh mesh: a path, a Mesh or a MeshingResult) onto ``data`` (anything
    :func:`bitemesh.mesh` reads; ``frame`` picks a frame of a GPFile holding several) keeping its cells.

    Returns the :class:`~bitemesh.core.fem.template.TemplateFit`: ``mesh`` (the moved points, the same cells and
    tags, the fibres carried), ``distances`` (each data point to the boundary, mm), ``similarity``, ``rounds``."""
    template = template_mesh(template)
    measured, carried = fit_data(template, data, frame)
    return fit_template(template, measured, pull=pull, rest=None if rest is None else template_mesh(rest),
                        carried=carried, progress=progress)


def fit_cycle(template, frames, *, pull: float = 3.0, progress: ProgressCallback = None) -> CycleFit:
    """Fit ``template`` to each of ``frames`` (data as :func:`fit` takes them, in the cycle's order), each frame
    starting from the last one's fit, the cells' shapes held to the template's."""
    template = template_mesh(template)
    if isinstance(frames, (str, Samples)) or not len(frames):
        raise InvalidInputError("frames: a list of the cycle's data (GPFile paths, ...) is needed, one per frame")
    fits, current = [], template
    for number, data in enumerate(frames):
        step = sub_progress(progress, number / len(frames), (number + 1) / len(frames))
        fitted = fit(current, data, pull=pull, rest=template, progress=step)
        fits.append(fitted)
        current = fitted.mesh
    cavities = ("ENDO", "RV_ENDO") if is_left_ventricle(template) else ("LV_ENDO", "RV_ENDO")
    volumes = np.array([[cavity_volumes(fitted.mesh, cavities).get(name, np.nan) / 1000 for name in cavities]
                        for fitted in fits])
    return CycleFit(fits, volumes)


def frame_fit_row(fitted: TemplateFit) -> dict:
    """The figures of one fit a report lists: distances (mm), cells, the worst cell, rounds, seconds."""
    summary = quality_summary(fitted.mesh)
    return {"data_mean": float(fitted.distances.mean()), "data_p95": float(np.percentile(fitted.distances, 95)),
            "min_dihedral": summary.angle_min, "min_radius_ratio": summary.q_min, "rounds": fitted.rounds,
            "seconds": fitted.seconds}

