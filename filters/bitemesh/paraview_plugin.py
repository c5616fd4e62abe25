"""bitemesh in ParaView: the five filters of the method and "Volume Mesh From Points", the whole method in one.

Start the GUI with ``paraview --script=<this file>`` (run as a script, this file loads itself as a plugin), or use
Tools > Manage Plugins > Load New on this file, or ``paraview.simple.LoadPlugin(path)`` in pvpython/pvbatch.  On
ParaView 5.11 with Python 3.11 (Debian 12) the last two need ``import inspect; inspect.getargspec =
inspect.getfullargspec`` first: ParaView's plugin loader imports ``inspect.getargspec``, which Python 3.11 removed.
ParaView's Python must import numpy and scipy (Debian: ``apt-get install python3-numpy python3-scipy``) and
``bitemesh`` (``PYTHONPATH=<clone>/filters``; loaded from its file, the plugin adds the folder above it itself).
Never put a virtual environment holding the pip ``vtk`` wheel on ParaView's path: a second VTK crashes it.

This is the only module of bitemesh that imports ``paraview``.  The ParaView classes are subclasses of the VTK
filters in :mod:`bitemesh.algorithms`, generated here from the parameter dataclasses of
:mod:`bitemesh.core.parameters`: each field becomes a property (its name in CamelCase) with the field's default,
its range (``IntRangeDomain``/``DoubleRangeDomain``), choices (``StringListDomain``) or free text (a string
property without a domain) and its help and unit as documentation.  Nothing about a parameter is written here a
second time.

A parameter that is None by default ("chosen automatically") cannot be None in a ParaView property: -1 stands for
it (:data:`bitemesh.core.parameters.AUTOMATIC`, below every such parameter's range), as in the VTK setters, the
Slicer panel and the CLI.  The property's help says so; the setter passes None to the filter for it.  Any other
out-of-range value reaches the filter, which refuses it with a message naming the parameter.
"""
from __future__ import annotations

import inspect

# ParaView 5.11's decorators import inspect.getargspec, which Python 3.11 removed; same signature for plain methods.
if not hasattr(inspect, "getargspec"):
    inspect.getargspec = inspect.getfullargspec

import math
import os
import sys

from xml.sax.saxutils import escape, quoteattr

#: this file; None where ParaView runs it from a string (paraview --script): then bitemesh must be on PYTHONPATH
PLUGIN_FILE = globals().get("__file__") or inspect.currentframe().f_code.co_filename
PLUGIN_FILE = os.path.abspath(PLUGIN_FILE) if os.path.isfile(PLUGIN_FILE) else None

try:
    import bitemesh
except ImportError as error:
    if error.name == "bitemesh" and PLUGIN_FILE:  # not on PYTHONPATH: the package this file belongs to
        sys.path.insert(0, os.path.dirname(os.path.dirname(PLUGIN_FILE)))
    try:
        import bitemesh
    except ImportError as error:
        hint = ("add the folder that holds bitemesh (the clone's filters/) to PYTHONPATH" if error.name == "bitemesh"
                else "ParaView's Python needs numpy and scipy; on Debian: apt-get install python3-numpy python3-scipy")
        raise ImportError(f"the bitemesh plugin cannot import {error.name} in ParaView's Python ({sys.executable}, "
                          f"Python {sys.version.split()[0]}): {hint}") from error

from paraview.util.vtkAlgorithm import smdomain, smhint, smproperty, smproxy
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

from bitemesh import algorithms
from bitemesh.algorithms.base import camel
from bitemesh.core.errors import InvalidInputError
from bitemesh.core.parameters import AUTOMATIC, is_optional

paraview_plugin_name = "bitemesh"
paraview_plugin_version = bitemesh.__version__

#: the menu (Filters > bitemesh) that holds the filters.
CATEGORY = "bitemesh"
#: IntVectorProperty holds a C int.
INT_MAX = 2**31 - 1

#: class name -> (label in ParaView, input port names, output port names); the order of the menu.
FILTERS = {
    "MeshFromPoints": ("Volume Mesh From Points", ("Input",), ("Mesh", "Surfaces")),
    "PointsToImplicit": ("Points To Implicit", ("Input",), ("Implicit",)),
    "BitingSampler": ("Biting Sampler", ("Input",), ("Nodes",)),
    "DelaunayTetra": ("Delaunay Tetra", ("Input",), ("Mesh",)),
    "SpuriousCellFilter": ("Spurious Cell Filter", ("Mesh", "Implicit"), ("Mesh",)),
    "MeshOptimizer": ("Mesh Optimizer", ("Mesh", "Implicit"), ("Mesh",)),
    "QualityFilter": ("Quality Filter", ("Input",), ("Mesh", "Histogram")),
    "FibreField": ("Fibre Field", ("Mesh", "Surfaces"), ("Mesh",)),
    "VentricularCoordinates": ("Ventricular Coordinates", ("Mesh", "Surfaces"), ("Mesh",)),
    "TemplateFit": ("Template Fit", ("Mesh", "Surfaces", "Data"), ("Mesh", "Surfaces")),
}


# -- parameters: dataclass field -> ParaView property ------------------------------------------------------------

def property_label(name: str) -> str:
    """``grid_spacing`` -> ``Grid Spacing`` (paraview.simple names the property ``GridSpacing``, as its setter)."""
    return " ".join(word.capitalize() for word in name.split("_"))


def range_text(item) -> str:
    low, high, low_open, high_open = item.metadata["range"]
    return (f"{'(' if low_open else '['}{'-inf' if low is None else low}, "
            f"{'inf' if high is None else high}{')' if high_open else ']'}")


def documentation(item) -> str:
    """The property's help: the field's help, unit, valid values and, for an optional field, its automatic value."""
    meta = item.metadata
    text = meta["help"]
    if meta.get("unit"):
        text += f" [{meta['unit']}]"
    if "choices" in meta:
        return f"{text}. One of: {', '.join(meta['choices'])}."
    if "text" in meta:
        return f"{text}."
    text += f". Valid values: {range_text(item)}"
    if is_optional(item):
        text += (f". {AUTOMATIC} means automatic (None in bitemesh: the default described above); "
                 "any other value outside the range is refused with an error naming the parameter")
    return text + "."


def domain_bounds(item):
    """(min, max) of the range domain (None where unbounded); an optional field's domain includes its automatic
    value."""
    low, high, _, _ = item.metadata["range"]
    minimum = AUTOMATIC if is_optional(item) else low
    maximum = high if high is not None and math.isfinite(high) else None
    if item.metadata["integer"]:
        minimum = None if minimum is None else max(int(minimum), -INT_MAX)
        maximum = None if maximum is None else min(int(maximum), INT_MAX)
    return minimum, maximum


def default_value(item):
    """The property's default: the field's, or the automatic value for None."""
    return AUTOMATIC if is_optional(item) else item.default


def property_decorators(item):
    """The decorators, innermost first, that declare the property of a field on the proxy class."""
    name = camel(item.name)
    common = {"name": name, "label": property_label(item.name), "command": f"Set{name}", "number_of_elements": 1,
              "default_values": default_value(item)}
    # smdomain.xml nests any element in the property: here its documentation
    decorators = [smdomain.xml(f"<Documentation>{escape(documentation(item))}</Documentation>")]
    if "text" in item.metadata:  # any string: a text field, no domain
        return decorators + [smproperty.stringvector(**common)]
    if "choices" in item.metadata:
        strings = "".join(f'<String value="{escape(choice)}"/>' for choice in item.metadata["choices"])
        decorators += [smdomain.xml(f'<StringListDomain name="list">{strings}</StringListDomain>'),
                       smproperty.stringvector(**common)]
        return decorators
    minimum, maximum = domain_bounds(item)
    bounds = {key: value for key, value in (("min", minimum), ("max", maximum)) if value is not None}
    if item.metadata["integer"]:
        decorators += [smdomain.intrange(**bounds), smproperty.intvector(**common)]
    else:
        decorators += [smdomain.doublerange(**bounds), smproperty.doublevector(**common)]
    return decorators


def property_setter(item, vtk_setter):
    """``Set<Name>(value)`` for ParaView: a whole float becomes an int, then the VTK filter's setter (which takes
    the automatic value for None)."""
    integer = item.metadata.get("integer", False)

    def set_value(self, value):
        if integer and isinstance(value, float) and value.is_integer():
            value = int(value)
        vtk_setter(self, value)

    set_value.__name__ = f"Set{camel(item.name)}"
    set_value.__doc__ = documentation(item)
    return set_value


# -- filters -----------------------------------------------------------------------------------------------------

class LabelMapsNeedSimpleITK:
    """Mixin for PointsToImplicit: a label map input needs SimpleITK, which Debian does not package."""

    def source_of(self, data):
        if isinstance(data, vtkImageData):   # before any work on the label map: ParaView reports the real error
            require_simpleitk()
        return super().source_of(data)


def require_simpleitk() -> None:
    """Refuse a label map where ParaView's Python has no SimpleITK, saying how to get one."""
    try:
        import SimpleITK  # noqa: F401
    except ImportError:
        raise InvalidInputError(
            "a label map (vtkImageData) input needs SimpleITK, which ParaView's Python cannot import "
            "(Debian has no python3-simpleitk): install a SimpleITK for that Python version in a folder of its own "
            "(pip install --target DIR SimpleITK) and add DIR to PYTHONPATH, mesh the label map with the "
            "bitemesh command or the 3D Slicer module, or connect scattered points") from None


def input_data_types(base) -> list:
    """The data type each input port of a VTK filter requires (from its FillInputPortInformation)."""
    algorithm = base()
    return [algorithm.GetInputPortInformation(port).Get(vtkAlgorithm.INPUT_REQUIRED_DATA_TYPE())
            for port in range(algorithm.GetNumberOfInputPorts())]


def paraview_filter(class_name: str):
    """The ParaView proxy class of a bitemesh VTK filter: its parameters as properties, its inputs and outputs."""
    label, inputs, outputs = FILTERS[class_name]
    base = getattr(algorithms, class_name)
    items = list(base.parameter_fields)
    namespace = {"__module__": __name__, "__qualname__": class_name, "__doc__": base.__doc__}
    for item in items:
        namespace[f"Set{camel(item.name)}"] = property_setter(item, getattr(base, f"Set{camel(item.name)}"))
    bases = (*((LabelMapsNeedSimpleITK,) if hasattr(base, "source_of") else ()), base)
    cls = type(class_name, bases, namespace)

    decorators = []  # innermost first; properties keep this order in the panel
    for port, (port_name, data_type) in enumerate(zip(inputs, input_data_types(base))):
        decorators += [smdomain.datatype(dataTypes=[data_type], composite_data_supported=False),
                       smproperty.input(name=port_name, port_index=port)]
    for item in items:
        decorators += property_decorators(item)
    summary = (base.__doc__ or label).strip().split("\n")[0]
    ports = "".join(f'<OutputPort name="{name}" index="{index}"/>' for index, name in enumerate(outputs))
    decorators += [smproperty.xml(f'<Documentation short_help={quoteattr(summary)} long_help={quoteattr(summary)}>'
                                  f"{escape(inspect.cleandoc(base.__doc__ or label))}</Documentation>{ports}"),
                   smhint.xml(f'<ShowInMenu category="{CATEGORY}"/>'),
                   smproxy.filter(name=f"Bitemesh{class_name}", label=label)]
    for decorate in decorators:
        cls = decorate(cls)
    return cls


for _name in FILTERS:  # ParaView finds a proxy class as an attribute of this module named like the class
    globals()[_name] = paraview_filter(_name)
del _name


if __name__ == "__main__":  # paraview --script=paraview_plugin.py (ParaView runs it from a string: no __file__)
    from paraview.simple import LoadPlugin

    LoadPlugin(PLUGIN_FILE or os.path.join(os.path.dirname(bitemesh.__file__), "paraview_plugin.py"))
