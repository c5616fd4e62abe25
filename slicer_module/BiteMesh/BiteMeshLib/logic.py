"""BiteMesh logic: MRML nodes in, a tetrahedral model node and its quality histogram out.

The rooms of BiteMeshLib: ``requirements`` (bitemesh on the path, scipy on first use), ``parameters`` (the panel's
parameters from bitemesh's dataclasses), one module per input kind (``points``: point lists, closed curves, models;
``contours``: labelled contours; ``segments``: a segmentation's segment), ``outputs`` (the model node, the
histogram, the result) and this one, which dispatches an input to bitemesh.

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

import logging
import time
from dataclasses import asdict, fields

import numpy as np

from .contours import hasLabelledModel, labelledPoints, loadLabelledPoints
from .fitting import fitSamples, templateMesh
from .outputs import BiteMeshResult, writeFibres, writeOutputs, writeSurfaces
from .parameters import FIT_PARAMETERS, coreParameters, coreSettings, parameterSpecs
from .points import scatteredPoints
from .requirements import installRequirements, missingRequirements, requireBitemesh
from .segments import meshSegment

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

#: the MRML classes process() takes as input.
INPUT_TYPES = ("vtkMRMLMarkupsFiducialNode", "vtkMRMLMarkupsClosedCurveNode", "vtkMRMLModelNode",
               "vtkMRMLSegmentationNode")


def withoutContourOptions(options):
    """``options`` with the panel's "Labelled contours" section at its defaults: the panel hands every value to
    every input, and that section applies to labelled contours only."""
    from bitemesh.core.parameters import LabelledParameters
    return options.replace(**{item.name: item.default for item in fields(LabelledParameters)})


class BiteMeshLogic(ScriptedLoadableModuleLogic):
    """Tetrahedral meshes from Slicer nodes by bitemesh.

    ``process(inputNode, outputModelNode, **parameters)`` takes a markups point list, one or more markups closed
    curves (contours), a model (its points and normals) or a segmentation (one segment), and writes into
    ``outputModelNode`` a vtkUnstructuredGrid of tetrahedra coloured by radius ratio (cell array ``Region``), with
    one model node per surface tag of its boundary (labelled contours: EPI, LV_ENDO, RV_ENDO, BASE; other inputs:
    BOUNDARY_1, ... by decreasing area, or the segment's BOUNDARY_1) and the radius-ratio histogram as a table node
    and a bar plot; with ``fibres=1``, the heart's myocardial fibres as cell arrays, coloured by helix angle.
    Labelled contours (a model with a point array ``Label``, as :meth:`loadLabelledPoints` makes from a biv-me
    GPFile, or closed curves named after their surfaces with a ``domain``) are meshed as the domain their surfaces
    bound.  It needs no GUI.
    """

    def __init__(self, parent=None):
        ScriptedLoadableModuleLogic.__init__(self, parent)

    # The panel's parameters, for the widget (BiteMesh.py builds its parameterNodeWrapper from them).
    parameterSpecs = staticmethod(parameterSpecs)

    @staticmethod
    def fitParameterSpecs() -> tuple:
        """The :class:`.parameters.ParameterSpec` of the elastic template's section (``pull``)."""
        return parameterSpecs(FIT_PARAMETERS)
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
        **parameters : the fields of bitemesh's parameter dataclasses that the panel has (the keys of
            :data:`.parameters.KEYWORDS`), None for "automatic"; others are refused.  ``optimize`` (0 or 1) runs
            the MeshOptimizer with ``iterations``, ``min_dihedral`` and ``min_quality`` (checked even when it is
            off).  ``method`` defaults to "rbf" for closed curves (sparse contours), else "mpu".  For a
            segmentation the grid is the segment's voxel grid, resampled to grid_spacing when given or when the
            voxels are coarser than radius / 4 or finer than radius / 8; method and error_bound do not apply.

        Labelled contours: the input is labelled when a model has a point array ``Label`` or ``domain`` is given
        (not empty); then every input node is labelled (:func:`.contours.labelledPoints`) and the points go to
        bitemesh's ``run_labelled``: one surface per label (biv-me's surfaces for biv-me labels), combined by the
        CSG expression ``domain`` (default: biv-me's two-cavity myocardium, or the only label), closed by
        ``base_plane`` (auto, valves or none), no wall thinner than ``min_wall`` (mm; default max(2.5, 1.25 R));
        method and error_bound do not apply.  domain, base_plane, min_wall, rv_wall (biv-me: the derived RV free
        wall, mm) and allow_implausible (1: keep a heart that fails the plausibility checks) do not apply to
        other inputs.

        Fibres: ``fibres`` 1 adds bitemesh's rule-based myocardial fibres (bitemesh.core.fem.fibres.with_fibres, Bayer
        et al. 2012, with ``alpha_endo``, ``alpha_epi``, ``beta_endo`` and ``beta_epi`` in degrees) to the mesh:
        the cell vectors Fibre (the active vectors), Sheet and SheetNormal and the cell scalar HelixAngle, by which
        the model is then coloured.  They need a mesh whose boundary is tagged EPI, LV_ENDO, RV_ENDO and BASE, as
        that of labelled biventricular contours (a biv-me GPFile) is, or EPI, ENDO and BASE (the LV's alone); any
        other mesh is refused (InvalidInputError
        naming the surfaces it lacks) after meshing, and nothing is written.  The angles are checked (range
        [-90, 90]) before anything runs, also when ``fibres`` is 0.

        Returns
        -------
        BiteMeshResult

        Raises
        ------
        bitemesh.InvalidInputError naming the bad node or parameter, bitemesh.MeshingError, bitemesh.Cancelled.
        Nothing is written to the scene unless meshing succeeds.
        """
        bitemesh = requireBitemesh()
        from bitemesh.core.errors import Cancelled, InvalidInputError
        from bitemesh.core.mesh.quality import quality_summary
        from bitemesh.core.progress import report, sub_progress

        clock = time.perf_counter()
        nodes = self._inputNodes(inputNode)
        self._checkOutput(outputModelNode, nodes)
        contours = all(node.IsA("vtkMRMLMarkupsClosedCurveNode") for node in nodes)
        settings = coreSettings(parameters, method="rbf" if contours else "mpu")
        options = bitemesh.Options(**{name: value for dataclassName, values in settings.items()
                                      if dataclassName != "QualityParameters"
                                      for name, value in asdict(values).items()})
        fibres = settings["FibreParameters"] if options.fibres else None
        domain = (options.domain or "").strip()   # "" (or None) stands for the default domain

        report(progress, 0.0, "reading the input")
        if any(node.IsA("vtkMRMLSegmentationNode") for node in nodes):
            if len(nodes) > 1:
                raise InvalidInputError("a segmentation must be the only input; mesh one segmentation at a time")
            if segmentId is not None and not isinstance(segmentId, str):
                raise InvalidInputError(f"segmentId must be a segment ID string, got {segmentId!r}")
            if domain:
                raise InvalidInputError(f"domain: {options.domain!r} combines labelled contours, and a segmentation "
                                        "has none; clear domain to mesh the segment")
            mesh, result = meshSegment(nodes[0], segmentId, withoutContourOptions(options),
                                       sub_progress(progress, 0.0, 0.95))
        else:
            if domain or hasLabelledModel(nodes):
                points, labels, slices = labelledPoints(nodes)
                samples = bitemesh.Samples(points, labels=labels, slices=slices)
                report(progress, 0.02, f"meshing {len(points)} labelled points ({len(np.unique(labels))} labels)")
            else:
                points, normals, slices = scatteredPoints(nodes, options.method)
                samples = bitemesh.Samples(points, normals, slices=slices)
                options = withoutContourOptions(options)
                report(progress, 0.02, f"meshing {len(points)} points")
            result = bitemesh.mesh(samples, options, progress=sub_progress(progress, 0.02, 0.95))
            mesh = result.mesh
        radius, seconds = result.radius, dict(result.seconds)

        report(progress, 0.95, "writing the mesh")
        summary = quality_summary(mesh)
        table, series, chart = writeOutputs(mesh, radius, summary, result.fidelity, outputModelNode,
                                            settings["QualityParameters"].bins)
        writeFibres(outputModelNode, fibres)
        surfaces = writeSurfaces(mesh, outputModelNode)
        seconds["total"] = time.perf_counter() - clock
        logger.info("BiteMesh: %d tetrahedra, %d nodes, R = %.4g mm, mean radius ratio %.3f, in %.1f s",
                    summary.n_cells, summary.n_points, radius, summary.q_mean, seconds["total"])
        if result.fidelity is not None:
            logger.info("BiteMesh fidelity: %s", result.fidelity.describe())
        try:
            report(progress, 1.0, "done")
        except Cancelled:   # too late: the output is written, and a run that wrote it is not a cancelled one
            pass
        return BiteMeshResult(mesh, radius, summary, table, series, chart, seconds, result.fidelity, result.notes,
                              surfaces)

    def fitTemplate(self, templateNode, dataNode, outputModelNode, pull: float = 3.0, progress=None):
        """Move the template (``templateNode``: a BiteMesh output model node and its surface models) onto the data
        of ``dataNode`` (labelled contours as :meth:`loadLabelledPoints` makes them, a point list, a model, or a
        list of them) with the same cells (bitemesh.fit: each surface pulled to its own contours, the fibres
        carried as cell arrays), into ``outputModelNode`` with its surface models and histogram, as :meth:`process`
        writes them (its "Radius" field: the mean edge length).

        Returns the bitemesh TemplateFit (``mesh``, ``distances`` of the data to the boundary in mm, ``rounds``,
        ``seconds``).  Raises bitemesh.InvalidInputError naming the bad node or ``pull``."""
        bitemesh = requireBitemesh()
        from bitemesh.core.mesh.quality import quality_summary
        from bitemesh.core.optimize.measures import mean_edge_length
        from bitemesh.core.parameters import QualityParameters

        nodes = self._inputNodes(dataNode)
        self._checkOutput(outputModelNode, nodes + [templateNode])
        fitted = bitemesh.fit(templateMesh(templateNode), fitSamples(nodes), pull=pull, progress=progress)
        summary = quality_summary(fitted.mesh)
        writeOutputs(fitted.mesh, mean_edge_length(fitted.mesh.points, fitted.mesh.cells), summary, None,
                     outputModelNode, QualityParameters().bins)
        writeSurfaces(fitted.mesh, outputModelNode)
        logger.info("BiteMesh fit: %d tetrahedra, data to the boundary %.2f mm on average, %d rounds, %.1f s",
                    summary.n_cells, float(fitted.distances.mean()), fitted.rounds, fitted.seconds)
        return fitted

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

