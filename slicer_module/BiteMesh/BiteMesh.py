"""BiteMesh: tetrahedral meshes from points, contours, surface models or segments, in 3D Slicer.

This file holds the module, its panel and its self-test.  All the work is done by ``BiteMeshLib.logic.BiteMeshLogic``,
which needs no GUI (it is tested headless against the MRML classes of slicer-core): call
``BiteMeshLogic().process(inputNode, outputModelNode, **parameters)`` from the Python console or a script.
"""
import os
import sys
from typing import Annotated, Union

import qt
import slicer
import vtk
from slicer.ScriptedLoadableModule import (
    ScriptedLoadableModule,
    ScriptedLoadableModuleTest,
    ScriptedLoadableModuleWidget,
)
from slicer.util import VTKObservationMixin

try:
    from slicer.i18n import tr as _
except ImportError:  # Slicer before 5.4
    def _(text):
        return text

_moduleDir = os.path.dirname(os.path.abspath(__file__))
if _moduleDir not in sys.path:
    sys.path.insert(0, _moduleDir)

from BiteMeshLib.help import HELP_TEXT  # noqa: E402
from BiteMeshLib.logic import BiteMeshLogic  # noqa: E402

#: QSpinBox holds a 32-bit int: integer ranges of the core are clipped to it in the panel (not in the logic).
_INT_MAX = 2**31 - 1


#
# BiteMesh
#

class BiteMesh(ScriptedLoadableModule):
    """The module's description (see the ScriptedLoadableModule base class in Slicer)."""

    def __init__(self, parent):
        ScriptedLoadableModule.__init__(self, parent)
        self.parent.title = _("BiteMesh")
        self.parent.categories = [_("Surface Models")]
        self.parent.dependencies = ["Markups", "Segmentations", "Plots"]
        self.parent.contributors = ["The bitemesh authors"]
        self.parent.helpText = _(HELP_TEXT)

        self.parent.acknowledgementText = _("""
bitemesh implements M. Schaerer et al., Volumetric mesh construction from scattered prior data.
""")


#
# The parameter node: one field per panel parameter, ranges from bitemesh's parameter dataclasses
#

_parameterNodeClass = None


def _annotated(spec):
    """The parameterNodeWrapper type of a panel parameter, with the core dataclass's range or choices."""
    from slicer.parameterNodeWrapper import Choice, Minimum, WithinRange
    if spec.choices is not None:
        return Annotated[str, Choice(list(spec.choices))]
    if spec.kind in (str, bool):   # free text, a switch
        return spec.kind
    high, low = spec.high, spec.low if spec.automatic is None else min(spec.low, spec.automatic)
    if spec.kind is int:
        high = _INT_MAX if high is None else min(high, _INT_MAX)
    if high is None:
        return Annotated[spec.kind, Minimum(low)]
    return Annotated[spec.kind, WithinRange(low, high)]


def parameterNodeClass():
    """The parameterNodeWrapper class of the module, built from the core's dataclasses on first use.

    It is built lazily because reading the dataclasses imports bitemesh, which needs scipy: the module must load,
    and offer to install scipy, even where scipy is still missing.
    """
    global _parameterNodeClass
    if _parameterNodeClass is None:
        from slicer import (
            vtkMRMLMarkupsClosedCurveNode,
            vtkMRMLMarkupsFiducialNode,
            vtkMRMLModelNode,
            vtkMRMLSegmentationNode,
        )
        from slicer.parameterNodeWrapper import parameterNodeWrapper
        annotations = {
            # None must be a member of a Union of nodes, or the wrapper cannot store "no node selected"
            "inputNode": Union[vtkMRMLMarkupsFiducialNode, vtkMRMLMarkupsClosedCurveNode, vtkMRMLModelNode,
                               vtkMRMLSegmentationNode, None],
            "contours": list[vtkMRMLMarkupsClosedCurveNode],
            "segmentId": str,
            "outputModel": vtkMRMLModelNode,
            "templateModel": Union[vtkMRMLModelNode, None],
        }
        namespace = {"segmentId": ""}
        for spec in BiteMeshLogic.parameterSpecs() + BiteMeshLogic.fitParameterSpecs():
            annotations[spec.name] = _annotated(spec)
            namespace[spec.name] = spec.default
        namespace.update(__annotations__=annotations, __module__=__name__,
                         __doc__="The parameters of BiteMesh (radius 0 etc. = automatic).")
        _parameterNodeClass = parameterNodeWrapper(type("BiteMeshParameterNode", (), namespace))
    return _parameterNodeClass


#
# BiteMeshWidget
#

class BiteMeshWidget(ScriptedLoadableModuleWidget, VTKObservationMixin):
    """The panel: input, parameters (bound to the parameter node), Apply with progress and Cancel."""

    def __init__(self, parent=None):
        ScriptedLoadableModuleWidget.__init__(self, parent)
        VTKObservationMixin.__init__(self)
        self.logic = None
        self._parameterNode = None
        self._parameterNodeGuiTag = None
        self._lastInputNode = None
        self._updatingExtras = False
        self._running = False
        self._cancelRequested = False

    def setup(self):
        ScriptedLoadableModuleWidget.setup(self)
        uiWidget = slicer.util.loadUI(self.resourcePath("UI/BiteMesh.ui"))
        self.layout.addWidget(uiWidget)
        self.ui = slicer.util.childWidgetVariables(uiWidget)
        uiWidget.setMRMLScene(slicer.mrmlScene)
        self.logic = BiteMeshLogic()

        self.addObserver(slicer.mrmlScene, slicer.mrmlScene.StartCloseEvent, self.onSceneStartClose)
        self.addObserver(slicer.mrmlScene, slicer.mrmlScene.EndCloseEvent, self.onSceneEndClose)
        self.ui.applyButton.connect("clicked(bool)", self.onApplyButton)
        self.ui.fitButton.connect("clicked(bool)", self.onFitButton)
        self.ui.cancelButton.connect("clicked(bool)", self.onCancelButton)
        self.ui.loadLabelledPointsButton.connect("clicked(bool)", self.onLoadLabelledPoints)
        self.ui.contoursSelector.connect("checkedNodesChanged()", self.onContoursChanged)
        self.ui.segmentComboBox.connect("currentIndexChanged(int)", self.onSegmentChanged)

        if self._ensureRequirements():
            self._setToolTips()
            self.initializeParameterNode()

    def cleanup(self):
        self.removeObservers()

    def enter(self):
        if self.logic is not None and self._ensureRequirements():
            self.initializeParameterNode()

    def exit(self):
        if self._parameterNode:
            self._parameterNode.disconnectGui(self._parameterNodeGuiTag)
            self._parameterNodeGuiTag = None
            self.removeObserver(self._parameterNode, vtk.vtkCommand.ModifiedEvent, self._onParameterNodeModified)

    def onSceneStartClose(self, caller, event):
        self.setParameterNode(None)

    def onSceneEndClose(self, caller, event):
        if self.parent.isEntered:
            self.initializeParameterNode()

    # --- requirements ------------------------------------------------------------------------------------------------

    def _ensureRequirements(self) -> bool:
        """On first use, install what bitemesh needs and Slicer lacks (scipy, numba; never VTK or SimpleITK)."""
        missing = self.logic.missingRequirements()
        if not missing:
            return True
        question = _("BiteMesh needs {packages}, which this Slicer lacks. Install it now with pip? (Then its "
                     "kernels compile once, so that the first mesh does not wait: a few minutes in all.)").format(
            packages=", ".join(missing))
        if slicer.util.confirmOkCancelDisplay(question):
            try:
                with slicer.util.tryWithErrorDisplay(_("Installing the Python packages BiteMesh needs failed."),
                                                     waitCursor=True):
                    self.logic.installRequirements(pipInstall=slicer.util.pip_install)
            except Exception:  # noqa: BLE001 - already shown to the user by tryWithErrorDisplay
                pass
        missing = self.logic.missingRequirements()
        if missing:
            self.ui.statusLabel.text = _("BiteMesh needs {packages}: reopen the module to install it.").format(
                packages=", ".join(missing))
            self.ui.applyButton.enabled = self.ui.fitButton.enabled = False
            self.ui.loadLabelledPointsButton.enabled = False
            return False
        return True

    def _setToolTips(self):
        """Each parameter's help and unit, from the core's dataclasses."""
        specs = {spec.name: spec for spec in self.logic.parameterSpecs() + self.logic.fitParameterSpecs()}
        for child in vars(self.ui).values():
            name = child.property("SlicerParameterName") if hasattr(child, "property") else None
            if name in specs:
                unit = f" ({specs[name].unit})" if specs[name].unit else ""
                child.toolTip = specs[name].help + unit

    # --- parameter node ----------------------------------------------------------------------------------------------

    def initializeParameterNode(self):
        self.setParameterNode(parameterNodeClass()(self.logic.getParameterNode()))
        if not self._parameterNode.inputNode:
            for className in ("vtkMRMLMarkupsFiducialNode", "vtkMRMLSegmentationNode"):
                node = slicer.mrmlScene.GetFirstNodeByClass(className)
                if node:
                    self._parameterNode.inputNode = node
                    break

    def setParameterNode(self, inputParameterNode):
        if self._parameterNode:
            self._parameterNode.disconnectGui(self._parameterNodeGuiTag)
            self.removeObserver(self._parameterNode, vtk.vtkCommand.ModifiedEvent, self._onParameterNodeModified)
        self._parameterNode = inputParameterNode
        if self._parameterNode:
            self._parameterNodeGuiTag = self._parameterNode.connectGui(self.ui)
            self.addObserver(self._parameterNode, vtk.vtkCommand.ModifiedEvent, self._onParameterNodeModified)
        self._onParameterNodeModified()

    def _onParameterNodeModified(self, caller=None, event=None):
        node = self._parameterNode
        if node is None:
            self.ui.applyButton.enabled = self.ui.fitButton.enabled = False
            return
        inputNode = node.inputNode
        if inputNode is not self._lastInputNode:
            self._lastInputNode = inputNode
            if inputNode is not None:   # sparse contours want the RBF, dense points MPU
                method = "rbf" if inputNode.IsA("vtkMRMLMarkupsClosedCurveNode") else "mpu"
                if node.method != method:
                    node.method = method
        self._updateExtras()
        canApply = inputNode is not None and not self._running
        self.ui.applyButton.enabled = canApply
        self.ui.fitButton.enabled = canApply and node.templateModel is not None
        self.ui.applyButton.toolTip = _("Mesh the input into the output model.") if canApply else \
            _("Select an input: points, closed curves, a model or a segmentation.")

    def _updateExtras(self):
        """The widgets bound by hand: the extra contours and the segment (shown only where they apply)."""
        if self._updatingExtras:
            return
        self._updatingExtras = True
        try:
            node = self._parameterNode
            inputNode = node.inputNode
            isCurve = inputNode is not None and inputNode.IsA("vtkMRMLMarkupsClosedCurveNode")
            isSegmentation = inputNode is not None and inputNode.IsA("vtkMRMLSegmentationNode")
            for widget in (self.ui.contoursLabel, self.ui.contoursSelector):
                widget.visible = isCurve
            for widget in (self.ui.segmentLabel, self.ui.segmentComboBox):
                widget.visible = isSegmentation
            checked = {n.GetID() for n in node.contours if n is not None}
            for index in range(self.ui.contoursSelector.nodeCount()):
                curve = self.ui.contoursSelector.nodeFromIndex(index)
                state = qt.Qt.Checked if curve.GetID() in checked else qt.Qt.Unchecked
                if self.ui.contoursSelector.checkState(curve) != state:
                    self.ui.contoursSelector.setCheckState(curve, state)
            combo = self.ui.segmentComboBox
            segments = []
            if isSegmentation:
                segmentation = inputNode.GetSegmentation()
                segments = [(segmentation.GetNthSegmentID(i), segmentation.GetNthSegment(i).GetName())
                            for i in range(segmentation.GetNumberOfSegments())]
            if [(combo.itemData(i), combo.itemText(i)) for i in range(combo.count)] != segments:
                combo.clear()
                for segmentId, name in segments:
                    combo.addItem(name, segmentId)
            index = combo.findData(node.segmentId) if node.segmentId else 0
            if combo.count and combo.currentIndex != max(index, 0):
                combo.currentIndex = max(index, 0)
        finally:
            self._updatingExtras = False

    def onLoadLabelledPoints(self):
        """Read a labelled points file into a model node (the logic's loadLabelledPoints) and make it the input."""
        if self._parameterNode is None:
            return
        from bitemesh.io import LABELLED_EXTENSIONS
        patterns = " ".join(f"*{extension}" for extension in LABELLED_EXTENSIONS)
        path = qt.QFileDialog.getOpenFileName(slicer.util.mainWindow(), _("Load labelled points"), "",
                                              _("Labelled points") + f" ({patterns});;" + _("All files") + " (*)")
        if not path:
            return
        with slicer.util.tryWithErrorDisplay(_("BiteMesh could not read the labelled points."), waitCursor=True):
            self._parameterNode.inputNode = self.logic.loadLabelledPoints(path)

    def onContoursChanged(self):
        if self._parameterNode is not None and not self._updatingExtras:
            self._parameterNode.contours = list(self.ui.contoursSelector.checkedNodes())

    def onSegmentChanged(self, index):
        if self._parameterNode is not None and not self._updatingExtras and index >= 0:
            self._parameterNode.segmentId = self.ui.segmentComboBox.itemData(index) or ""

    # --- apply, progress, cancel -------------------------------------------------------------------------------------

    def _inputs(self):
        """The input node, with the further closed curves when it is a closed curve."""
        node = self._parameterNode
        inputs = node.inputNode
        if inputs is not None and inputs.IsA("vtkMRMLMarkupsClosedCurveNode"):
            inputs = [inputs] + [curve for curve in node.contours if curve is not None and curve is not inputs]
        return inputs

    def _run(self, failure, work):
        """``work(outputModel)`` with progress and Cancel, its errors shown under ``failure``."""
        if self._running or self._parameterNode is None:
            return
        from bitemesh.core.errors import Cancelled
        node = self._parameterNode
        self._cancelRequested = False
        self._setRunning(True)
        try:
            with slicer.util.tryWithErrorDisplay(failure, waitCursor=True):
                if node.outputModel is None:
                    node.outputModel = slicer.mrmlScene.AddNewNodeByClass("vtkMRMLModelNode", "BiteMesh")
                try:
                    work(node.outputModel)
                except Cancelled:
                    self.ui.statusLabel.text = _("Cancelled: the output was left as it was.")
        finally:
            self._setRunning(False)

    def onApplyButton(self):
        node = self._parameterNode

        def work(output):
            values = {spec.name: getattr(node, spec.name) for spec in self.logic.parameterSpecs()}
            self._showResult(self.logic.process(self._inputs(), output, segmentId=node.segmentId or None,
                                                progress=self._onProgress, **self.logic.coreParameters(values)))

        self._run(_("BiteMesh could not mesh the input."), work)

    def onFitButton(self):
        """The elastic template: the template model moved onto the input's points, into the output model."""
        node = self._parameterNode

        def work(output):
            fitted = self.logic.fitTemplate(node.templateModel, self._inputs(), output, pull=node.pull,
                                            progress=self._onProgress)
            self.ui.progressBar.value = 100
            self.ui.statusLabel.text = _("Fitted: the template's {cells} tetrahedra moved; the data {mean:.2f} mm from "
                                         "its boundary on average; {rounds} rounds, {seconds:.1f} s").format(
                cells=len(fitted.mesh.cells), mean=float(fitted.distances.mean()), rounds=fitted.rounds,
                seconds=fitted.seconds)

        self._run(_("BiteMesh could not fit the template."), work)

    def onCancelButton(self):
        self._cancelRequested = True
        self.ui.statusLabel.text = _("Cancelling...")

    def _onProgress(self, fraction, message):
        """The logic's progress callback: show it, let Qt handle the Cancel button, stop when asked."""
        from bitemesh.core.errors import Cancelled
        self.ui.progressBar.value = round(100 * fraction)
        if message and not self._cancelRequested:
            self.ui.statusLabel.text = message
        slicer.app.processEvents()
        if self._cancelRequested:
            raise Cancelled(_("cancelled by the user"))

    def _setRunning(self, running):
        self._running = running
        self.ui.cancelButton.enabled = running
        ready = not running and self._parameterNode is not None and self._parameterNode.inputNode is not None
        self.ui.applyButton.enabled = ready
        self.ui.fitButton.enabled = ready and self._parameterNode.templateModel is not None
        if running:
            self.ui.progressBar.value = 0
            self.ui.statusLabel.text = ""

    def _showResult(self, result):
        summary = result.summary
        self.ui.progressBar.value = 100
        text = _(
            "{cells} tetrahedra, {points} nodes, R = {radius:.3g} mm; radius ratio mean {mean:.3f}, "
            "min {low:.3f}; {seconds:.1f} s").format(cells=summary.n_cells, points=summary.n_points,
                                                     radius=result.radius, mean=summary.q_mean, low=summary.q_min,
                                                     seconds=result.seconds.get("total", 0.0))
        if "fibres" in result.seconds:
            text += _("; fibres added (coloured by helix angle)")
        if "coordinates" in result.seconds:
            text += _("; ventricular coordinates (point arrays) and AHA segments (cell array AHA) added")
        self.ui.statusLabel.text = text
        plots = getattr(slicer.modules, "plots", None)
        if plots is not None:
            plots.logic().ShowChartInLayout(result.chartNode)


#
# BiteMeshTest
#

class BiteMeshTest(ScriptedLoadableModuleTest):
    """Self-test (Reload and Test): the cases of BiteMeshLib.selftest on Slicer's scene."""

    def setUp(self):
        slicer.mrmlScene.Clear()

    def runTest(self):
        self.setUp()
        self.test_BiteMeshPoints()
        self.setUp()
        self.test_BiteMeshSegmentation()
        self.setUp()
        self.test_BiteMeshErrors()

    def _run(self, case, what):
        from BiteMeshLib import selftest
        self.delayDisplay(f"Meshing {what}")
        getattr(selftest, case)(slicer.mrmlScene, BiteMeshLogic())
        self.delayDisplay("Test passed")

    def test_BiteMeshPoints(self):
        self._run("runPointsCase", "points on a sphere")

    def test_BiteMeshSegmentation(self):
        self._run("runSegmentationCase", "a ball segment")

    def test_BiteMeshErrors(self):
        self._run("runErrorsCase", "bad input")
