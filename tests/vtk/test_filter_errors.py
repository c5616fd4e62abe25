"""Errors in the VTK filters: a bad input or parameter is reported once, by the filter that fails, with the
parameter's name, and leaves no output downstream; an abort from a progress observer raises Cancelled; both runs
recover once repaired.

Every test here also fails if VTK printed an error or a warning (tests/vtk/conftest.py), unless it asks for the
``vtk_errors`` fixture.
"""
from __future__ import annotations

import re
from collections import Counter

import numpy as np
import pytest
from bitemesh.algorithms import BitingSampler, DelaunayTetra, PointsToImplicit, QualityFilter, SpuriousCellFilter
from bitemesh.convert import point_coordinates
from bitemesh.core.errors import Cancelled, InvalidInputError
from vtkmodules.vtkCommonCore import vtkCommand, vtkDoubleArray
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPolyData

from tests.builders import output, polydata

#: the chain's filters, in order
CHAIN = (PointsToImplicit, BitingSampler, DelaunayTetra, SpuriousCellFilter, QualityFilter)


def is_empty(dataset) -> bool:
    """No points and no cells (a vtkTable: no rows and no columns)."""
    if dataset.IsA("vtkTable"):
        return dataset.GetNumberOfRows() == 0 and dataset.GetNumberOfColumns() == 0
    return dataset.GetNumberOfPoints() == 0 and dataset.GetNumberOfCells() == 0


# ------------------------------------------------------------------------------------------------ bad input


def empty_polydata(pipeline):
    pipeline.implicit.SetInputData(vtkPolyData())


def nan_points(pipeline):
    points = point_coordinates(pipeline.source)
    points[7, 1] = np.nan
    pipeline.implicit.SetInputData(polydata(points))


def coplanar_points(pipeline):
    """Points in the plane z = 1: PointsToImplicit announces a grid, then its fit fails in RequestData."""
    points = point_coordinates(pipeline.source)
    points[:, 2] = 1.0
    pipeline.implicit.SetInputData(polydata(points))


def image_without_implicit(pipeline):
    image = vtkImageData()
    image.SetDimensions(5, 6, 7)
    scalars = vtkDoubleArray()
    scalars.SetName("Density")
    scalars.SetNumberOfTuples(5 * 6 * 7)
    scalars.Fill(1.0)
    image.GetPointData().SetScalars(scalars)
    pipeline.spurious.SetInputData(1, image)


BAD_INPUTS = {
    # case: (break the pipeline, repair it, the filter that fails, what its message must name)
    "negative radius": (lambda p: p.biting.SetRadius(-2.0), lambda p: p.biting.SetRadius(None),
                        BitingSampler, r"radius must be in \(0, inf\], got -2"),   # -1 is automatic
    "biting R finer than the grid": (lambda p: p.biting.SetCells(400000), lambda p: p.biting.SetCells(10000),
                                     BitingSampler, r"Radius \(chosen for Cells = 400000\) = .* too small for the "
                                     r"grid I .*set Radius or Cells on PointsToImplicit"),
    "threshold 2": (lambda p: p.spurious.SetThreshold(2), lambda p: p.spurious.SetThreshold(0.4),
                    SpuriousCellFilter, r"threshold must be in \[0, 1\], got 2"),
    "method bogus": (lambda p: p.implicit.SetMethod("bogus"), lambda p: p.implicit.SetMethod("mpu"),
                     PointsToImplicit, r"method must be one of 'auto', 'mpu', 'rbf', got 'bogus'"),
    "bins 0": (lambda p: p.quality.SetBins(0), lambda p: p.quality.SetBins(20), QualityFilter, r"bins must be"),
    "empty polydata": (empty_polydata, lambda p: p.implicit.SetInputData(p.source), PointsToImplicit,
                       r"input holds no points"),
    "NaN points": (nan_points, lambda p: p.implicit.SetInputData(p.source), PointsToImplicit,
                   r"points contains 1 rows with NaN"),
    "coplanar points": (coplanar_points, lambda p: p.implicit.SetInputData(p.source), PointsToImplicit,
                        r"points: all \d+ points lie in one plane"),
    "no Implicit array on port 1": (image_without_implicit,
                                    lambda p: p.spurious.SetInputConnection(1, p.implicit.GetOutputPort()),
                                    SpuriousCellFilter, r"no point array 'Implicit'"),
}


def counted(execute, name, runs):
    """``execute`` that also counts its calls in ``runs[name]``."""
    def wrapper(*arguments):
        runs.update([name])
        return execute(*arguments)
    return wrapper


@pytest.mark.parametrize("case", BAD_INPUTS)
def test_a_bad_input_is_reported_once_by_its_filter_and_leaves_no_output(small_chain, vtk_errors, case):
    spoil, repair, culprit, message = BAD_INPUTS[case]
    pipeline = small_chain
    spoil(pipeline)
    runs = Counter()
    for algorithm in pipeline.filters:  # count the real runs of each step, not the executive's requests
        algorithm.execute = counted(algorithm.execute, type(algorithm).__name__, runs)
    with pytest.raises(InvalidInputError, match=message) as raised:
        pipeline.quality.update()
    # the user gets the failing filter's own exception, from the last filter and from the failing one
    failing = next(algorithm for algorithm in pipeline.filters if type(algorithm) is culprit)
    assert failing.last_error is raised.value
    with pytest.raises(InvalidInputError, match=message):
        failing.update()
    # no half-built output: the failing filter's and every later filter's outputs are empty
    downstream = pipeline.filters[pipeline.filters.index(failing):]
    for algorithm in downstream:
        for port in range(algorithm.GetNumberOfOutputPorts()):
            assert is_empty(output(algorithm, port)), f"{type(algorithm).__name__} port {port}"
    assert runs[culprit.__name__] == 1  # a failed step is not run again for its second consumer
    # printed once, by the failing filter, not by every filter downstream
    printed = vtk_errors.messages()
    assert len(printed) == 1, vtk_errors.text()
    assert printed[0].startswith(f"ERROR: {culprit.__name__}: ") and re.search(message, printed[0])

    vtk_errors.clear()
    repair(pipeline)
    result = pipeline.quality.update()
    assert result.GetNumberOfCells() > 500 and output(pipeline.quality, 1).GetNumberOfRows() == 20
    assert vtk_errors.messages() == []


@pytest.mark.parametrize("step", range(5), ids=[cls.__name__ for cls in CHAIN])
def test_an_abort_from_a_progress_observer_raises_cancelled(small_chain, vtk_errors, step):
    pipeline = small_chain
    target = pipeline.filters[step]

    def abort(caller, event):
        caller.SetAbortExecute(1)

    observer = target.AddObserver(vtkCommand.ProgressEvent, abort)
    with pytest.raises(Cancelled, match=f"{type(target).__name__} was aborted"):
        pipeline.quality.update()
    assert is_empty(output(pipeline.quality)) and is_empty(output(pipeline.quality, 1))
    assert is_empty(output(target))
    assert len(vtk_errors.messages()) == 1, vtk_errors.text()

    target.RemoveObserver(observer)
    target.SetAbortExecute(0)  # VTK >= 9.4 keeps the flag until it is reset
    target.Modified()
    assert pipeline.quality.update().GetNumberOfCells() > 500
