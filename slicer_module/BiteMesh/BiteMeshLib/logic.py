"""BiteMesh logic: MRML nodes in, a tetrahedral model node and its quality histogram out.

Everything the module does happens here, without Qt, ctk or ScriptedLoadableModule, so that it runs in Slicer and
against the real MRML classes of the PyPI package ``slicer-core`` (where the tests run it).

Coordinates: Slicer's world frame is RAS (ITK's LPS is diag(-1, -1, 1) of it).  Markups give their control and
curve points in world coordinates; a model's points are taken through its parent transforms; labelled points files
are read as LPS, as Slicer reads its own model and markups files (:func:`loadLabelledPoints`); a segment's binary
labelmap is meshed in its own voxel frame (voxel size applied) and the mesh is then carried to world coordinates by
the labelmap's IJK-to-RAS direction and origin and the segmentation's parent transforms, so the mesh lands where
the segment is.  The output mesh is always in world (RAS) coordinates.

bitemesh (``filters/bitemesh`` in the source tree, installed beside BiteMesh.py in the extension) needs numpy,
SimpleITK and VTK, which Slicer bundles and which must never be pip-installed into Slicer, and scipy, which recent
Slicer releases bundle too; :func:`installRequirements` installs only what is missing, and only scipy.
"""
from __future__ import annotations

import importlib
import importlib.util
import logging
import math
import re
import sys
import time
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import slicer
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints, vtkStringArray
from vtkmodules.vtkCommonDataModel import vtkTable
from vtkmodules.vtkCommonMath import vtkMatrix4x4
from vtkmodules.vtkCommonTransforms import vtkGeneralTransform
from vtkmodules.vtkFiltersCore import vtkAssignAttribute, vtkPolyDataNormals
from vtkmodules.vtkFiltersGeneral import vtkTransformPolyDataFilter

try:  # Slicer
    from slicer.ScriptedLoadableModule import ScriptedLoadableModuleLogic
except ImportError:  # slicer-core has no ScriptedLoadableModule (it needs Qt): the same constructor, nothing more
    class ScriptedLoadableModuleLogic:
        """Stand-in for Slicer's base class where it is absent (headless MRML from slicer-core)."""

        def __init__(self, parent=None):
            self.parent = parent
            name = type(self).__name__
            self.moduleName = name.removesuffix("Logic")

logger = logging.getLogger("BiteMesh")


# --- bitemesh and its requirements ----------------------------------------------------------------------------------

def bitemeshSourceRoot() -> Path | None:
    """The folder that holds the ``bitemesh`` package: beside BiteMesh.py (extension), or ``filters/`` (checkout)."""
    here = Path(__file__).resolve()
    candidates = [here.parents[1]]
    if len(here.parents) > 3:
        candidates.append(here.parents[3] / "filters")
    for candidate in candidates:
        if (candidate / "bitemesh" / "__init__.py").is_file():
            return candidate
    return None


def _addBitemeshToPath() -> None:
    root = bitemeshSourceRoot()
    if root is not None and str(root) not in sys.path:
        sys.path.insert(0, str(root))


_addBitemeshToPath()

#: what bitemesh needs beyond the Python packages Slicer bundles (numpy, VTK, SimpleITK): module -> pip requirement.
REQUIREMENTS = {"scipy": "scipy>=1.9"}
#: Slicer bundles these and breaks if pip replaces them: never installed, whatever a requirement says.
NEVER_INSTALL = ("vtk", "simpleitk", "itk", "numpy")


class MissingRequirementError(ImportError):
    """A Python package bitemesh needs is absent and was not installed."""


def missingRequirements() -> list:
    """The pip requirements (of :data:`REQUIREMENTS`) whose module cannot be imported, e.g. ``["scipy>=1.9"]``."""
    return [requirement for module, requirement in REQUIREMENTS.items() if importlib.util.find_spec(module) is None]


def installRequirements(pipInstall=None, confirm=None) -> list:
    """Install the missing requirements (scipy only) with Slicer's pip, on first use.

    Parameters
    ----------
    pipInstall : callable taking a list of requirement strings; default ``slicer.util.pip_install``
    confirm : callable(missing) -> bool asking the user, or None to install without asking

    Returns
    -------
    The requirements that were installed (empty when nothing was missing).

    numpy is pinned to the version Slicer bundles so that pip cannot replace it; VTK and SimpleITK are never named.
    """
    missing = missingRequirements()
    if not missing:
        return []
    named = {requirement.split(">")[0].split("=")[0].split("<")[0].strip().lower() for requirement in missing}
    if named & set(NEVER_INSTALL):
        raise MissingRequirementError(f"refusing to pip-install {sorted(named & set(NEVER_INSTALL))} into Slicer")
    if confirm is not None and not confirm(missing):
        raise MissingRequirementError(f"BiteMesh needs {', '.join(missing)}; it was not installed")
    if pipInstall is None:
        pipInstall = slicer.util.pip_install
    pipInstall(missing + [f"numpy=={np.__version__}"])
    importlib.invalidate_caches()
    still = missingRequirements()
    if still:
        raise MissingRequirementError(f"installing {', '.join(still)} failed; install it from the Python console "
                                      f"with slicer.util.pip_install({still!r})")
    return missing


def _requireBitemesh():
    """Import bitemesh, saying how to fix a missing requirement instead of a bare ImportError."""
    missing = missingRequirements()
    if missing:
        raise MissingRequirementError(f"BiteMesh needs {', '.join(missing)}: open the BiteMesh module (it offers to "
                                      f"install it) or run slicer.util.pip_install({missing!r})")
    import bitemesh
    return bitemesh


# --- parameters, from the core's dataclasses ------------------------------------------------------------------------

#: the module's parameters: parameter-node name -> (core dataclass, field), in panel order.
PARAMETERS = {
    "radius": ("BitingParameters", "radius"),
    "cells": ("BitingParameters", "cells"),
    "gridSpacing": ("ImplicitParameters", "grid_spacing"),
    "errorBound": ("ImplicitParameters", "error_bound"),
    "method": ("ImplicitParameters", "method"),
    "threshold": ("SpuriousParameters", "threshold"),
    "minComponent": ("SpuriousParameters", "min_component"),
    "order": ("BitingParameters", "order"),
    "seed": ("BitingParameters", "seed"),
    "maxMemoryMb": ("ImplicitParameters", "max_memory_mb"),
    "bins": ("QualityParameters", "bins"),
    "optimize": ("OptimizeSwitch", "optimize"),
    "domain": ("LabelledParameters", "domain"),
    "basePlane": ("LabelledParameters", "base_plane"),
    "outliers": ("ImplicitParameters", "outliers"),
    "allowUnfaithful": ("FidelityParameters", "allow_unfaithful"),
}
#: keywords of :meth:`BiteMeshLogic.process` beyond the panel's (no "automatic" sentinel fits them: their ranges
#: include their low bound).
EXTRA_KEYWORDS = {"margin": ("ImplicitParameters", "margin"), "min_wall": ("LabelledParameters", "min_wall"),
                  "rv_wall": ("LabelledParameters", "rv_wall"),
                  "allow_implausible": ("LabelledParameters", "allow_implausible")}


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter of the panel, read from the core's dataclass field.

    Attributes
    ----------
    name : parameter-node name (camelCase); core : keyword of ``process`` (the dataclass field)
    kind : float, int or str; default : the parameter-node default
    low, high : valid range (None: unbounded); lowOpen : the low bound itself is invalid
    choices : the valid values of a str parameter, else None (a str parameter without choices is free text)
    automatic : the parameter-node value that stands for "chosen automatically" (the core's None), or None when the
        parameter is not optional; it is ``low`` of an open range, never a valid value
    help, unit : from the field's metadata
    """

    name: str
    core: str
    kind: type
    default: object
    low: float | None
    high: float | None
    lowOpen: bool
    choices: tuple | None
    automatic: object
    help: str
    unit: str


def parameterSpecs() -> tuple:
    """The :class:`ParameterSpec` of every panel parameter, in panel order, from bitemesh.core.parameters."""
    _requireBitemesh()
    from bitemesh.core import parameters as core
    specs = []
    for name, (dataclassName, fieldName) in PARAMETERS.items():
        item = {f.name: f for f in fields(getattr(core, dataclassName))}[fieldName]
        metadata = item.metadata
        if "choices" in metadata or metadata.get("text"):
            choices = tuple(metadata["choices"]) if "choices" in metadata else None
            specs.append(ParameterSpec(name, fieldName, str, item.default, None, None, False, choices, None,
                                       metadata["help"], metadata["unit"]))
            continue
        low, high, lowOpen, _ = metadata["range"]
        kind = int if metadata["integer"] else float
        high = None if high is None or high == float("inf") else kind(high)
        automatic = None
        default = item.default
        if default is None:  # optional: the open low bound stands for "automatic" in the parameter node
            if low is None or not lowOpen:
                raise ValueError(f"{fieldName}: an optional parameter needs an open low bound to stand for automatic")
            automatic = default = kind(low)
        specs.append(ParameterSpec(name, fieldName, kind, kind(default), None if low is None else kind(low), high,
                                   bool(lowOpen), None, automatic, metadata["help"], metadata["unit"]))
    return tuple(specs)


def coreParameters(values: dict) -> dict:
    """Parameter-node values (by name) -> keywords of :meth:`BiteMeshLogic.process` ("automatic" becomes None)."""
    keywords = {}
    for spec in parameterSpecs():
        if spec.name in values:
            value = values[spec.name]
            keywords[spec.core] = None if spec.automatic is not None and value == spec.automatic else value
    return keywords


# --- labelled points files ------------------------------------------------------------------------------------------

#: how loadLabelledPoints takes a file's coordinates: as LPS (negate x and y for RAS) or as RAS.
COORDINATE_SYSTEMS = ("LPS", "RAS")
#: the loaded points are drawn as dots this large (pixels).
LABELLED_POINT_SIZE = 4.0


def loadLabelledPoints(path, name=None, scene=None, coordinateSystem="LPS"):
    """A model node in ``scene`` holding the labelled contour points of a file, to mesh with
    :meth:`BiteMeshLogic.process`.

    Parameters
    ----------
    path : a biv-me GPFile (.txt), a CSV table or a VTK file (.vtp) with a ``Label`` point array, as read by
        bitemesh.io.read_labelled_points
    name : the node's name; default the file's name without its extension
    scene : vtkMRMLScene; default slicer.mrmlScene
    coordinateSystem : "LPS" (default) or "RAS", the frame of the file's coordinates (mm).  Files are LPS as
        Slicer reads its own model and markups files, and as DICOM's patient coordinates are, in which biv-me
        writes GPFiles (the points of bitemesh's sample GPFile lie on the slice planes that its SliceInfoFile's
        ImagePositionPatient and ImageOrientationPatient give); LPS points are turned to RAS, x and y negated, so
        that they overlay the images of the same study.

    Returns
    -------
    vtkMRMLModelNode: one vertex per point (world RAS, mm), point arrays ``Label`` (vtkStringArray) and, when the
    file gives slices, ``Slice`` (int64).
    """
    _requireBitemesh()
    from bitemesh.convert import nodes_to_polydata
    from bitemesh.core.errors import check_choice
    from bitemesh.io import read_labelled_points

    check_choice(coordinateSystem, "coordinateSystem", COORDINATE_SYSTEMS)
    points, labels, slices = read_labelled_points(path, slices=True)
    if coordinateSystem == "LPS":
        points = points * np.array([-1.0, -1.0, 1.0])
    polydata = nodes_to_polydata(points)
    labelArray = vtkStringArray()
    labelArray.SetName("Label")
    labelArray.SetNumberOfValues(len(labels))
    for index, label in enumerate(labels.tolist()):
        labelArray.SetValue(index, label)
    polydata.GetPointData().AddArray(labelArray)
    if slices is not None:
        sliceArray = numpy_support.numpy_to_vtk(np.ascontiguousarray(slices, dtype=np.int64), deep=True)
        sliceArray.SetName("Slice")
        polydata.GetPointData().AddArray(sliceArray)
    scene = slicer.mrmlScene if scene is None else scene
    node = scene.AddNewNodeByClass("vtkMRMLModelNode", name or Path(path).stem)
    node.SetAndObservePolyData(polydata)
    node.CreateDefaultDisplayNodes()
    node.GetDisplayNode().SetPointSize(LABELLED_POINT_SIZE)
    return node


# --- what the logic returns -----------------------------------------------------------------------------------------

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
#: closed curves for the RBF are resampled to about this many points in all, at least MIN_CURVE_POINTS each.
RBF_CURVE_POINTS, MIN_CURVE_POINTS = 300, 16
#: a labelled closed curve is resampled evenly by arc length to at least its control points, at most this far apart
#: (mm): about biv-me's contour points (3 mm) and the contour RBF's 4 mm offset, and few enough for a quick fit.
CONTOUR_SPACING = 5.0
#: a node attribute naming the label of a closed curve or point list (else its name without a copy number).
LABEL_ATTRIBUTE = "BiteMesh.Label"
#: a trailing copy number of a node name: "LV_ENDO_1", "LV_ENDO 2" and "LV_ENDO-3" are contours of LV_ENDO.
COPY_NUMBER = re.compile(r"[ _-]+\d+$")
INPUT_TYPES = ("vtkMRMLMarkupsFiducialNode", "vtkMRMLMarkupsClosedCurveNode", "vtkMRMLModelNode",
               "vtkMRMLSegmentationNode")


class BiteMeshLogic(ScriptedLoadableModuleLogic):
    """Tetrahedral meshes from Slicer nodes by bitemesh.

    ``process(inputNode, outputModelNode, **parameters)`` takes a markups point list, one or more markups closed
    curves (contours), a model (its points and normals) or a segmentation (one segment), and writes into
    ``outputModelNode`` a vtkUnstructuredGrid of tetrahedra coloured by radius ratio, with the radius-ratio
    histogram as a table node and a bar plot.  Labelled contours (a model with a point array ``Label``, as
    :meth:`loadLabelledPoints` makes from a biv-me GPFile, or closed curves named after their surfaces with a
    ``domain``) are meshed as the domain their surfaces bound.  It needs no GUI.
    """

    def __init__(self, parent=None):
        ScriptedLoadableModuleLogic.__init__(self, parent)

    # The panel's parameters, for the widget (BiteMesh.py builds its parameterNodeWrapper from them).
    parameterSpecs = staticmethod(parameterSpecs)
    coreParameters = staticmethod(coreParameters)
    missingRequirements = staticmethod(missingRequirements)
    installRequirements = staticmethod(installRequirements)
    loadLabelledPoints = staticmethod(loadLabelledPoints)

    def process(self, inputNode, outputModelNode, segmentId=None, progress=None, **parameters) -> BiteMeshResult:
        """Mesh ``inputNode`` into ``outputModelNode``.

        Parameters
        ----------
        inputNode : vtkMRMLMarkupsFiducialNode, vtkMRMLMarkupsClosedCurveNode, vtkMRMLModelNode,
            vtkMRMLSegmentationNode, or a list of point lists, closed curves and models (their points pooled)
        outputModelNode : vtkMRMLModelNode in a scene; receives the mesh (world/RAS coordinates, mm)
        segmentId : the segment to mesh (segmentation input); default the first segment
        progress : callable(fraction, message) or None; it may raise bitemesh.Cancelled to stop
        **parameters : keywords of bitemesh's parameter dataclasses, None for "automatic": radius, cells,
            grid_spacing, error_bound, method, threshold, min_component, order, seed, max_memory_mb, margin,
            bins, optimize (0 or 1), domain, base_plane, min_wall.  ``method`` defaults to "rbf" for closed curves
            (sparse contours), else "mpu".  For a segmentation the grid is the segment's voxel grid, resampled to
            grid_spacing when given or when the voxels are coarser than radius / 4 or finer than radius / 8;
            method and error_bound do not apply.

        Labelled contours: the input is labelled when a model has a point array ``Label`` or ``domain`` is given
        (not empty); then every input node is labelled (:meth:`_labelledPoints`) and the points go to
        bitemesh's ``run_labelled``: one surface per label (biv-me's surfaces for biv-me labels), combined by the
        CSG expression ``domain`` (default: biv-me's two-cavity myocardium, or the only label), closed by
        ``base_plane`` (auto, valves or none), no wall thinner than ``min_wall`` (mm; default max(2.5, 1.25 R));
        method and error_bound do not apply.  domain, base_plane and min_wall do not apply to other inputs.

        Returns
        -------
        BiteMeshResult

        Raises
        ------
        bitemesh.InvalidInputError naming the bad node or parameter, bitemesh.MeshingError, bitemesh.Cancelled.
        Nothing is written to the scene unless meshing succeeds.
        """
        bitemesh = _requireBitemesh()
        from bitemesh.core import parameters as core
        from bitemesh.core.errors import Cancelled, InvalidInputError
        from bitemesh.core.labelled import run_labelled
        from bitemesh.core.progress import report, sub_progress

        clock = time.perf_counter()
        nodes = self._inputNodes(inputNode)
        self._checkOutput(outputModelNode, nodes)
        contours = all(node.IsA("vtkMRMLMarkupsClosedCurveNode") for node in nodes)
        settings = self._parameters(parameters, method="rbf" if contours else "mpu")
        implicit = core.ImplicitParameters(**settings["ImplicitParameters"])
        biting = core.BitingParameters(**settings["BitingParameters"])
        spurious = core.SpuriousParameters(**settings["SpuriousParameters"])
        quality = core.QualityParameters(**settings["QualityParameters"])
        fidelity = core.FidelityParameters(**settings["FidelityParameters"])
        labelled = core.LabelledParameters(**settings["LabelledParameters"])
        domain = (labelled.domain or "").strip()   # "" (or None) stands for the default domain
        optimize = core.OptimizeParameters() if core.OptimizeSwitch(**settings["OptimizeSwitch"]).optimize else None

        report(progress, 0.0, "reading the input")
        if any(node.IsA("vtkMRMLSegmentationNode") for node in nodes):
            if len(nodes) > 1:
                raise InvalidInputError("a segmentation must be the only input; mesh one segmentation at a time")
            if segmentId is not None and not isinstance(segmentId, str):
                raise InvalidInputError(f"segmentId must be a segment ID string, got {segmentId!r}")
            if domain:
                raise InvalidInputError(f"domain: {labelled.domain!r} combines labelled contours, and a segmentation "
                                        "has none; clear domain to mesh the segment")
            mesh, result = self._meshSegment(nodes[0], segmentId, implicit, biting, spurious, optimize, fidelity,
                                             sub_progress(progress, 0.0, 0.95))
        elif domain or any(node.IsA("vtkMRMLModelNode") and self._modelLabels(node)[0] is not None for node in nodes):
            points, labels, slices = self._labelledPoints(nodes)
            report(progress, 0.02, f"meshing {len(points)} labelled points ({len(np.unique(labels))} labels)")
            result = run_labelled(points, labels, domain=domain or None, base_plane=labelled.base_plane,
                                  slices=slices, min_wall=labelled.min_wall, rv_wall=labelled.rv_wall,
                                  allow_implausible=bool(labelled.allow_implausible), implicit=implicit,
                                  biting=biting, spurious=spurious, optimize=optimize, fidelity=fidelity,
                                  progress=sub_progress(progress, 0.02, 0.95))
            mesh = result.mesh
        else:
            points, normals, slices = self._scatteredPoints(nodes, implicit.method)
            report(progress, 0.02, f"meshing {len(points)} points")
            result = bitemesh.run(points, normals, implicit, biting, spurious, sub_progress(progress, 0.02, 0.95),
                                  optimize=optimize, fidelity=fidelity, slices=slices)
            mesh = result.mesh
        radius, seconds = result.radius, dict(result.seconds)

        report(progress, 0.95, "writing the mesh")
        summary = bitemesh.quality_summary(mesh)
        table, series, chart = self._writeOutputs(mesh, radius, summary, result.fidelity, outputModelNode,
                                                  quality.bins)
        seconds["total"] = time.perf_counter() - clock
        logger.info("BiteMesh: %d tetrahedra, %d nodes, R = %.4g mm, mean radius ratio %.3f, in %.1f s",
                    summary.n_cells, summary.n_points, radius, summary.q_mean, seconds["total"])
        if result.fidelity is not None:
            logger.info("BiteMesh fidelity: %s", result.fidelity.describe())
        try:
            report(progress, 1.0, "done")
        except Cancelled:   # too late: the output is written, and a run that wrote it is not a cancelled one
            pass
        return BiteMeshResult(mesh, radius, summary, table, series, chart, seconds, result.fidelity, result.notes)

    # --- checks ------------------------------------------------------------------------------------------------------

    @staticmethod
    def _inputNodes(inputNode) -> list:
        from bitemesh.core.errors import InvalidInputError
        nodes = list(inputNode) if isinstance(inputNode, (list, tuple)) else [inputNode]
        if not nodes or any(node is None for node in nodes):
            raise InvalidInputError("inputNode: no input node; select a markups point list, closed curves, a model "
                                    "or a segmentation")
        for node in nodes:
            if not any(hasattr(node, "IsA") and node.IsA(kind) for kind in INPUT_TYPES):
                kind = node.GetClassName() if hasattr(node, "GetClassName") else type(node).__name__
                hint = ("; an open curve bounds no volume: use a closed curve" if hasattr(node, "IsA")
                        and node.IsA("vtkMRMLMarkupsCurveNode") else "")
                raise InvalidInputError(f"inputNode: {kind} is not an accepted input; give one of "
                                        f"{', '.join(INPUT_TYPES)}{hint}")
        return nodes

    @staticmethod
    def _checkOutput(outputModelNode, nodes) -> None:
        from bitemesh.core.errors import InvalidInputError
        if outputModelNode is None or not outputModelNode.IsA("vtkMRMLModelNode"):
            raise InvalidInputError("outputModelNode: select or create a model node for the mesh")
        if outputModelNode.GetScene() is None:
            raise InvalidInputError("outputModelNode: the model node is not in a scene; add it to the scene first")
        if any(node is outputModelNode for node in nodes):
            raise InvalidInputError("outputModelNode: it is also the input; choose a new model node for the mesh")

    @staticmethod
    def _parameters(parameters: dict, method: str) -> dict:
        """Split keyword parameters by core dataclass; unknown names are refused with the list of known ones."""
        from bitemesh.core.errors import InvalidInputError
        known = {fieldName: dataclassName for dataclassName, fieldName in
                 list(PARAMETERS.values()) + list(EXTRA_KEYWORDS.values())}
        unknown = sorted(set(parameters) - set(known))
        if unknown:
            raise InvalidInputError(f"unknown parameter(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
        split = {name: {} for name in ("ImplicitParameters", "BitingParameters", "SpuriousParameters",
                                       "QualityParameters", "OptimizeSwitch", "LabelledParameters",
                                       "FidelityParameters")}
        split["ImplicitParameters"]["method"] = method
        for name, value in parameters.items():
            split[known[name]][name] = value
        if split["ImplicitParameters"]["method"] is None:
            split["ImplicitParameters"]["method"] = method
        return split

    # --- inputs ------------------------------------------------------------------------------------------------------

    def _scatteredPoints(self, nodes, method: str):
        """(points (n, 3), normals (n, 3) or None, slices (n,) or None) in world coordinates from point lists,
        closed curves, models.

        Normals are kept only when every input gives them (closed curves and models with polygons do); slices (the
        curve of each point) only when every input is a closed curve.
        """
        from bitemesh.core.implicit import MAX_RBF_POINTS
        parts = []
        for node in nodes:
            if node.IsA("vtkMRMLMarkupsFiducialNode"):
                parts.append((self._pointListPoints(node), None))
            elif node.IsA("vtkMRMLMarkupsClosedCurveNode"):
                points = self._closedCurvePoints(node)
                parts.append((points, contourNormals(points, node.GetName())))
            else:
                parts.append(self._modelPoints(node))
        curves = [index for index, node in enumerate(nodes) if node.IsA("vtkMRMLMarkupsClosedCurveNode")]
        if method == "rbf" and curves:
            # The RBF costs (3 x points) per evaluation on every grid node: resample the densely interpolated curves
            # evenly by arc length to at most RBF_CURVE_POINTS in all, shared by length.
            others = sum(len(parts[i][0]) for i in range(len(parts)) if i not in curves)
            budget = max(min(RBF_CURVE_POINTS, MAX_RBF_POINTS - others), MIN_CURVE_POINTS * len(curves))
            lengths = np.array([closedLength(parts[i][0]) for i in curves])
            for index, length in zip(curves, lengths):
                count = max(MIN_CURVE_POINTS, round(budget * length / lengths.sum()))
                if count < len(parts[index][0]):
                    points = resampleClosed(parts[index][0], count)
                    parts[index] = (points, contourNormals(points, nodes[index].GetName()))
        points = np.vstack([part[0] for part in parts])
        normals = np.vstack([part[1] for part in parts]) if all(part[1] is not None for part in parts) else None
        slices = np.concatenate([np.full(len(part[0]), index) for index, part in enumerate(parts)]) \
            if len(curves) == len(nodes) else None
        return points, normals, slices

    @staticmethod
    def _pointListPoints(node) -> np.ndarray:
        """(n, 3) world positions of the defined control points of a markups point list."""
        from bitemesh.core.errors import InvalidInputError
        count = node.GetNumberOfControlPoints()
        defined = [i for i in range(count) if not hasattr(node, "GetNthControlPointPositionStatus")
                   or node.GetNthControlPointPositionStatus(i) == node.PositionDefined]
        if not defined:
            raise InvalidInputError(f"inputNode: the point list '{node.GetName()}' has no placed control points; "
                                    "place points on the surface to mesh (at least 10, typically hundreds)")
        points = np.zeros((len(defined), 3))
        position = [0.0, 0.0, 0.0]
        for row, index in enumerate(defined):
            node.GetNthControlPointPositionWorld(index, position)
            points[row] = position
        return points

    def _labelledPoints(self, nodes):
        """Labelled contour points of the input nodes, in world coordinates (mm).

        A model gives its points, its point array ``Label`` and its ``Slice`` (or ``FrameID``) array when present; a
        closed curve (one slice of its own) its curve resampled evenly by arc length (at least its control points,
        at most :data:`CONTOUR_SPACING` apart) and a point list its placed points (slice unknown), each labelled
        :func:`contourLabel`.

        Returns
        -------
        points : (n, 3) float64; labels : (n,) str
        slices : (n,) int64 slice ids (-1: unknown), or None when no point has one (bitemesh then finds the slice
            planes)
        """
        from bitemesh.convert import point_coordinates
        from bitemesh.core.errors import InvalidInputError
        parts, nextSlice = [], 0
        for node in nodes:
            if node.IsA("vtkMRMLModelNode"):
                labels, slices = self._modelLabels(node)
                if labels is None:
                    raise InvalidInputError(
                        f"inputNode: the model '{node.GetName()}' has no point array Label, and labelled contours "
                        "need a label per point; load them with loadLabelledPoints, or clear domain and mesh the "
                        "model alone as a surface")
                points = point_coordinates(self._worldPolyData(node))
                labels = (labels.astype(np.int64) if labels.dtype.kind in "iuf" else labels).astype(str)
                if slices is None:
                    slices = np.full(len(points), -1, dtype=np.int64)
                else:   # the model's own ids, moved past those already taken
                    slices = np.where(slices >= 0, slices + nextSlice, -1)
            else:
                if node.IsA("vtkMRMLMarkupsClosedCurveNode"):
                    curve = self._closedCurvePoints(node)
                    count = max(node.GetNumberOfControlPoints(), math.ceil(closedLength(curve) / CONTOUR_SPACING))
                    points, number = resampleClosed(curve, count), nextSlice
                else:
                    points, number = self._pointListPoints(node), -1
                labels = np.full(len(points), contourLabel(node))
                slices = np.full(len(points), number, dtype=np.int64)
            nextSlice = max(nextSlice, int(slices.max()) + 1)
            parts.append((points, labels, slices))
        slices = np.concatenate([part[2] for part in parts])
        return (np.vstack([part[0] for part in parts]), np.concatenate([part[1] for part in parts]),
                slices if (slices >= 0).any() else None)

    @staticmethod
    def _closedCurvePoints(node) -> np.ndarray:
        """(n, 3) points along a closed curve, in world coordinates: the curve as interpolated by Slicer (its curve
        points), without the point that repeats the first."""
        from bitemesh.core.errors import InvalidInputError
        curve = node.GetCurvePointsWorld() if node.GetNumberOfControlPoints() >= 3 else None
        if curve is None or curve.GetNumberOfPoints() < 3:
            raise InvalidInputError(f"inputNode: the closed curve '{node.GetName()}' has "
                                    f"{node.GetNumberOfControlPoints()} control points; a contour needs at least 3")
        points = numpy_support.vtk_to_numpy(curve.GetData()).astype(np.float64).reshape(-1, 3)
        length = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
        step = np.linalg.norm(np.diff(np.vstack([points, points[:1]]), axis=0), axis=1)
        points = points[step > 1e-9 * max(length, 1e-300)]   # drop repeats (the closing point repeats the first)
        if len(points) < 3 or length <= 0:
            raise InvalidInputError(f"inputNode: the closed curve '{node.GetName()}' is degenerate (zero length)")
        return points

    @staticmethod
    def _modelLabels(node):
        """(labels (n,) or None, slices (n,) int64 or None) of a model: its point arrays ``Label`` and ``Slice`` or
        ``FrameID`` (bitemesh.convert.point_labels)."""
        from bitemesh.convert import point_labels
        polydata = node.GetPolyData()
        if polydata is None:
            return None, None
        return point_labels(polydata, f"inputNode: the model '{node.GetName()}'")

    @staticmethod
    def _worldPolyData(node):
        """The polydata of a model through its parent transforms (world coordinates), with its point arrays."""
        from bitemesh.core.errors import InvalidInputError
        polydata = node.GetPolyData()
        if polydata is None or polydata.GetNumberOfPoints() == 0:
            what = "a volume mesh" if node.GetMesh() is not None and node.GetMesh().GetNumberOfPoints() else "no points"
            raise InvalidInputError(f"inputNode: the model '{node.GetName()}' holds {what}; give a surface model "
                                    "(or points sampled on the surface)")
        transform = _toWorld(node)
        if transform is None:
            return polydata
        moved = vtkTransformPolyDataFilter()
        moved.SetTransform(transform)
        moved.SetInputData(polydata)
        moved.Update()
        return moved.GetOutput()

    def _modelPoints(self, node):
        """(points, normals or None) of a surface model in world coordinates; normals from the model or computed
        from its polygons (auto-oriented outward); None when they are missing or unusable (bitemesh estimates them).
        """
        from bitemesh.convert import point_coordinates
        polydata = self._worldPolyData(node)
        points = point_coordinates(polydata)
        normals = polydata.GetPointData().GetNormals()
        if normals is None and polydata.GetNumberOfPolys() > 0:
            computed = vtkPolyDataNormals()
            computed.SetInputData(polydata)
            computed.ComputePointNormalsOn()
            computed.ComputeCellNormalsOff()
            computed.SplittingOff()
            computed.ConsistencyOn()
            computed.AutoOrientNormalsOn()
            computed.Update()
            if computed.GetOutput().GetNumberOfPoints() == len(points):
                normals = computed.GetOutput().GetPointData().GetNormals()
        if normals is None:
            return points, None
        normals = numpy_support.vtk_to_numpy(normals).astype(np.float64).reshape(-1, 3)
        usable = np.isfinite(normals).all() and (np.linalg.norm(normals, axis=1) > 0).all()
        return points, normals if usable else None

    # --- a segmentation ----------------------------------------------------------------------------------------------

    def _meshSegment(self, node, segmentId, implicit, biting, spurious, optimize, fidelity, progress):
        """Mesh one segment: its binary labelmap through bitemesh.labelmap.mesh_label_grid (the path the bitemesh
        command takes for label map files), which meshes in the voxel frame and places the mesh with the labelmap's
        IJK-to-RAS matrix; then the segmentation's parent transforms carry it to world."""
        from bitemesh.core.mesh import Mesh, signed_measures
        from bitemesh.core.quality import cell_quality
        from bitemesh.labelmap import mesh_label_grid

        labels, _, ijk0, ijkToWorld = segmentLabelmap(node, segmentId)
        firstVoxel = np.eye(4)
        firstVoxel[:3, 3] = ijk0   # labels[0, 0, 0] is voxel ijk0 of the labelmap's frame
        result = mesh_label_grid(labels, ijkToWorld @ firstVoxel, implicit=implicit, biting=biting,
                                 spurious=spurious, optimize=optimize, fidelity=fidelity, progress=progress)
        transform = _toWorld(node)
        if transform is None:
            return result.mesh, result
        points = transformPoints(transform, result.mesh.points)
        cells = result.mesh.cells.copy()
        if np.sum(signed_measures(points, cells)) < 0:   # a parent transform that reflects
            cells[:, [1, 2]] = cells[:, [2, 1]]
        mesh = Mesh(points, cells)
        return mesh.with_cell_data(**cell_quality(mesh)), result

    # --- outputs -----------------------------------------------------------------------------------------------------

    def _writeOutputs(self, mesh, radius, summary, fidelity, outputModelNode, bins):
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
        tableNode = _referenced(outputModelNode, TABLE_ROLE, "vtkMRMLTableNode", f"{base} radius ratio histogram")
        tableNode.SetAndObserveTable(table)
        series = _referenced(outputModelNode, SERIES_ROLE, "vtkMRMLPlotSeriesNode", f"{base} radius ratio")
        series.SetAndObserveTableNodeID(tableNode.GetID())
        series.SetXColumnName("BinCentre")
        series.SetYColumnName("Count")
        series.SetPlotType(series.PlotTypeBar)
        chart = _referenced(outputModelNode, CHART_ROLE, "vtkMRMLPlotChartNode", f"{base} quality")
        if not chart.HasPlotSeriesNodeID(series.GetID()):
            chart.AddAndObservePlotSeriesNodeID(series.GetID())
        chart.SetTitle(f"Radius ratio of {summary.n_cells} tetrahedra (mean {summary.q_mean:.3f})")
        chart.SetXAxisTitle("radius ratio 3 r_in / R_circ (1 = regular)")
        chart.SetYAxisTitle("cells")
        chart.SetLegendVisibility(False)
        return tableNode, series, chart


# --- helpers --------------------------------------------------------------------------------------------------------

def contourNormals(points: np.ndarray, name: str = "curve") -> np.ndarray:
    """(n, 3) outward unit normals of a closed planar-ish curve, in its best-fit plane.

    The plane normal is the direction of least spread; each normal is (tangent x plane normal), the whole set
    flipped so that it points away from the enclosed area (positive flux through the curve).
    """
    from bitemesh.core.errors import InvalidInputError
    centred = points - points.mean(axis=0)
    _, spread, axes = np.linalg.svd(centred, full_matrices=False)
    if spread[1] <= 1e-9 * spread[0]:
        raise InvalidInputError(f"inputNode: the closed curve '{name}' is a line; a contour must enclose an area")
    tangent = np.roll(points, -1, axis=0) - np.roll(points, 1, axis=0)
    normals = np.cross(tangent, axes[2])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    if not (length > 0).all():
        raise InvalidInputError(f"inputNode: the closed curve '{name}' doubles back on itself")
    normals /= length
    if np.einsum("ij,ij->", normals, centred) < 0:
        normals = -normals
    return normals


def contourLabel(node) -> str:
    """The label of a closed curve or point list: its attribute :data:`LABEL_ATTRIBUTE`, else its name without a
    trailing copy number ("LV_ENDO_2" -> "LV_ENDO")."""
    from bitemesh.core.errors import InvalidInputError
    label = (node.GetAttribute(LABEL_ATTRIBUTE) or "").strip()
    if not label:
        name = (node.GetName() or "").strip()
        label = COPY_NUMBER.sub("", name) or name
    if not label:
        raise InvalidInputError(f"inputNode: the {node.GetClassName()} '{node.GetID()}' has no name; name it after "
                                f"its surface (e.g. LV_ENDO) or set its attribute {LABEL_ATTRIBUTE}")
    return label


def closedLength(points: np.ndarray) -> float:
    """Length of the closed polyline through ``points``."""
    return float(np.linalg.norm(np.roll(points, -1, axis=0) - points, axis=1).sum())


def resampleClosed(points: np.ndarray, count: int) -> np.ndarray:
    """``count`` points evenly spaced by arc length along the closed polyline through ``points``."""
    closed = np.vstack([points, points[:1]])
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))]
    at = np.linspace(0.0, arc[-1], count, endpoint=False)
    return np.column_stack([np.interp(at, arc, closed[:, axis]) for axis in range(3)])


def segmentLabelmap(node, segmentId=None):
    """One segment of a segmentation node as a binary label array and its geometry.

    Returns
    -------
    labels : (n_i, n_j, n_k) uint8, 1 inside, indexed [i, j, k] from the extent's first voxel
    spacing : (3,) voxel size (mm); ijk0 : (3,) IJK index of labels[0, 0, 0]
    ijkToWorld : (4, 4) IJK -> RAS of the segmentation's frame (the node's parent transforms not included)
    """
    from bitemesh.core.errors import InvalidInputError
    segmentation = node.GetSegmentation()
    ids = [segmentation.GetNthSegmentID(i) for i in range(segmentation.GetNumberOfSegments())]
    if not ids:
        raise InvalidInputError(f"inputNode: the segmentation '{node.GetName()}' has no segments")
    segmentId = ids[0] if segmentId in (None, "") else segmentId
    if segmentId not in ids:
        names = ", ".join(f"{i} ({segmentation.GetSegment(i).GetName()})" for i in ids)
        raise InvalidInputError(f"segmentId: '{segmentId}' is not a segment of '{node.GetName()}'; segments: {names}")
    name = slicer.vtkSegmentationConverter.GetSegmentationBinaryLabelmapRepresentationName()
    if not segmentation.ContainsRepresentation(name):
        node.CreateBinaryLabelmapRepresentation()
        if not segmentation.ContainsRepresentation(name):
            raise InvalidInputError(f"inputNode: the segmentation '{node.GetName()}' could not be converted to a "
                                    "binary labelmap; create one in the Segmentations module")
    image = slicer.vtkOrientedImageData()
    node.GetBinaryLabelmapRepresentation(segmentId, image)
    segmentName = segmentation.GetSegment(segmentId).GetName()
    scalars = image.GetPointData().GetScalars() if image.GetNumberOfPoints() else None
    if scalars is None:
        raise InvalidInputError(f"inputNode: the segment '{segmentName}' is empty; paint it first")
    dims = image.GetDimensions()
    labels = (numpy_support.vtk_to_numpy(scalars).reshape(dims, order="F") != 0).astype(np.uint8)
    if not labels.any():
        raise InvalidInputError(f"inputNode: the segment '{segmentName}' is empty; paint it first")
    matrix = vtkMatrix4x4()
    image.GetImageToWorldMatrix(matrix)
    ijkToWorld = np.array([[matrix.GetElement(r, c) for c in range(4)] for r in range(4)])
    extent = image.GetExtent()
    return labels, np.array(image.GetSpacing(), dtype=np.float64), np.array(extent[::2], dtype=np.float64), \
        ijkToWorld


def _toWorld(node):
    """The node's parent transforms to world as a vtkGeneralTransform, or None when it has none."""
    parent = node.GetParentTransformNode() if hasattr(node, "GetParentTransformNode") else None
    if parent is None:
        return None
    transform = vtkGeneralTransform()
    slicer.vtkMRMLTransformNode.GetTransformBetweenNodes(parent, None, transform)
    return transform


def transformPoints(transform, points: np.ndarray) -> np.ndarray:
    """(n, 3) points through a VTK transform."""
    source, target = vtkPoints(), vtkPoints()
    source.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
    transform.TransformPoints(source, target)
    return numpy_support.vtk_to_numpy(target.GetData()).astype(np.float64).reshape(-1, 3)


def _referenced(owner, role: str, className: str, name: str):
    """The node ``owner`` references under ``role``, or a new one of ``className`` added to its scene."""
    node = owner.GetNodeReference(role)
    if node is None or not node.IsA(className) or node.GetScene() is None:
        node = owner.GetScene().AddNewNodeByClass(className, name)
        owner.SetNodeReferenceID(role, node.GetID())
    return node
