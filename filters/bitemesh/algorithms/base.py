"""What the five filters share: VTK-style parameters generated from the core's dataclasses, errors that keep
their message, progress and abort.

Facts this relies on (verified on VTK 9.2 and 9.7): an exception escaping ``RequestData`` reaches the user only as
"Failure when calling method ProcessRequest"; a Python algorithm has no ``GetOutput()``.
"""
from __future__ import annotations

import contextlib
import logging
import warnings
from dataclasses import fields

from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonCore import vtkCommand, vtkOutputWindow
from vtkmodules.vtkCommonDataModel import vtkDataObject
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

from ..core.errors import BitemeshError, BitemeshWarning, Cancelled
from ..core.parameters import AUTOMATIC, is_optional
from ..options import Options


def camel(name: str) -> str:
    """``grid_spacing`` -> ``GridSpacing``."""
    return "".join(part.capitalize() for part in name.split("_"))


def with_parameters(*specs):
    """Class decorator: a ``Set<Name>``/``Get<Name>`` pair per field of the dataclasses, VTK style.

    Each spec is a parameter dataclass (all its fields) or ``(dataclass, names)`` (those fields only).  A setter
    calls ``Modified()`` only when the value changes; values are checked (ranges of the dataclass) when the filter
    runs, so that a bad one surfaces through ``update()`` with the parameter's name.
    """
    def decorate(cls):
        cls.parameter_classes = tuple(spec[0] if isinstance(spec, tuple) else spec for spec in specs)
        cls.parameter_fields = tuple(item for spec in specs for item in fields(spec[0] if isinstance(spec, tuple)
                                                                              else spec)
                                     if not isinstance(spec, tuple) or item.name in spec[1])
        for item in cls.parameter_fields:
            setattr(cls, f"Set{camel(item.name)}", _setter(item.name, AUTOMATIC if is_optional(item) else None))
            setattr(cls, f"Get{camel(item.name)}", _getter(item.name))
        return cls
    return decorate


def _setter(name, automatic):
    """``Set<Name>(value)``; None or ``automatic`` (the number a GUI property gives for None) is automatic."""
    def set_value(self, value):
        if automatic is not None and value is not None and value == automatic:
            value = None
        if self._values[name] != value:
            self._values[name] = value
            self.Modified()
    set_value.__doc__ = f"Set {name} (see the core's parameter dataclass for its unit and range)."
    return set_value


def _getter(name):
    def get_value(self):
        return self._values[name]
    get_value.__doc__ = f"The current {name}."
    return get_value


class BitemeshAlgorithm(VTKPythonAlgorithmBase):
    """Base of the bitemesh filters: subclasses implement ``execute(request, inInfo, outInfo)``."""

    parameter_classes = ()
    parameter_fields = ()

    def __init__(self, **ports):
        VTKPythonAlgorithmBase.__init__(self, **ports)
        self._values = {item.name: item.default for item in self.parameter_fields}
        self.last_error = None
        self._failed_run = None  # what the last failed run saw: (filter MTime, input data MTimes)

    def SetInputData(self, *arguments):
        """``SetInputData(data)`` or ``SetInputData(port, data)``, as VTK's typed algorithms offer."""
        port, data = (0, *arguments) if len(arguments) == 1 else arguments
        self.SetInputDataObject(port, data)

    def parameters(self, dataclass):
        """The checked parameter dataclass from the current values, its other fields at their defaults (raises
        InvalidInputError naming a bad one)."""
        return dataclass(**{f.name: self._values[f.name] for f in fields(dataclass) if f.name in self._values})

    def options(self) -> Options:
        """The filter's parameters as the front door's options (:func:`bitemesh.mesh`), the others at their
        defaults."""
        return Options(**self._values)

    def progress(self, fraction: float, message: str = "") -> None:
        """The core's progress callback: VTK progress, and an abort request becomes Cancelled."""
        self.SetProgressText(message)
        self.UpdateProgress(fraction)
        self.check_abort()

    def check_abort(self) -> None:
        """Raise Cancelled if an observer asked this filter to abort (``SetAbortExecute(1)``)."""
        if self.GetAbortExecute():
            raise Cancelled(f"{type(self).__name__} was aborted")

    def RequestUpdateExtent(self, request, inInfo, outInfo):
        """Every step needs its image inputs whole: ask for their whole extent.

        VTK's default copies the output's update extent to image inputs; a label map's extent is not that of the
        padded grid PointsToImplicit announces, and an image on SpuriousCellFilter's port 1 may differ from the
        grid that was there before, so the default request falls outside the input and VTK reports errors.
        """
        whole = vtkStreamingDemandDrivenPipeline.WHOLE_EXTENT()
        update = vtkStreamingDemandDrivenPipeline.UPDATE_EXTENT()
        for port in range(self.GetNumberOfInputPorts()):
            for connection in range(inInfo[port].GetNumberOfInformationObjects()):
                info = inInfo[port].GetInformationObject(connection)
                if info.Has(whole):
                    info.Set(update, info.Get(whole), 6)
        return 1

    def RequestData(self, request, inInfo, outInfo):
        run = self.run_key(inInfo)
        if self.last_error is not None and run == self._failed_run:
            # the executive asks again for the same failed run (an image output with two consumers, such as
            # PointsToImplicit's, looks out of date when empty): it has been reported, do not run it again
            self.clear_outputs(outInfo)
            return 1
        self.last_error = self._failed_run = None
        if self.upstream_error() is not None:  # reported where it happened; pass on an empty output quietly
            self.clear_outputs(outInfo)
            return 1
        try:
            with self.passing_on_notes():
                self.check_abort()  # an abort asked at the executive's first progress event, or left set
                self.execute(request, inInfo, outInfo)
                self.check_abort()  # an abort asked while a step that reports no progress ran
        except Exception as error:  # noqa: BLE001 - every error must reach the user with its message
            self.last_error = error
            self._failed_run = run  # rerunning needs a change: a parameter, an input, Modified(), SetAbortExecute(0)
            self.clear_outputs(outInfo)
            self.report_error(error)
        return 1

    @contextlib.contextmanager
    def passing_on_notes(self):
        """While a run executes, what the core says to the user goes to VTK's output window: the "bitemesh"
        logger's notes as text (points dropped, columns read), a BitemeshWarning (a mesh kept although it missed a
        bound it was allowed to miss) as a warning; other warnings go on as they came."""
        name = type(self).__name__
        window = vtkOutputWindow.GetInstance()

        class Notes(logging.Handler):
            def emit(self, record):
                window.DisplayText(f"{name}: note: {record.getMessage()}\n")

        handler = Notes(logging.INFO)
        logger = logging.getLogger("bitemesh")
        previous = logger.level
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", BitemeshWarning)
                yield
        finally:
            logger.removeHandler(handler)
            logger.setLevel(previous)
            for warning in caught:
                if issubclass(warning.category, BitemeshWarning):
                    if self.HasObserver(vtkCommand.WarningEvent):
                        self.InvokeEvent(vtkCommand.WarningEvent, f"{name}: {warning.message}")
                    else:
                        window.DisplayWarningText(f"Warning: {name}: {warning.message}\n")
                else:
                    warnings.warn_explicit(warning.message, warning.category, warning.filename, warning.lineno)

    def run_key(self, inInfo):
        """What a run depends on: this filter's MTime and the MTime of every input data object."""
        inputs = []
        for port in range(self.GetNumberOfInputPorts()):
            for connection in range(inInfo[port].GetNumberOfInformationObjects()):
                data = inInfo[port].GetInformationObject(connection).Get(vtkDataObject.DATA_OBJECT())
                inputs.append(None if data is None else data.GetMTime())
        return self.GetMTime(), tuple(inputs)

    def clear_outputs(self, outInfo) -> None:
        """Leave no half-built output behind."""
        for port in range(self.GetNumberOfOutputPorts()):
            output = outInfo.GetInformationObject(port).Get(vtkDataObject.DATA_OBJECT())
            if output is not None:
                output.Initialize()

    def report_error(self, error: Exception) -> None:
        """Send the error's message to VTK's error output, as vtkErrorMacro does (observers first)."""
        kind = "" if isinstance(error, BitemeshError) else f"{type(error).__name__}: "
        message = f"{type(self).__name__}: {kind}{error}"
        if isinstance(error, Cancelled):
            vtkOutputWindow.GetInstance().DisplayWarningText(f"Warning: {type(self).__name__}: cancelled\n")
            return
        if self.HasObserver(vtkCommand.ErrorEvent):
            self.InvokeEvent(vtkCommand.ErrorEvent, message)
        else:
            vtkOutputWindow.GetInstance().DisplayErrorText(f"ERROR: {message}\n")

    def upstream_error(self):
        """The first error of this filter's upstream chain (the root cause), or None.

        The chain is walked through every algorithm, not only bitemesh's: a GUI application puts a post filter after
        each output port, and a VTK script may put any filter between two of ours; without this, every filter below
        one that failed would report an empty input too.
        """
        seen = set()

        def first_error(algorithm):
            for port in range(algorithm.GetNumberOfInputPorts()):
                for connection in range(algorithm.GetNumberOfInputConnections(port)):
                    producer = algorithm.GetInputAlgorithm(port, connection)
                    if producer is None or producer.__this__ in seen:
                        continue
                    seen.add(producer.__this__)
                    error = first_error(producer) or getattr(producer, "last_error", None)
                    if error is not None:
                        return error
            return None

        return first_error(self)

    def update(self, port: int = 0):
        """Update and return the output of ``port``; raise the error that stopped this filter or one upstream."""
        self.Update(port)
        error = self.upstream_error() or self.last_error
        if error is not None:
            raise error
        return self.GetOutputDataObject(port)
