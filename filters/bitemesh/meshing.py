"""The front door: any input and one :class:`~bitemesh.options.Options` -> one meshing result.

It reads the input (a file, arrays, a VTK data set), picks the source by kind (scattered points, labelled
contours, a label map), runs the spine and what follows it (the heart's plausibility check, the fibres) and hands
back the result with its report.  The command line, the cohorts, the VTK filters, ParaView and the Slicer module
all call it; no other module tells inputs apart.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Optional

import numpy as np

from .core.columns import AXES
from .core.compiled import using_threads
from .core.errors import InvalidInputError
from .core.fem.coordinates import POINT_ARRAY_FORMATS, with_coordinates
from .core.fem.fibres import FIBRE_ARRAYS, FibreParameters, warn_thin_walls, with_fibres
from .core.parameters import ImplicitParameters, LabelledParameters
from .core.progress import ProgressCallback, report, sub_progress
from .core.sources.contours.cardiac import canonical_labels, is_bivme
from .core.sources.contours.run import labelled_keywords, labelled_source, run_labelled, two_cells_across
from .core.sources.points import points_source, run
from .core.sources.source import Source
from .core.sources.spacetime import (SPACE_TIME_CELLS, frame_instants, space_time_radius,
                                          space_time_source)
from .core.steps.spine import MeshingResult, mesh_source
from .io import (LABEL_MAP_EXTENSIONS, LABELLED_EXTENSIONS, MESH_EXTENSIONS, NO_CELL_ARRAYS, POINT_EXTENSIONS,
                 LabelMap, check_holds, looks_labelled, read_label_map, read_labelled_config, read_labelled_points,
                 read_points, write_mesh)
from .io.opencarp import MICROMETRES
from .labelmap import label_grid_source, mesh_label_grid
from .options import Options, as_options, flag

#: the files :func:`mesh` reads: point tables and surfaces, labelled contours, label maps.
INPUT_EXTENSIONS = tuple(sorted(set(POINT_EXTENSIONS) | set(LABELLED_EXTENSIONS) | set(LABEL_MAP_EXTENSIONS)))


@dataclass(frozen=True)
class Samples:
    """Points in memory: (n, k) float64 points (k = 2 or 3), optional (n, k) outward normals; with (n,) labels (str
    or int, one per point) they are labelled contours, with (n,) int slice ids the contour each was traced on."""

    points: np.ndarray
    normals: Optional[np.ndarray] = None
    labels: Optional[np.ndarray] = None
    slices: Optional[np.ndarray] = None


@dataclass(frozen=True)
class Voxels:
    """A label map in memory: (n_i, n_j[, n_k]) integer labels indexed [i, j, k] and the (k + 1, k + 1) matrix from
    voxel index to physical point (mm; the voxel sizes as its columns' lengths)."""

    labels: np.ndarray
    ijk_to_physical: np.ndarray


def read_input(input, options: Options) -> Samples | Voxels:
    """``input`` as Samples or Voxels: a path (a point table, a VTK-readable surface, labelled contours, a label
    map), a LabelMap, an (n, k) array of points, a VTK point set or image, or Samples or Voxels themselves."""
    if isinstance(input, (Samples, Voxels)):
        data = input
    elif isinstance(input, LabelMap):
        data = Voxels(input.labels, input.index_to_physical(ras=options.ras))
    elif isinstance(input, (str, os.PathLike)):
        data = read_file(Path(input), options)
    elif hasattr(input, "IsA"):   # a VTK data object
        from .convert import dataset_samples, image_voxels
        data = Voxels(*image_voxels(input)) if input.IsA("vtkImageData") else Samples(*dataset_samples(input))
    elif isinstance(input, (np.ndarray, list, tuple)):
        data = Samples(np.asarray(input, dtype=np.float64))
    else:
        raise InvalidInputError(f"input: {type(input).__name__} is not a mesh input; give a file path, an (n, 3) "
                                "array of points, bitemesh.Samples, bitemesh.Voxels, a LabelMap or a VTK data set")
    check_applies(data, options, input)
    return data


def read_file(path: Path, options: Options) -> Samples | Voxels:
    """A file as Samples or Voxels, by its extension and, for tables and VTK files, whether it has labels."""
    name = str(path)
    if name.lower().endswith(LABEL_MAP_EXTENSIONS):
        if options.columns or options.dimension:
            raise InvalidInputError(f"--{'columns' if options.columns else 'dimension'} applies to text tables, not "
                                    f"to the label map '{path}'")
        label_map = read_label_map(path)
        return Voxels(label_map.labels, label_map.index_to_physical(ras=options.ras))
    if looks_labelled(path) or "label" in options.columns.lower():
        if options.dimension not in (None, 3):
            raise InvalidInputError(f"--dimension {options.dimension}: '{path}' holds labelled contours, whose points "
                                    "have 3 coordinates; leave --dimension out")
        points, labels, slices = read_labelled_points(path, columns=options.columns or None, frame=options.frame)
        return Samples(points, labels=labels, slices=slices)
    return Samples(*read_points(path, options.columns or None, options.dimension))


def check_applies(data, options: Options, input) -> None:
    """Refuse options given for another kind of input: the labelled-contour options (and --frame, --config) for
    anything but labelled contours, the label-map options for anything but a label map, a unit other than mm for
    cardiac guide points."""
    labelled = isinstance(data, Samples) and data.labels is not None
    given = options.given(LabelledParameters)
    contour_options = [flag(name) for name in ("config", "frame") if getattr(options, name) is not None] + \
        [flag(name) for name in given]
    if contour_options and not labelled:
        what = f"'{input}'" if isinstance(input, (str, os.PathLike)) else "the input"
        option = contour_options[0]
        if isinstance(data, Voxels):
            reason, hint = "is a label map (--label chooses its labels)", ""
        else:
            reason, hint = ("has no label column or Label array (a biv-me GPFile, a table whose header names a label "
                            "column, a VTP with a Label point array)", " to mesh the points as one surface")
        raise InvalidInputError(f"{option} applies to labelled contours, and {what} {reason}; leave {option} out{hint}")
    if not isinstance(data, Voxels):
        if options.label is not None:
            raise InvalidInputError(f"--label {' '.join(map(str, options.label))} applies to label maps; leave it "
                                    "out to mesh these points")
        if options.ras:
            raise InvalidInputError("--ras applies to label maps (points and contours keep the coordinates they are "
                                    "given in); leave it out to mesh these points")
    if labelled and options.unit != "mm" and is_bivme(canonical_labels(data.labels)[0]):
        raise InvalidInputError(
            f"unit (--unit {options.unit}): cardiac guide points are meshed in mm (the walls, valves and base are "
            f"measured in mm); give the coordinates in mm (multiply them by {MICROMETRES[options.unit] / 1000:g}) and "
            "leave --unit out")


def contour_keywords(options: Options) -> dict:
    """The keywords of run_labelled and labelled_source: every labelled-contour option, the config file's values
    over the defaults, the options given over both."""
    parameters = options.of(LabelledParameters)
    config = read_labelled_config(options.config) if options.config else {}
    return {**labelled_keywords(parameters), **config, **labelled_keywords(parameters, given_only=True)}


def source(input, options=None, progress: ProgressCallback = None) -> Source:
    """The :class:`~bitemesh.core.sources.source.Source` of ``input`` (what PointsToImplicit samples on the grid I):
    f fitted to the points, the contours' domain, or the label map's signed distance."""
    options = as_options(options)
    data = read_input(input, options)
    implicit = options.of(ImplicitParameters)
    if isinstance(data, Voxels):
        return label_grid_source(data.labels, data.ijk_to_physical, labels=labels_of(options), implicit=implicit)
    if data.labels is not None:
        keywords = contour_keywords(options)
        keywords.pop("allow_implausible", None)   # a check of the mesh, not of the fit
        return labelled_source(data.points, data.labels, slices=data.slices, progress=progress, **keywords)
    return points_source(data.points, data.normals, implicit, progress, slices=data.slices)


def labels_of(options: Options):
    return None if options.label is None else set(options.label)


def mesh(input, options=None, *, progress: ProgressCallback = None, **changes) -> MeshingResult:
    """Mesh ``input`` with ``options`` (an Options, a dict of option names, or None for the defaults) and
    ``changes`` (option names, e.g. ``cells=20000``, ``optimize=0``).

    Parameters
    ----------
    input : a file (points, labelled contours, a label map), an (n, k) array of points, Samples, Voxels, a
        LabelMap, or a VTK point set or image; with ``space_time=1``, a list of them: the frames of one cycle (the
        result's mesh is then the space-time mesh, one dimension more; :func:`instants` cuts out the frames)
    progress : callable(fraction, message), optional; it may raise bitemesh.Cancelled

    Returns
    -------
    MeshingResult: ``mesh`` (user coordinates, quality arrays, tagged facets; fibres with ``fibres=1``),
    ``radius`` R, ``fidelity``, ``notes`` (what was done to the data), ``seconds`` per step
    """
    options = as_options(options, **changes)
    with using_threads(options.threads):
        return _meshed(input, options, progress)


def _meshed(input, options: Options, progress: ProgressCallback) -> MeshingResult:
    if options.space_time:
        return _space_time(input, options, progress)
    if options.frame_step is not None:
        raise InvalidInputError(f"--frame-step {options.frame_step:g} applies to a space-time mesh of several frames; "
                                "add --space-time (space_time=1) with the frames, or leave it out")
    fibres = options.of(FibreParameters) if options.fibres else None
    meshed = sub_progress(progress, 0.0, 0.9 if fibres or options.coordinates else 1.0)
    data = read_input(input, options)
    if isinstance(data, Voxels):
        result = mesh_label_grid(data.labels, data.ijk_to_physical, labels=labels_of(options), progress=meshed,
                                 **options.steps)
    elif data.labels is not None:
        result = run_labelled(data.points, data.labels, slices=data.slices, progress=meshed, **options.steps,
                              **contour_keywords(options))
    else:
        result = run(data.points, data.normals, progress=meshed, slices=data.slices, **options.steps)
    if fibres is not None:
        report(progress, 0.9, "adding the fibres")
        try:
            with_them, seconds = with_fibres(result.mesh, fibres, sub_progress(progress, 0.9, 0.95))
        except InvalidInputError as error:
            raise InvalidInputError(f"fibres (--fibres): {error}") from None
        result = replace(result, mesh=with_them, seconds={**result.seconds, "fibres": seconds})
    if options.coordinates:
        report(progress, 0.95, "adding the ventricular coordinates")
        start = time.perf_counter()
        try:
            with_them = with_coordinates(result.mesh)
        except InvalidInputError as error:
            raise InvalidInputError(f"coordinates (--coordinates): {error}") from None
        result = replace(result, mesh=with_them,
                         seconds={**result.seconds, "coordinates": time.perf_counter() - start})
    if options.unit != result.mesh.unit:
        result = replace(result, mesh=replace(result.mesh, unit=options.unit))
    if fibres is not None or options.coordinates:
        warn_thin_walls(result.mesh, result.radius, "--fibres" if fibres is not None else "--coordinates",
                        two_cells_across(result.radius))
    return result


def _space_time(inputs, options: Options, progress: ProgressCallback) -> MeshingResult:
    """The frames of a cycle (a sequence of inputs) meshed as one space-time mesh (user coordinates, tau last)."""
    if isinstance(inputs, (str, os.PathLike, np.ndarray)) or not isinstance(inputs, (list, tuple)):
        raise InvalidInputError("space_time (--space-time): give the frames of the cycle as a list of inputs (e.g. "
                                "the files GPFile_000.txt ... GPFile_024.txt in the cycle's order), got one input")
    for name in ("fibres", "coordinates"):
        if getattr(options, name):
            raise InvalidInputError(f"{flag(name)} applies to a 3-D heart mesh, not to a space-time mesh; leave it "
                                    "out (each frame's instant is a 3-D mesh without tags)")
    one = options.replace(space_time=0)
    frames = []
    for number, item in enumerate(inputs):
        report(progress, 0.3 * number / len(inputs), f"fitting frame {number + 1} of {len(inputs)}")
        try:
            frames.append(source(item, one))
        except InvalidInputError as error:
            raise InvalidInputError(f"space_time: frame {number} ({item}): {error}") from None
    cells = options.cells or SPACE_TIME_CELLS
    radius = options.radius or space_time_radius(frames, cells, options.frame_step)
    shape = space_time_source(frames, radius, options.frame_step)
    steps = {**options.steps, "biting": replace(options.steps["biting"], radius=radius, cells=None)}
    result = mesh_source(shape, progress=sub_progress(progress, 0.3, 1.0), **steps)
    note = () if options.radius else (f"R = {radius:.3g} for about {cells:,} space-time cells",)
    return replace(result, notes=note + result.notes)


def instants(result: MeshingResult) -> list:
    """Each frame's instant of a space-time mesh (``space_time=1``): the k-D meshes cut at its frames' times."""
    shape = result.function
    return frame_instants(result.mesh, shape.step * result.frame.scale, len(shape.frames))


def check_output(path, options=None) -> None:
    """Refuse, before any work, an output path bitemesh cannot write, or one that would lose the fibres or the
    coordinates.  A path without an extension is the folder cardiac-geometries and fenicsx-pulse read."""
    options = None if options is None else as_options(options)
    suffix = Path(path).suffix.lower()
    if suffix not in MESH_EXTENSIONS + ("",):
        raise InvalidInputError(f"output {path} has an unsupported extension; use one of {', '.join(MESH_EXTENSIONS)}"
                                ", or none for a cardiac-geometries / fenicsx-pulse folder")
    directory = Path(path).parent
    if not directory.is_dir():
        raise InvalidInputError(f"output {path}: the directory '{directory}' does not exist")
    if not suffix and Path(path).exists() and not Path(path).is_dir():
        raise InvalidInputError(f"output {path} is a file, and an output without an extension is a folder (the "
                                "one cardiac-geometries and fenicsx-pulse read); give another name, or an "
                                "extension such as .vtu")
    kind = f"a {suffix} file" if suffix else "a cardiac-geometries folder"
    if options is not None and options.fibres and suffix in NO_CELL_ARRAYS + ("",):
        raise InvalidInputError(f"--fibres: {kind} keeps no cell arrays but the regions, so the fibres would be "
                                f"lost; write .vtu, .vtk or .xdmf, which keep {', '.join(FIBRE_ARRAYS)}")
    if options is not None:   # the dimension given, or that of the axes --columns names; time one more
        dimension = options.dimension or sum(role.strip() in AXES for role in options.columns.split(",")) or 3
        check_holds(dimension + bool(options.space_time), suffix,
                    f"output {path}: " + ("the space-time mesh of 3-D frames is 4-D: " if options.space_time else ""))
    if options is not None and options.coordinates and suffix not in POINT_ARRAY_FORMATS:
        raise InvalidInputError(f"--coordinates: {kind} keeps no point arrays, so the coordinates would be lost; "
                                f"write {', '.join(POINT_ARRAY_FORMATS)}")


def write(result, path) -> None:
    """Write a mesh (or a MeshingResult's mesh) to ``path`` with its tags, atomically (companions too)."""
    write_mesh(getattr(result, "mesh", result), path)


def compile_kernels() -> None:
    """Compile the numba kernels of a first run into numba's cache: the demo's die (from scattered points) and a
    small heart with its fibres meshed, nothing written, nothing said (the small heart's thin walls).  The wheel's
    build runs it (setup.py), the Slicer module once it has installed numba, a ParaView user once with pvpython."""
    import warnings
    from importlib import resources

    from .core.shapes import die_samples
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mesh(Samples(*die_samples()), cells=3000)
        with resources.as_file(resources.files("bitemesh") / "data" / "bivme_patient1" / "GPFile_000.txt") as path:
            mesh(path, cells=5000, fibres=1)
