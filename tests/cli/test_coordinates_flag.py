"""``--coordinates`` of ``bitemesh mesh``: the ventricular coordinates written as point arrays and the AHA segments
and ventricles as cell arrays (the tagged two-cavity shell stands in for the meshing), and one-line refusals of an
output that keeps no point arrays, before any meshing."""
from __future__ import annotations

import numpy as np
import pytest
from bitemesh import cli, meshing
from bitemesh.core.fem.coordinates import COORDINATE_ARRAYS, ventricular_coordinates
from bitemesh.io import read_mesh

from tests.cli.commands import assert_no_traceback, assert_one_line_error
from tests.cli.test_fibres_flag import forbidden, meshed_as_the_shell
from tests.fibrecheck import tagged_shell


@pytest.mark.parametrize("extension", [".vtu", ".xdmf", ".npz"])
def test_mesh_coordinates_writes_point_and_cell_arrays(tmp_path, monkeypatch, capsys, extension):
    meshed_as_the_shell(monkeypatch)
    output = tmp_path / f"heart{extension}"
    assert cli.main(["mesh", "contours.txt", "-o", str(output), "--coordinates", "--fibres"]) == 0
    out, err = capsys.readouterr()
    assert_no_traceback(err)
    written, expected = read_mesh(output), ventricular_coordinates(tagged_shell())
    for name in COORDINATE_ARRAYS + ("Psi", "PhiEpi", "PhiLV", "PhiRV"):
        np.testing.assert_allclose(written.point_data[name], expected.points[name], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(written.cell_data["AHA"], expected.aha)
    np.testing.assert_array_equal(written.cell_data["Ventricle"], expected.ventricle)
    assert "Fibre" in written.cell_data and "coordinates: point arrays ApicoBasal" in out


@pytest.mark.parametrize("extension", [".msh", ".inp", ".mesh", ".pts"])
def test_an_output_without_point_arrays_is_refused_before_meshing(tmp_path, monkeypatch, capsys, extension):
    monkeypatch.setattr(meshing, "read_input", forbidden)
    code = cli.main(["mesh", "contours.txt", "-o", str(tmp_path / f"heart{extension}"), "--coordinates"])
    assert_one_line_error(capsys, code, "--coordinates", extension, "no point arrays", ".vtu")
