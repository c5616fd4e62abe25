"""Imports that users were shown and that moved still work, each with a DeprecationWarning naming the new place."""
from __future__ import annotations

import importlib
import sys

import pytest


def test_algorithms_convert_reexports_bitemesh_convert_and_warns():
    import bitemesh.convert

    sys.modules.pop("bitemesh.algorithms.convert", None)
    with pytest.warns(DeprecationWarning, match=r"bitemesh\.convert"):
        old = importlib.import_module("bitemesh.algorithms.convert")
    from bitemesh.algorithms.convert import mesh_to_unstructured   # what the README once showed

    assert mesh_to_unstructured is bitemesh.convert.mesh_to_unstructured
    for name in old.__all__:
        assert getattr(old, name) is getattr(bitemesh.convert, name)


@pytest.mark.parametrize("name", ["LABEL_COLUMNS", "LABELLED_TEXT_EXTENSIONS", "LABELLED_VTK_EXTENSIONS"])
def test_io_constants_moved_to_io_contours_warn(name):
    import bitemesh.io
    import bitemesh.io.contours

    with pytest.warns(DeprecationWarning, match=r"bitemesh\.io\.contours"):
        value = getattr(bitemesh.io, name)
    assert value is getattr(bitemesh.io.contours, name)


def test_io_slice_columns_warns_and_gives_the_slice_names():
    import bitemesh.io
    from bitemesh.core.columns import role

    with pytest.warns(DeprecationWarning, match=r"bitemesh\.core\.columns"):
        from bitemesh.io import SLICE_COLUMNS
    assert SLICE_COLUMNS and all(role(name) == "slice" for name in SLICE_COLUMNS)
    assert {"frameid", "slice", "sliceid"} <= set(SLICE_COLUMNS)
    with pytest.raises(AttributeError):
        bitemesh.io.NO_SUCH_NAME   # noqa: B018


def test_points_to_implicit_from_core_implicit_warns():
    from bitemesh.core import pipeline

    with pytest.warns(DeprecationWarning, match=r"bitemesh\.core\.pipeline"):
        from bitemesh.core.implicit import points_to_implicit
    assert points_to_implicit is pipeline.points_to_implicit
