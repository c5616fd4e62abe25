"""What the logic writes: the mesh into its model node (coloured by radius ratio, or by helix angle when it carries
the fibres), one model node per surface tag (its tagged boundary triangles, named by the tag, coloured apart), the
radius-ratio histogram into table and plot nodes, and the result it returns."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np
from vtkmodules.vtkCommonDataModel import vtkTable
from vtkmodules.vtkFiltersCore import vtkAssignAttribute


@dataclass
class BiteMeshResult:
    """What :meth:`BiteMeshLogic.process` produced.

    Attributes
    ----------
    mesh : bitemesh.Mesh in world (RAS) coordinates, with the quality arrays as cell data
    radius : R used (mm)
    summary : bitemesh.core.mesh.quality.QualitySummary
    tableNode, seriesNode, chartNode : the radius-ratio histogram and its bar plot
    seconds : step -> wall-clock seconds ("fibres" when the fibres were added)
    fidelity : bitemesh.core.steps.fidelity.Fidelity, how closely the boundary follows the input (mm), or None
    notes : what was done to the input on the way (points dropped as outliers, ...)
    surfaceNodes : the model nodes of the surface tags (:func:`writeSurfaces`), by tag
    """

    mesh: object
    radius: float
    summary: object
    tableNode: object
    seriesNode: object
    chartNode: object
    seconds: dict = field(default_factory=dict)
    fidelity: object = None
    notes: tuple = ()
    surfaceNodes: list = field(default_factory=list)


#: node references from the output model to its histogram nodes (reused by the next run).
TABLE_ROLE, SERIES_ROLE, CHART_ROLE = "BiteMeshQualityTable", "BiteMeshQualitySeries", "BiteMeshQualityChart"
#: node references from the output model to its surface models, one per facet tag (reused by the next run).
SURFACE_ROLE = "BiteMeshSurface"
#: the surface models' colours (RGB in [0, 1], Okabe and Ito's colour-blind safe set), by tag: tag t takes entry
#: (t - 1) modulo its length.
SURFACE_COLOURS = ((0.90, 0.62, 0.00), (0.34, 0.71, 0.91), (0.00, 0.62, 0.45), (0.94, 0.89, 0.26),
                   (0.00, 0.45, 0.70), (0.84, 0.37, 0.00), (0.80, 0.47, 0.65), (0.60, 0.60, 0.60))
#: colour tables for the radius ratio, the first one present in the scene is used.
COLOR_NODE_IDS = ("vtkMRMLColorTableNodeFileViridis.txt", "vtkMRMLColorTableNodeRainbow")
#: colour tables for the helix angle (diverging: negative, epicardial, blue; positive, endocardial, red), the first
#: one present in the scene is used.
FIBRE_COLOR_NODE_IDS = ("vtkMRMLColorTableNodeFileDivergingBlueRed.txt", "vtkMRMLColorTableNodeRainbow")
#: the model attribute prefix of the fibre rule's angles (degrees), set when the mesh carries the fibres.
FIBRE_ATTRIBUTE = "BiteMesh.Fibres"


def writeOutputs(mesh, radius, summary, fidelity, outputModelNode, bins):
    """The mesh into the model node (coloured by radius ratio; the quality summary and the fidelity as field
    data and attributes), the histogram into table and plot nodes."""
    from bitemesh.convert import add_field_values, field_array, mesh_to_unstructured
    from bitemesh.core.mesh.quality import quality_histogram

    grid = mesh_to_unstructured(mesh)
    for name, value in list(asdict(summary).items()) + [("Radius", radius)]:
        grid.GetFieldData().AddArray(field_array(name, [value]))
    figures = {} if fidelity is None else asdict(fidelity)
    add_field_values(grid, figures, "Fidelity")
    outputModelNode.SetAndObserveMesh(grid)
    outputModelNode.SetAttribute("BiteMesh.Radius", f"{radius:.6g}")
    outputModelNode.SetAttribute("BiteMesh.MeanRadiusRatio", f"{summary.q_mean:.6g}")
    for name, value in figures.items():
        outputModelNode.SetAttribute(f"BiteMesh.Fidelity.{name}", f"{value:.6g}")
    showCellScalar(outputModelNode, "RadiusRatio", (0.0, 1.0), COLOR_NODE_IDS)

    counts, edges = quality_histogram(mesh.cell_data["RadiusRatio"], bins)
    table = vtkTable()
    for name, values in (("BinStart", edges[:-1]), ("BinEnd", edges[1:]),
                         ("BinCentre", 0.5 * (edges[:-1] + edges[1:]))):
        table.AddColumn(field_array(name, values))
    table.AddColumn(field_array("Count", counts, integer=True))
    base = outputModelNode.GetName() or "BiteMesh"
    tableNode = referenced(outputModelNode, TABLE_ROLE, "vtkMRMLTableNode", f"{base} radius ratio histogram")
    tableNode.SetAndObserveTable(table)
    series = referenced(outputModelNode, SERIES_ROLE, "vtkMRMLPlotSeriesNode", f"{base} radius ratio")
    series.SetAndObserveTableNodeID(tableNode.GetID())
    series.SetXColumnName("BinCentre")
    series.SetYColumnName("Count")
    series.SetPlotType(series.PlotTypeBar)
    chart = referenced(outputModelNode, CHART_ROLE, "vtkMRMLPlotChartNode", f"{base} quality")
    if not chart.HasPlotSeriesNodeID(series.GetID()):
        chart.AddAndObservePlotSeriesNodeID(series.GetID())
    chart.SetTitle(f"Radius ratio of {summary.n_cells} tetrahedra (mean {summary.q_mean:.3f})")
    chart.SetXAxisTitle("radius ratio 3 r_in / R_circ (1 = regular)")
    chart.SetYAxisTitle("cells")
    chart.SetLegendVisibility(False)
    return tableNode, series, chart


def showCellScalar(modelNode, name: str, scalarRange, colorIds) -> None:
    """Colour the model by its cell array ``name`` over ``scalarRange`` (manual range) with the first colour table
    of ``colorIds`` that the scene has (the display node's active scalar, as Slicer's Models module sets it)."""
    display = modelNode.GetDisplayNode()
    if display is None:
        modelNode.CreateDefaultDisplayNodes()
        display = modelNode.GetDisplayNode()
    display.SetActiveScalar(name, vtkAssignAttribute.CELL_DATA)
    display.SetScalarVisibility(True)
    display.SetScalarRangeFlag(display.UseManualScalarRange)
    display.SetScalarRange(*scalarRange)
    display.SetVisibility2D(True)
    for colorId in colorIds:
        if modelNode.GetScene().GetNodeByID(colorId) is not None:
            display.SetAndObserveColorNodeID(colorId)
            break


def writeFibres(outputModelNode, parameters) -> None:
    """After :func:`writeOutputs`, for a mesh with the fibres (``parameters``: its FibreParameters): the model
    coloured by the cell scalar HelixAngle over +-(the larger of the rule's two helix angles) on a diverging colour
    table, Fibre the active cell vectors (for glyphs), and the rule's angles as the attributes
    ``BiteMesh.Fibres.alpha_endo`` etc. (degrees).  ``parameters`` None (no fibres) removes those attributes of a
    previous run."""
    from bitemesh.core.fem.fibres import FibreParameters
    angles = [item.name for item in fields(FibreParameters) if item.name != "fibres"]
    if parameters is None:
        for name in angles:
            outputModelNode.RemoveAttribute(f"{FIBRE_ATTRIBUTE}.{name}")
        return
    outputModelNode.GetMesh().GetCellData().SetActiveVectors("Fibre")
    widest = max(abs(parameters.alpha_endo), abs(parameters.alpha_epi)) or 90.0
    showCellScalar(outputModelNode, "HelixAngle", (-widest, widest), FIBRE_COLOR_NODE_IDS)
    for name in angles:
        outputModelNode.SetAttribute(f"{FIBRE_ATTRIBUTE}.{name}", f"{getattr(parameters, name):.6g}")


def referenced(owner, role: str, className: str, name: str):
    """The node ``owner`` references under ``role``, or a new one of ``className`` added to its scene."""
    node = owner.GetNodeReference(role)
    if node is None or not node.IsA(className) or node.GetScene() is None:
        node = owner.GetScene().AddNewNodeByClass(className, name)
        owner.SetNodeReferenceID(role, node.GetID())
    return node



def writeSurfaces(mesh, outputModelNode) -> list:
    """One model node per facet tag of ``mesh`` (in world coordinates, as the output model): the tag's triangles on
    the mesh's points (bitemesh.convert.tags_to_polydata, cell array ``SurfaceTag``), named "<output> <tag name>"
    (e.g. "mesh LV_ENDO"), coloured by :data:`SURFACE_COLOURS`, with the attributes ``BiteMesh.SurfaceTag`` and
    ``BiteMesh.SurfaceName``.  The nodes of the output's previous run are reused in order, those left over removed.

    Returns the model nodes, by increasing tag.
    """
    from bitemesh.convert import tags_to_polydata

    scene = outputModelNode.GetScene()
    base = outputModelNode.GetName() or "BiteMesh"
    named = {tag: name for name, (tag, dimension) in mesh.tag_names.items() if dimension == mesh.dim - 1}
    tags = [] if mesh.facet_tags is None else [int(tag) for tag in np.unique(mesh.facet_tags)]
    previous = [outputModelNode.GetNthNodeReference(SURFACE_ROLE, i)
                for i in range(outputModelNode.GetNumberOfNodeReferences(SURFACE_ROLE))]
    previous = [node for node in previous if node is not None and node.IsA("vtkMRMLModelNode")
                and node.GetScene() is scene]
    nodes = []
    for index, tag in enumerate(tags):
        name = named.get(tag, f"TAG_{tag}")
        node = previous[index] if index < len(previous) else scene.AddNewNodeByClass("vtkMRMLModelNode")
        node.SetName(f"{base} {name}")
        chosen = mesh.facet_tags == tag
        node.SetAndObservePolyData(tags_to_polydata(replace(mesh, facets=mesh.facets[chosen],
                                                            facet_tags=mesh.facet_tags[chosen],
                                                            tag_names={name: (tag, mesh.dim - 1)})))
        node.SetAttribute("BiteMesh.SurfaceTag", str(tag))
        node.SetAttribute("BiteMesh.SurfaceName", name)
        if node.GetDisplayNode() is None:
            node.CreateDefaultDisplayNodes()
        display = node.GetDisplayNode()
        display.SetScalarVisibility(False)
        display.SetColor(*SURFACE_COLOURS[(tag - 1) % len(SURFACE_COLOURS)])
        display.SetVisibility2D(True)
        nodes.append(node)
    for node in previous[len(tags):]:
        scene.RemoveNode(node)
    outputModelNode.RemoveNodeReferenceIDs(SURFACE_ROLE)
    for node in nodes:
        outputModelNode.AddNodeReferenceID(SURFACE_ROLE, node.GetID())
    return nodes
