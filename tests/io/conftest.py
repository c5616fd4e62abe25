"""Fixtures of the reader and writer tests."""
from __future__ import annotations

import pytest


@pytest.fixture
def vtk_silent(capfd):
    """Call it at the end of a test: fails if VTK (or meshio) printed an error or a warning so far in the test."""
    def check():
        err = capfd.readouterr().err
        assert "ERROR" not in err and "ERR|" not in err and "Warning" not in err and "WARN" not in err, err
    return check
