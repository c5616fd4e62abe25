"""A parameter change reruns only the filters downstream of it, and a setter calls Modified() only when the value
changes.

Every test here also fails if VTK printed an error or a warning (tests/vtk/conftest.py), unless it asks for the
``vtk_errors`` fixture.
"""
from __future__ import annotations

from collections import Counter

import pytest
from bitemesh.algorithms import (BitingSampler, DelaunayTetra, MeshFromPoints, PointsToImplicit, QualityFilter,
                                 SpuriousCellFilter)
from vtkmodules.vtkCommonCore import vtkCommand

from bitemesh.convert import plan_of

from tests.builders import output

FILTERS = (PointsToImplicit, BitingSampler, DelaunayTetra, SpuriousCellFilter, QualityFilter, MeshFromPoints)


def count_runs(filters) -> Counter:
    """A Counter of RequestData runs per filter class name, kept up to date by StartEvent observers."""
    runs = Counter()
    for algorithm in filters:
        algorithm.AddObserver(vtkCommand.StartEvent, lambda caller, event: runs.update([type(caller).__name__]))
    return runs


# ------------------------------------------------------------------------------------------------ reruns


def test_a_parameter_change_reruns_only_what_is_downstream(small_chain):
    pipeline = small_chain
    runs = count_runs(pipeline.filters)
    first = pipeline.quality.update().GetNumberOfCells()
    assert runs == Counter(PointsToImplicit=1, BitingSampler=1, DelaunayTetra=1, SpuriousCellFilter=1,
                           QualityFilter=1)
    runs.clear()
    pipeline.quality.update()
    assert runs == Counter()  # nothing changed, nothing runs

    pipeline.spurious.SetThreshold(0.3)
    pipeline.quality.update()
    assert runs == Counter(SpuriousCellFilter=1, QualityFilter=1)
    runs.clear()

    pipeline.quality.SetBins(10)
    assert pipeline.quality.update().GetNumberOfCells() == output(pipeline.spurious).GetNumberOfCells()
    assert output(pipeline.quality, 1).GetNumberOfRows() == 10
    assert runs == Counter(QualityFilter=1)
    runs.clear()

    radius = plan_of(output(pipeline.biting))["Radius"]
    pipeline.biting.SetRadius(0.75 * radius)
    smaller = pipeline.quality.update().GetNumberOfCells()
    assert smaller > 1.5 * first  # (1 / 0.75)^3 = 2.4 times as many cells, roughly
    assert plan_of(output(pipeline.biting))["Radius"] == 0.75 * radius
    assert runs == Counter(BitingSampler=1, DelaunayTetra=1, SpuriousCellFilter=1, QualityFilter=1)
    runs.clear()

    pipeline.implicit.SetGridSpacing(0.05)
    pipeline.quality.update()
    assert runs == Counter(PointsToImplicit=1, BitingSampler=1, DelaunayTetra=1, SpuriousCellFilter=1,
                           QualityFilter=1)


def other_value(item, value):
    """A valid value of the parameter ``item`` different from ``value``."""
    if "choices" in item.metadata:
        return next(choice for choice in item.metadata["choices"] if choice != value)
    if "text" in item.metadata:
        return value + " - A"
    return 1.5 if value is None else value + 1


@pytest.mark.parametrize("algorithm", FILTERS, ids=lambda cls: cls.__name__)
def test_setters_call_modified_only_on_a_change(algorithm):
    instance = algorithm()
    names = list(algorithm.parameter_fields)
    assert names or algorithm is DelaunayTetra
    for item in names:
        name = "".join(part.capitalize() for part in item.name.split("_"))
        setter, getter = getattr(instance, f"Set{name}"), getattr(instance, f"Get{name}")
        assert getter() == item.default
        before = instance.GetMTime()
        setter(item.default)
        assert instance.GetMTime() == before, f"Set{name} of the same value called Modified()"
        setter(other_value(item, item.default))
        assert instance.GetMTime() > before, f"Set{name} of a new value did not call Modified()"
        assert getter() == other_value(item, item.default)
