"""What the logic writes: the mesh into its model node (coloured by radius ratio), the radius-ratio histogram
into table and plot nodes, and the result it returns."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

from vtkmodules.vtkCommonDataModel import vtkTable
from vtkmodules.vtkFiltersCore import vtkAssignAttribute


@dataclass
class BiteMeshResult:
    """What :meth:`BiteMeshLogic.process` produced.

    Attributes
    ----------
    mesh : bitemesh.Mesh in world (RAS) coordinates, with the quality arrays as cell data
    radius : R used (mm)
    summary : bitemesh.core.quality.QualitySummary
    tableNode, seriesNode, chartNode : the radius-ratio histogram and its bar plot
    seconds : step -> wall-clock seconds
    fidelity : bitemesh.core.fidelity.Fidelity, how closely the boundary follows the input (mm), or None
    notes : what was done to the input on the way (points dropped as outliers, ...)
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


#: node references from the output model to its histogram nodes (reused by the next run).
TABLE_ROLE, SERIES_ROLE, CHART_ROLE = "BiteMeshQualityTable", "BiteMeshQualitySeries", "BiteMeshQualityChart"
#: colour tables for the radius ratio, the first one present in the scene is used.
COLOR_NODE_IDS = ("vtkMRMLColorTableNodeFileViridis.txt", "vtkMRMLColorTableNodeRainbow")


def writeOutputs(mesh, radius, summary, fidelity, outputModelNode, bins):
    """The mesh into the model node (coloured by radius ratio; the quality summary and the fidelity as field
    data and attributes), the histogram into table and plot nodes."""
    from bitemesh.convert import add_field_values, field_array, mesh_to_unstructured
    from bitemesh.core.quality import quality_histogram

    grid = mesh_to_unstructured(mesh)
    for name, value in list(asdict(summary).items()) + [("Radius", radius)]:
        grid.GetFieldData().AddArray(field_array(name, [value]))
    figures = {} if fidelity is None else asdict(fidelity)
    add_field_values(grid, figures, "Fidelity")
    scene = outputModelNode.GetScene()
    outputModelNode.SetAndObserveMesh(grid)
    outputModelNode.SetAttribute("BiteMesh.Radius", f"{radius:.6g}")
    outputModelNode.SetAttribute("BiteMesh.MeanRadiusRatio", f"{summary.q_mean:.6g}")
    for name, value in figures.items():
        outputModelNode.SetAttribute(f"BiteMesh.Fidelity.{name}", f"{value:.6g}")
    display = outputModelNode.GetDisplayNode()
    if display is None:
        outputModelNode.CreateDefaultDisplayNodes()
        display = outputModelNode.GetDisplayNode()
    if display is not None:
        display.SetActiveScalar("RadiusRatio", vtkAssignAttribute.CELL_DATA)
        display.SetScalarVisibility(True)
        display.SetScalarRangeFlag(display.UseManualScalarRange)
        display.SetScalarRange(0.0, 1.0)
        display.SetVisibility2D(True)
        for colorId in COLOR_NODE_IDS:
            if scene.GetNodeByID(colorId) is not None:
                display.SetAndObserveColorNodeID(colorId)
                break

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


def referenced(owner, role: str, className: str, name: str):
    """The node ``owner`` references under ``role``, or a new one of ``className`` added to its scene."""
    node = owner.GetNodeReference(role)
    if node is None or not node.IsA(className) or node.GetScene() is None:
        node = owner.GetScene().AddNewNodeByClass(className, name)
        owner.SetNodeReferenceID(role, node.GetID())
    return node

