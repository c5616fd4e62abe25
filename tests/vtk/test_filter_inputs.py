"""No VTK filter modifies its input: geometry, topology, every array and the MTime stay as they were.

Every test here also fails if VTK printed an error or a warning (tests/vtk/conftest.py), unless it asks for the
``vtk_errors`` fixture.
"""
from __future__ import annotations


import numpy as np
import pytest
from bitemesh.algorithms import (BitingSampler, DelaunayTetra, MeshFromPoints, PointsToImplicit, QualityFilter,
                                 SpuriousCellFilter)
from bitemesh.convert import cell_types, point_coordinates
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkDoubleArray
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPointSet, vtkPolyData, vtkUnstructuredGrid

from tests.builders import ball_label_map, chain, output, polydata

def snapshot(dataset) -> dict:
    """Copies of everything a filter could change in its input: geometry, topology, every array, the MTime."""
    state = {"class": dataset.GetClassName(), "mtime": dataset.GetMTime(),
             "n": (dataset.GetNumberOfPoints(), dataset.GetNumberOfCells())}
    if isinstance(dataset, vtkPointSet):
        state["points"] = point_coordinates(dataset)
    if isinstance(dataset, vtkImageData):
        state["geometry"] = (dataset.GetOrigin(), dataset.GetSpacing(), dataset.GetExtent())
    if isinstance(dataset, vtkUnstructuredGrid) and dataset.GetNumberOfCells():
        cells = dataset.GetCells()
        state["topology"] = [vtk_to_numpy(cells.GetOffsetsArray()).copy(),
                             vtk_to_numpy(cells.GetConnectivityArray()).copy(), cell_types(dataset).copy()]
    if isinstance(dataset, vtkPolyData):
        verts = dataset.GetVerts()
        state["topology"] = [vtk_to_numpy(verts.GetOffsetsArray()).copy(),
                             vtk_to_numpy(verts.GetConnectivityArray()).copy()]
    for kind, attributes in (("point", dataset.GetPointData()), ("cell", dataset.GetCellData()),
                             ("field", dataset.GetFieldData())):
        for index in range(attributes.GetNumberOfArrays()):
            array = attributes.GetAbstractArray(index)
            state[f"{kind} {array.GetName()}"] = vtk_to_numpy(array).copy()
    return state


def assert_same_state(before: dict, after: dict) -> None:
    assert before.keys() == after.keys()
    for key, value in before.items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(after[key], value, err_msg=key)
        elif isinstance(value, list):
            for old, new in zip(value, after[key]):
                np.testing.assert_array_equal(new, old, err_msg=key)
        else:
            assert after[key] == value, key


# ------------------------------------------------------------------------------------------------ inputs untouched


@pytest.fixture(scope="module")
def step_inputs(sphere_samples):
    """Each filter's inputs, deep copies of a small pipeline's intermediate outputs, with extra arrays."""
    points, normals = sphere_samples
    pipeline = chain(polydata(points, normals), cells=1000, grid_spacing=0.06)
    pipeline.quality.update()

    def copy(algorithm):
        data = output(algorithm).NewInstance()
        data.DeepCopy(output(algorithm))
        return data

    source = polydata(points, normals, Weight=np.arange(len(points), dtype=np.float64))
    weight = vtkDoubleArray()
    weight.SetName("Note")
    weight.InsertNextValue(42.0)
    source.GetFieldData().AddArray(weight)
    image, *_ = ball_label_map()
    return {"points": source, "label map": image, "implicit": copy(pipeline.implicit),
            "nodes": copy(pipeline.biting), "tetrahedra": copy(pipeline.tetra), "domain": copy(pipeline.spurious)}


STEPS = {
    "PointsToImplicit-points": (PointsToImplicit, ["points"], {"GridSpacing": 0.06}),
    "PointsToImplicit-label-map": (PointsToImplicit, ["label map"], {}),
    "BitingSampler": (BitingSampler, ["implicit"], {"Cells": 1000}),
    "DelaunayTetra": (DelaunayTetra, ["nodes"], {}),
    "SpuriousCellFilter": (SpuriousCellFilter, ["tetrahedra", "implicit"], {}),
    "QualityFilter": (QualityFilter, ["domain"], {}),
    "MeshFromPoints": (MeshFromPoints, ["points"], {"Cells": 1000}),
}


@pytest.mark.parametrize("step", STEPS)
def test_no_filter_modifies_its_input(step_inputs, step):
    algorithm, inputs, parameters = STEPS[step]
    instance = algorithm()
    for port, name in enumerate(inputs):
        instance.SetInputData(port, step_inputs[name])
    for name, value in parameters.items():
        getattr(instance, f"Set{name}")(value)
    before = [snapshot(step_inputs[name]) for name in inputs]
    result = instance.update()
    assert result.GetNumberOfPoints() > 0
    for name, state in zip(inputs, before):
        assert_same_state(state, snapshot(step_inputs[name]))
