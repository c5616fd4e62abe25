"""The five steps of the method as VTK pipeline filters, plus the whole method in one filter.

Each filter is thin: convert its inputs to numpy, call the core, convert back.  Inputs are never modified.
"""
from __future__ import annotations

from dataclasses import asdict, fields, replace

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import (vtkDataObject, vtkDataSet, vtkImageData, vtkPointSet, vtkPolyData,
                                           vtkTable, vtkUnstructuredGrid)
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm, vtkStreamingDemandDrivenPipeline

from ..core.steps.biting import bite
from ..core.steps.delaunay import delaunay
from ..core.steps.repair import carve_domain
from ..core.errors import InvalidInputError
from ..core.mesh.betti import check_topology
from ..core.steps.fidelity import measure_fidelity
from ..core.steps.verdict import check_fidelity
from ..core.mesh.simplicial import Mesh
from ..core.optimize.measures import mean_edge_length
from ..core.optimize.optimizer import optimize_mesh
from ..core.parameters import (BitingParameters, FidelityParameters, ImplicitParameters, LabelledParameters,
                               LabelMapParameters, OptimizeParameters, QualityParameters,
                               SpuriousParameters)
from ..core.steps.spine import radius_on_grid
from ..core.progress import sub_progress
from ..core.mesh.quality import cell_quality, quality_histogram, quality_summary
from .base import BitemeshAlgorithm, with_parameters
from ..meshing import mesh as mesh_input, source as input_source
from ..convert import (add_field_values, attach_plan, attach_samples, attach_surfaces, attached_samples,
                       attached_surfaces, field_array, grid_to_image, image_to_grid, mesh_to_unstructured,
                       nodes_to_polydata, plan_of, planar_as_2d, point_coordinates, tags_to_polydata,
                       unstructured_to_mesh)


#: the parameters of BitingParameters that lay out the grid I (R); the others are the BitingSampler's alone.
GRID_BITING = (BitingParameters, ("radius", "cells"))
#: PointsToImplicit's labelled-contour fields: all but the heart's plausibility check, which MeshFromPoints runs.
FIT_LABELLED = (LabelledParameters, tuple(item.name for item in fields(LabelledParameters)
                                          if item.name != "allow_implausible"))
#: the MeshOptimizer filter's fields: OptimizeParameters but its switch (the filter always runs).
OPTIMIZER_BOUNDS = tuple(item.name for item in fields(OptimizeParameters) if item.name != "optimize")


@with_parameters(ImplicitParameters, GRID_BITING, LabelMapParameters, FIT_LABELLED)
class PointsToImplicit(BitemeshAlgorithm):
    """Scattered points (with optional ``Normals``), labelled contours or a label map -> f on the grid I
    (vtkImageData ``Implicit``).

    f > 0 inside, about the signed distance near the surface.  Points use MPU (or RBF).  Points with a ``Label``
    point array (and optionally ``Slice``) are contours of several surfaces: one implicit per surface, combined by
    ``Domain`` (a CSG expression) and cut by the base plane.  A vtkImageData input is a label map, turned into a
    signed distance by SimpleITK (``Label`` chooses the domain's label).  The grid I is laid out as MeshFromPoints
    lays it out (:func:`bitemesh.core.steps.spine.grid_for_source`): for R (``Radius``, or chosen for ``Cells``),
    spacing ``GridSpacing`` or R / 4; the plan (field data ``BitemeshPlan``, :func:`bitemesh.convert.plan_of`)
    holds R, which BitingSampler takes, whether the domain is a myocardium, and the samples' noise and gap.
    """

    def __init__(self):
        super().__init__(nInputPorts=1, inputType="vtkDataSet", nOutputPorts=1, outputType="vtkImageData")
        self._source = None  # ((input MTime, source options), Source) of the last fit
        self._grid = None    # ((source key, grid options), (grid I in user coordinates, R)) of the last sampling

    def source_of(self, data):
        """The :class:`~bitemesh.core.sources.source.Source` of the input (:func:`bitemesh.meshing.source`), fitted
        once per input and fit options."""
        options = self.options()
        fit = replace(options, radius=None, cells=None, grid_spacing=None, margin=None, min_wall=None)
        key = (data.GetMTime(), fit)
        if self._source is None or self._source[0] != key:
            self._source = (key, input_source(data, fit, sub_progress(self.progress, 0.0, 0.4)))
        found = self._source[1]
        if options.min_wall is not None and hasattr(found.function, "with_min_wall"):
            # a given thinnest wall instead of one that follows R: no new fit
            found = replace(found, function=found.function.with_min_wall(options.min_wall), at_radius=None)
        return found

    def grid_of(self, data):
        """(f on the grid I in user coordinates, R in user units, the Source, the f meshed (local frame)), sampled
        once per source and grid options."""
        from ..core.steps.spine import grid_for_source
        source = self.source_of(data)
        implicit, biting = self.parameters(ImplicitParameters), self.parameters(BitingParameters)
        key = (id(self._source[1]), self.parameters(LabelledParameters).min_wall, implicit, biting.radius,
               biting.cells)
        if self._grid is None or self._grid[0] != key:
            grid, radius, function, _ = grid_for_source(source, implicit, biting,
                                                        sub_progress(self.progress, 0.4, 1.0))
            self._grid = (key, (source.frame.grid_to_user(grid), radius * source.frame.scale, source, function))
        return self._grid[1]

    def RequestInformation(self, request, inInfo, outInfo):
        # The grid's extent depends on the input: bring the input up to date and lay the grid out before announcing
        # it (the sampled grid is kept for RequestData).
        self.GetInputAlgorithm(0, 0).Update(self.GetInputConnection(0, 0).GetIndex())
        try:
            grid = self.grid_of(vtkDataSet.GetData(inInfo[0]))[0]
        except Exception:  # noqa: BLE001 - bad input: RequestData reports it with its message
            return 1
        info = outInfo.GetInformationObject(0)
        dims = list(grid.shape) + [1] * (3 - grid.dim)
        info.Set(vtkStreamingDemandDrivenPipeline.WHOLE_EXTENT(), [0, dims[0] - 1, 0, dims[1] - 1, 0, dims[2] - 1], 6)
        info.Set(vtkDataObject.ORIGIN(), list(grid.origin) + [0.0] * (3 - grid.dim), 3)
        info.Set(vtkDataObject.SPACING(), list(grid.spacing) + [1.0] * (3 - grid.dim), 3)
        return 1

    def execute(self, request, inInfo, outInfo):
        grid, radius, source, function = self.grid_of(vtkDataSet.GetData(inInfo[0]))
        output = vtkImageData.GetData(outInfo)
        grid_to_image(grid, output)
        attach_surfaces(output, source.surfaces_on(grid, function))
        # the plan: R, for a myocardium SpuriousCellFilter's Handles "auto" removes handles, and for one fit of
        # scattered points it refuses a fold of f that the mesh does not show
        attach_plan(output, Radius=radius, Myocardium=float(source.handles == "remove"), OneFit=float(source.one_fit))
        frame = source.frame
        attach_samples(output, frame.to_user(source.samples), source.noise * frame.scale, source.gap * frame.scale,
                       source.unsampled_on(grid))


@with_parameters(BitingParameters)
class BitingSampler(BitemeshAlgorithm):
    """f on the grid I -> mesh nodes about R apart (vtkPolyData with a vertex per node), the paper's Algorithm 1.

    R is ``Radius``, else the R that PointsToImplicit laid the grid out for (in its plan, field data
    ``BitemeshPlan``) unless ``Cells`` is set here, else chosen for about ``Cells`` cells; the output carries the
    plan on with the R used.
    """

    def __init__(self):
        super().__init__(nInputPorts=1, inputType="vtkImageData", nOutputPorts=1, outputType="vtkPolyData")

    def execute(self, request, inInfo, outInfo):
        parameters = self.parameters(BitingParameters)
        image = vtkImageData.GetData(inInfo[0])
        grid = image_to_grid(image)
        plan = plan_of(image)   # with the R PointsToImplicit laid the grid out for
        if parameters.radius is not None:
            radius = parameters.radius
        elif "Radius" in plan and parameters.cells is None:
            radius = plan["Radius"]
        else:
            radius = radius_on_grid(grid, parameters.aimed_cells)
        spacing = float(np.max(grid.spacing))
        if spacing > radius / 2:   # a grid laid out for a larger R cannot resolve this one
            named = ("Radius" if parameters.radius is not None
                     else f"Radius (chosen for Cells = {parameters.aimed_cells})")
            raise InvalidInputError(
                f"BitingSampler: {named} = {radius:.4g} is too small for the grid I (spacing {spacing:.4g}): the "
                f"grid must resolve R, R >= 2 x spacing = {2 * spacing:.4g}; set Radius or Cells on "
                "PointsToImplicit instead, which lays the grid out for them")
        nodes = bite(grid, radius, order=parameters.order, seed=parameters.seed, progress=self.progress)
        output = vtkPolyData.GetData(outInfo)
        output.ShallowCopy(nodes_to_polydata(nodes))
        attach_plan(output, **{**plan, "Radius": radius})   # the plan goes on, with the R used


class DelaunayTetra(BitemeshAlgorithm):
    """Nodes -> their Delaunay tetrahedra (triangles in 2D) by qhull, all positively oriented."""

    def __init__(self):
        super().__init__(nInputPorts=1, inputType="vtkPointSet", nOutputPorts=1, outputType="vtkUnstructuredGrid")

    def execute(self, request, inInfo, outInfo):
        source = vtkPointSet.GetData(inInfo[0])
        nodes = node_coordinates(source)
        output = vtkUnstructuredGrid.GetData(outInfo)
        mesh_to_unstructured(Mesh(nodes, delaunay(nodes)), output)
        output.GetFieldData().PassData(source.GetFieldData())   # the plan, with the R the BitingSampler used


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
    unless ``AllowUnfaithful``; so is a domain with parts, handles or voids that f > 0 on the grid I lacks.
    """

    def execute(self, request, inInfo, outInfo):
        mesh, grid = self.mesh_and_grid(inInfo)
        delaunay_mesh = vtkUnstructuredGrid.GetData(inInfo[0])
        parameters = self.parameters(SpuriousParameters)
        if parameters.handles == "auto" and plan_of(vtkImageData.GetData(inInfo[1])).get("Myocardium"):
            parameters = replace(parameters, handles="remove")   # a myocardium is a ball, its cavities open
        domain = carve_domain(grid, mesh.points, mesh.cells, parameters, self.progress,
                              surface_of=attached_surfaces(vtkImageData.GetData(inInfo[1])))
        output = vtkUnstructuredGrid.GetData(outInfo)
        mesh_to_unstructured(domain, output)
        output.GetFieldData().PassData(delaunay_mesh.GetFieldData())
        radius = plan_of(output).get("Radius") or mean_edge_length(domain.points, domain.cells)
        bounds = self.parameters(FidelityParameters)
        attached = attached_samples(vtkImageData.GetData(inInfo[1]), domain.dim)
        if attached is not None:
            samples, noise, gap, unsampled = attached
            fidelity = measure_fidelity(domain, samples, radius, noise, gap,
                                        None if unsampled is None else lambda x: unsampled.evaluate(x) > 0.5)
            check_fidelity(fidelity, bounds)
            add_field_values(output, asdict(fidelity), "Fidelity")
        check_topology(domain, grid.inside(), radius, bool(bounds.allow_unfaithful), around=grid.inside_offsets,
                       one_fit=bool(plan_of(vtkImageData.GetData(inInfo[1])).get("OneFit")), grid=grid)


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


@with_parameters((OptimizeParameters, OPTIMIZER_BOUNDS))
class MeshOptimizer(MeshWithImplicitFilter):
    """A valid mesh (port 0) and f on the grid (port 1) -> the mesh relaxed, without slivers, boundary on f = 0."""

    def execute(self, request, inInfo, outInfo):
        mesh, grid = self.mesh_and_grid(inInfo)
        optimized = optimize_mesh(grid, mesh, self.parameters(OptimizeParameters), self.progress)
        mesh_to_unstructured(optimized, vtkUnstructuredGrid.GetData(outInfo))


@with_parameters(ImplicitParameters, BitingParameters, SpuriousParameters, OptimizeParameters,
                 LabelledParameters, FidelityParameters)
class MeshFromPoints(BitemeshAlgorithm):
    """The whole method in one filter: scattered points -> a valid mesh with its quality arrays and its tags.

    As :func:`bitemesh.mesh`: R is ``Radius`` or chosen for about ``Cells`` cells, the grid spacing R / 4 by
    default; the MeshOptimizer runs unless ``SetOptimize(0)``.  Points with a ``Label`` point array are labelled
    contours, meshed as the domain their surfaces bound (``Domain``, ``BasePlane``, ``MinWall``).

    Port 0: the mesh (vtkUnstructuredGrid), with the cell array ``Region``.  Port 1: its tagged boundary
    (vtkPolyData sharing every point of the mesh, point id = node id; triangles, lines in 2D; cell array
    ``SurfaceTag``; field data ``TagNames``, ``TagValues``, ``TagDimensions``: see
    :func:`bitemesh.convert.tags_to_polydata`): contours by surface (EPI, LV_ENDO, RV_ENDO, BASE), scattered points
    one tag per boundary piece (BOUNDARY_1, ... by decreasing area).
    """

    def __init__(self):
        super().__init__(nInputPorts=1, inputType="vtkPointSet", nOutputPorts=2, outputType="vtkUnstructuredGrid")

    def FillOutputPortInformation(self, port, info):
        info.Set(vtkDataObject.DATA_TYPE_NAME(), "vtkUnstructuredGrid" if port == 0 else "vtkPolyData")
        return 1

    def execute(self, request, inInfo, outInfo):
        result = mesh_input(vtkPointSet.GetData(inInfo[0]), self.options(), progress=self.progress)
        output = vtkUnstructuredGrid.GetData(outInfo, 0)
        mesh_to_unstructured(result.mesh, output)
        attach_plan(output, Radius=result.radius)
        if result.fidelity is not None:
            add_field_values(output, asdict(result.fidelity), "Fidelity")
        tags_to_polydata(result.mesh, vtkPolyData.GetData(outInfo, 1))


def node_coordinates(dataset) -> np.ndarray:
    """(n, k) node coordinates of a vtkPointSet; nodes with z = 0 everywhere are 2D."""
    points = point_coordinates(dataset)
    if len(points) == 0:
        raise InvalidInputError("the input holds no nodes; connect a BitingSampler")
    return planar_as_2d(points)


def output_array(dataset, name: str) -> np.ndarray:
    return numpy_support.vtk_to_numpy(dataset.GetCellData().GetArray(name))
