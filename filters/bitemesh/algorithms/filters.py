"""The five steps of the method as VTK pipeline filters, plus the whole method in one filter.

Each filter is thin: convert its inputs to numpy, call the core, convert back.  Inputs are never modified.
"""
from __future__ import annotations

from dataclasses import asdict, replace

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import (vtkDataObject, vtkDataSet, vtkImageData, vtkPointSet, vtkPolyData,
                                           vtkTable, vtkUnstructuredGrid)
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm, vtkStreamingDemandDrivenPipeline

from ..core.biting import bite
from ..core.delaunay import delaunay
from ..core.domain import carve_domain
from ..core.errors import InvalidInputError, check_points
from ..core.fidelity import check_fidelity, measure_fidelity, on_plane
from ..core.grid import grid_shape
from ..core.implicit import grid_layout
from ..core.mesh import Mesh
from ..core.cell_measures import mean_edge_length
from ..core.optimize import optimize_mesh
from ..core.parameters import (BitingParameters, FidelityParameters, ImplicitParameters, LabelledParameters,
                               LabelMapParameters, OptimizeParameters, OptimizeSwitch, QualityParameters,
                               SpuriousParameters)
from ..core.pipeline import points_source, run, sample_source
from ..core.spine import radius_on_grid
from ..core.progress import sub_progress
from ..core.quality import cell_quality, quality_histogram, quality_summary
from ..labelmap import STAIRCASE_NOISE
from .base import BitemeshAlgorithm, with_parameters
from ..convert import (add_field_values, attach_samples, attached_samples, field_array, grid_to_image, image_to_grid,
                       mesh_to_unstructured, nodes_to_polydata, point_array, point_coordinates, point_labels,
                       unstructured_to_mesh)


def scattered_points(dataset):
    """(points, normals or None) of a vtkPointSet: the ``Normals`` point array, or the point normals attribute.

    Points with z = 0 everywhere are 2D (a contour in the xy plane): both come back with two columns.
    """
    if not isinstance(dataset, vtkPointSet) or dataset.GetNumberOfPoints() == 0:
        raise InvalidInputError("the input holds no points; connect scattered points (vtkPolyData) or a label map")
    normals = dataset.GetPointData().GetNormals()
    normals = point_array(dataset, "Normals") if normals is None else numpy_support.vtk_to_numpy(normals).copy()
    points = planar_as_2d(point_coordinates(dataset))
    if normals is not None and normals.ndim == 2 and normals.shape[1] > points.shape[1]:
        normals = normals[:, :points.shape[1]]
    return points, normals


def labelled_contours(dataset):
    """(points (n, 3), labels (n,), slice ids (n,) or None) of a point set with a ``Label`` point array, else
    None."""
    if not isinstance(dataset, vtkPointSet) or dataset.GetNumberOfPoints() == 0:
        return None
    labels, slices = point_labels(dataset)
    return None if labels is None else (point_coordinates(dataset), labels, slices)


def labelled_options(parameters: LabelledParameters) -> dict:
    """Keywords of :func:`~bitemesh.core.labelled.labelled_implicit` from LabelledParameters."""
    return {"domain": (parameters.domain or "").strip() or None, "base_plane": parameters.base_plane,
            "rv_wall": parameters.rv_wall}


@with_parameters(ImplicitParameters, LabelMapParameters, LabelledParameters)
class PointsToImplicit(BitemeshAlgorithm):
    """Scattered points (with optional ``Normals``), labelled contours or a label map -> f on the grid I
    (vtkImageData ``Implicit``).

    f > 0 inside, about the signed distance near the surface.  Points use MPU (or RBF).  Points with a ``Label``
    point array (and optionally ``Slice``) are contours of several surfaces: one implicit per surface, combined by
    ``Domain`` (a CSG expression) and cut by the base plane.  A vtkImageData input is a label map, turned into a
    signed distance by SimpleITK (``Label`` chooses the domain's label).
    """

    def __init__(self):
        super().__init__(nInputPorts=1, inputType="vtkDataSet", nOutputPorts=1, outputType="vtkImageData")
        self._fitted = None  # ((input MTime, fit options), (function, lower, upper)) of the last labelled fit

    def labelled_fit(self, source):
        """(LabelledImplicit, lower, upper) of labelled contour input, fitted once per input, domain and base plane;
        None for other input.  RequestInformation needs the domain's box, RequestData the function: one fit serves
        both, and changes of the grid or of the thinnest wall only sample it again."""
        from ..core.labelled import labelled_implicit
        contours = labelled_contours(source)
        if contours is None:
            return None
        options = labelled_options(self.parameters(LabelledParameters))
        key = (source.GetMTime(), tuple(options.items()))
        if self._fitted is None or self._fitted[0] != key:
            points, labels, slices = contours
            self._fitted = (key, labelled_implicit(points, labels, slices=slices, min_wall=0.0,
                                                   progress=self.progress, **options))
        return self._fitted[1]

    def RequestInformation(self, request, inInfo, outInfo):
        # The grid's extent depends on the input's bounds: bring the input up to date before announcing it.
        self.GetInputAlgorithm(0, 0).Update(self.GetInputConnection(0, 0).GetIndex())
        source = vtkDataSet.GetData(inInfo[0])
        try:
            origin, spacing, shape = self.grid_geometry(source)
        except Exception:  # noqa: BLE001 - bad input: RequestData reports it with its message
            return 1
        info = outInfo.GetInformationObject(0)
        dims = list(shape) + [1] * (3 - len(shape))
        info.Set(vtkStreamingDemandDrivenPipeline.WHOLE_EXTENT(), [0, dims[0] - 1, 0, dims[1] - 1, 0, dims[2] - 1], 6)
        info.Set(vtkDataObject.ORIGIN(), list(origin) + [0.0] * (3 - len(origin)), 3)
        info.Set(vtkDataObject.SPACING(), list(spacing) + [1.0] * (3 - len(spacing)), 3)
        return 1

    def grid_geometry(self, source):
        """(origin, spacing, shape) of the grid this input will give."""
        if isinstance(source, vtkImageData):
            return self.label_grid_geometry(source)
        parameters = self.parameters(ImplicitParameters)
        fit = self.labelled_fit(source)
        points = check_points(scattered_points(source)[0]) if fit is None else np.array(fit[1:])
        lower, upper, spacing, margin = grid_layout(points, parameters.grid_spacing, parameters.margin)
        shape = grid_shape(lower - margin, upper + margin, spacing, max_memory_mb=parameters.max_memory_mb)
        return lower - margin, np.full(len(lower), spacing), shape

    def label_grid_geometry(self, image: vtkImageData):
        """(origin, spacing, shape) of the grid a label map gives: its voxels, padded."""
        from ..labelmap import PAD_VOXELS
        dims = image.GetDimensions()
        dim = 2 if dims[2] == 1 else 3
        origin, spacing = np.array(image.GetOrigin()[:dim]), np.array(image.GetSpacing()[:dim])
        return origin - PAD_VOXELS * spacing, spacing, tuple(n + 2 * PAD_VOXELS for n in dims[:dim])

    def label_grid(self, image: vtkImageData):
        """The label map's signed distance on its grid and its voxel faces (the samples)."""
        from ..labelmap import label_map_to_grid, label_mask, mask_faces
        dims = image.GetDimensions()
        dim = 2 if dims[2] == 1 else 3
        origin, spacing = np.array(image.GetOrigin()[:dim]), np.array(image.GetSpacing()[:dim])
        scalars = image.GetPointData().GetScalars()
        if scalars is None:
            raise InvalidInputError("the label map has no point scalars (the labels)")
        labels = numpy_support.vtk_to_numpy(scalars).reshape(dims, order="F").reshape(dims[:dim])
        label = self.parameters(LabelMapParameters).label
        return label_map_to_grid(labels, origin, spacing, label), mask_faces(label_mask(labels, label)[0], origin,
                                                                              spacing)

    def execute(self, request, inInfo, outInfo):
        source = vtkDataSet.GetData(inInfo[0])
        fit = None if isinstance(source, vtkImageData) else self.labelled_fit(source)
        output = vtkImageData.GetData(outInfo)
        if isinstance(source, vtkImageData):
            grid, samples = self.label_grid(source)
            grid_to_image(grid, output)
            attach_samples(output, samples, STAIRCASE_NOISE * float(np.max(grid.spacing)),
                           float(np.linalg.norm(grid.spacing)))
        elif fit is not None:
            from ..core.labelled import is_myocardium, sample_labelled
            function = fit[0]
            grid_to_image(sample_labelled(*fit, self.parameters(ImplicitParameters),
                                          self.parameters(LabelledParameters).min_wall, progress=self.progress), output)
            attach_samples(output, function.surface_samples(), function.tracing_noise(), function.contour_gap(),
                           function.base)
            if is_myocardium(function):   # SpuriousCellFilter's Handles "auto" then removes handles
                output.GetFieldData().AddArray(field_array("Myocardium", [1.0]))
        else:
            parameters = self.parameters(ImplicitParameters)
            points, normals = scattered_points(source)
            fitted = points_source(points, normals, parameters, sub_progress(self.progress, 0.0, 0.4))
            frame = fitted.frame
            grid_to_image(sample_source(fitted, parameters, sub_progress(self.progress, 0.4, 1.0)), output)
            attach_samples(output, frame.to_user(fitted.samples), fitted.noise * frame.scale,
                           fitted.gap * frame.scale)


@with_parameters(BitingParameters)
class BitingSampler(BitemeshAlgorithm):
    """f on the grid I -> mesh nodes about R apart (vtkPolyData with a vertex per node), the paper's Algorithm 1.

    R is ``Radius``, or chosen for about ``Cells`` cells; the field data ``Radius`` holds the R used.
    """

    def __init__(self):
        super().__init__(nInputPorts=1, inputType="vtkImageData", nOutputPorts=1, outputType="vtkPolyData")

    def execute(self, request, inInfo, outInfo):
        parameters = self.parameters(BitingParameters)
        grid = image_to_grid(vtkImageData.GetData(inInfo[0]))
        radius = parameters.radius or radius_on_grid(grid, parameters.cells)
        nodes = bite(grid, radius, order=parameters.order, seed=parameters.seed, progress=self.progress)
        output = vtkPolyData.GetData(outInfo)
        output.ShallowCopy(nodes_to_polydata(nodes))
        output.GetFieldData().AddArray(field_array("Radius", [radius]))


class DelaunayTetra(BitemeshAlgorithm):
    """Nodes -> their Delaunay tetrahedra (triangles in 2D) by qhull, all positively oriented."""

    def __init__(self):
        super().__init__(nInputPorts=1, inputType="vtkPointSet", nOutputPorts=1, outputType="vtkUnstructuredGrid")

    def execute(self, request, inInfo, outInfo):
        source = vtkPointSet.GetData(inInfo[0])
        nodes = node_coordinates(source)
        output = vtkUnstructuredGrid.GetData(outInfo)
        mesh_to_unstructured(Mesh(nodes, delaunay(nodes)), output)
        output.GetFieldData().PassData(source.GetFieldData())   # the Radius the BitingSampler used


class MeshWithImplicitFilter(BitemeshAlgorithm):
    """Base of the steps that take a mesh (port 0) and f on the grid (port 1) and give a mesh."""

    def __init__(self):
        super().__init__(nInputPorts=2, inputType="vtkDataObject", nOutputPorts=1, outputType="vtkUnstructuredGrid")

    def FillInputPortInformation(self, port, info):
        info.Set(vtkAlgorithm.INPUT_REQUIRED_DATA_TYPE(), "vtkUnstructuredGrid" if port == 0 else "vtkImageData")
        return 1

    def mesh_and_grid(self, inInfo):
        """The input mesh (without its cell data) and the implicit grid, of the same dimension."""
        mesh = unstructured_to_mesh(vtkUnstructuredGrid.GetData(inInfo[0]))
        grid = image_to_grid(vtkImageData.GetData(inInfo[1]))
        if grid.dim != mesh.dim:
            raise InvalidInputError(f"the mesh is {mesh.dim}D but the implicit image is {grid.dim}D")
        return Mesh(mesh.points, mesh.cells), grid


@with_parameters(SpuriousParameters, FidelityParameters)
class SpuriousCellFilter(MeshWithImplicitFilter):
    """All Delaunay cells (port 0) and f on the grid (port 1) -> the valid domain, unused points dropped.

    A cell goes when f < 0 at its circumcentre and |f|/|grad f| there exceeds ``Threshold`` x its circumradius
    (the paper's test, on the cells lying on the surface), or when its centroid is outside; then voids inside are
    filled, flat boundary cells peeled, pinched edges and vertices repaired and parts below ``MinComponent``
    dropped.  When the image carries the data's samples (PointsToImplicit puts them there), the domain's boundary
    is compared with them (field data ``Fidelity*``) and refused beyond ``FarSamples`` / ``UnsupportedArea``
    unless ``AllowUnfaithful``.
    """

    def execute(self, request, inInfo, outInfo):
        mesh, grid = self.mesh_and_grid(inInfo)
        delaunay_mesh = vtkUnstructuredGrid.GetData(inInfo[0])
        parameters = self.parameters(SpuriousParameters)
        if parameters.handles == "auto" and vtkImageData.GetData(inInfo[1]).GetFieldData().GetArray("Myocardium"):
            parameters = replace(parameters, handles="remove")   # a myocardium is a ball, its cavities open
        domain = carve_domain(grid, mesh.points, mesh.cells, parameters, self.progress)
        output = vtkUnstructuredGrid.GetData(outInfo)
        mesh_to_unstructured(domain, output)
        output.GetFieldData().PassData(delaunay_mesh.GetFieldData())
        attached = attached_samples(vtkImageData.GetData(inInfo[1]), domain.dim)
        if attached is not None:
            samples, noise, gap, base = attached
            radius = output.GetFieldData().GetArray("Radius")
            radius = radius.GetValue(0) if radius is not None else mean_edge_length(domain.points, domain.cells)
            fidelity = measure_fidelity(domain, samples, radius, noise, gap,
                                        None if base is None else on_plane(*base, 0.1 * radius))
            check_fidelity(fidelity, self.parameters(FidelityParameters))
            add_field_values(output, asdict(fidelity), "Fidelity")


@with_parameters(QualityParameters)
class QualityFilter(BitemeshAlgorithm):
    """Mesh -> the same mesh with cell arrays RadiusRatio, MinDihedralAngle, MaxDihedralAngle, Volume and a
    field-data summary (port 0), and the radius-ratio histogram as a vtkTable (port 1)."""

    def __init__(self):
        super().__init__(nInputPorts=1, inputType="vtkUnstructuredGrid", nOutputPorts=2,
                         outputType="vtkUnstructuredGrid")

    def FillOutputPortInformation(self, port, info):
        info.Set(vtkDataObject.DATA_TYPE_NAME(), "vtkUnstructuredGrid" if port == 0 else "vtkTable")
        return 1

    def execute(self, request, inInfo, outInfo):
        source = vtkUnstructuredGrid.GetData(inInfo[0])
        mesh = unstructured_to_mesh(source)
        output = vtkUnstructuredGrid.GetData(outInfo, 0)
        output.ShallowCopy(mesh_to_unstructured(mesh.with_cell_data(**cell_quality(mesh))))
        summary = quality_summary(mesh)
        for name, value in asdict(summary).items():
            output.GetFieldData().AddArray(field_array(name, [value]))
        counts, edges = quality_histogram(output_array(output, "RadiusRatio"), self.parameters(QualityParameters).bins)
        table = vtkTable.GetData(outInfo, 1)
        table.Initialize()
        table.AddColumn(field_array("BinStart", edges[:-1]))
        table.AddColumn(field_array("BinEnd", edges[1:]))
        table.AddColumn(field_array("Count", counts, integer=True))


@with_parameters(OptimizeParameters)
class MeshOptimizer(MeshWithImplicitFilter):
    """A valid mesh (port 0) and f on the grid (port 1) -> the mesh relaxed, without slivers, boundary on f = 0."""

    def execute(self, request, inInfo, outInfo):
        mesh, grid = self.mesh_and_grid(inInfo)
        optimized = optimize_mesh(grid, mesh, self.parameters(OptimizeParameters), self.progress)
        mesh_to_unstructured(optimized, vtkUnstructuredGrid.GetData(outInfo))


@with_parameters(ImplicitParameters, BitingParameters, SpuriousParameters, OptimizeSwitch, OptimizeParameters,
                 LabelledParameters, FidelityParameters)
class MeshFromPoints(BitemeshAlgorithm):
    """The whole method in one filter: scattered points -> a valid mesh with its quality arrays.

    As ``bitemesh.run``: R is ``Radius`` or chosen for about ``Cells`` cells, the grid spacing R / 4 by default;
    ``SetOptimize(1)`` also runs the MeshOptimizer.  Points with a ``Label`` point array are labelled contours,
    meshed as ``bitemesh.core.labelled.run_labelled`` does (``Domain``, ``BasePlane``, ``MinWall``).
    """

    def __init__(self):
        super().__init__(nInputPorts=1, inputType="vtkPointSet", nOutputPorts=1, outputType="vtkUnstructuredGrid")

    def execute(self, request, inInfo, outInfo):
        source = vtkPointSet.GetData(inInfo[0])
        optimize = self.parameters(OptimizeParameters) if self.parameters(OptimizeSwitch).optimize else None
        steps = {"implicit": self.parameters(ImplicitParameters), "biting": self.parameters(BitingParameters),
                 "spurious": self.parameters(SpuriousParameters), "optimize": optimize, "progress": self.progress,
                 "fidelity": self.parameters(FidelityParameters)}
        contours = labelled_contours(source)
        if contours is None:
            result = run(*scattered_points(source), **steps)
        else:
            from ..core.labelled import run_labelled
            labelled = self.parameters(LabelledParameters)
            points, labels, slices = contours
            result = run_labelled(points, labels, slices=slices, min_wall=labelled.min_wall,
                                  allow_implausible=bool(labelled.allow_implausible), **labelled_options(labelled),
                                  **steps)
        output = vtkUnstructuredGrid.GetData(outInfo)
        mesh_to_unstructured(result.mesh, output)
        output.GetFieldData().AddArray(field_array("Radius", [result.radius]))
        if result.fidelity is not None:
            add_field_values(output, asdict(result.fidelity), "Fidelity")


def planar_as_2d(points: np.ndarray) -> np.ndarray:
    """(n, 2) when every z is 0 (a 2D point set, as VTK stores it), else the (n, 3) points unchanged."""
    return points[:, :2] if len(points) and np.all(points[:, 2] == 0) else points


def node_coordinates(dataset) -> np.ndarray:
    """(n, k) node coordinates of a vtkPointSet; nodes with z = 0 everywhere are 2D."""
    points = point_coordinates(dataset)
    if len(points) == 0:
        raise InvalidInputError("the input holds no nodes; connect a BitingSampler")
    return planar_as_2d(points)


def output_array(dataset, name: str) -> np.ndarray:
    return numpy_support.vtk_to_numpy(dataset.GetCellData().GetArray(name))
