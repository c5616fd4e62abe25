"""The mesh's unit (``--unit``, ``Mesh.unit``): kept by the files that hold one (.xdmf: its Geometry's ``Unit``;
the cardiac-geometries folder: info.json; Abaqus: a comment line), converted where a format has its own (openCARP's
micrometres), and refused when it is no unit bitemesh knows."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from bitemesh import InvalidInputError, Options
from bitemesh.io import read_mesh, write_mesh

from tests.fibrecheck import tagged_shell


@pytest.mark.parametrize("unit", ["um", "mm", "cm", "m"])
def test_the_unit_round_trips_and_opencarp_gets_micrometres(tmp_path, unit):
    mesh = replace(tagged_shell(), unit=unit)
    for name in ("heart.xdmf", "heart"):
        write_mesh(mesh, tmp_path / name)
        back = read_mesh(tmp_path / name)
        assert back.unit == unit, name
        np.testing.assert_array_equal(back.points, mesh.points)
    write_mesh(mesh, tmp_path / "heart.pts")
    micrometres = {"um": 1.0, "mm": 1e3, "cm": 1e4, "m": 1e6}[unit]
    np.testing.assert_allclose(np.loadtxt(tmp_path / "heart.pts", skiprows=1), mesh.points * micrometres, rtol=1e-15)
    write_mesh(mesh, tmp_path / "heart.inp")
    assert f"** the coordinates' unit: {unit}" in (tmp_path / "heart.inp").read_text()


def test_an_unknown_unit_is_refused_naming_the_choices(tmp_path):
    with pytest.raises(InvalidInputError, match=r"unit \(--unit\) must be one of um, mm, cm, m .* got 'inch'"):
        Options(unit="inch")
    with pytest.raises(InvalidInputError, match=r"mesh.unit must be one of um, mm, cm, m, got 'inch'"):
        write_mesh(replace(tagged_shell(), unit="inch"), tmp_path / "heart.xdmf")


def test_the_command_writes_the_unit_it_is_given(tmp_path, monkeypatch, capsys):
    from bitemesh import cli

    from tests.cli.test_fibres_flag import meshed_as_the_shell
    meshed_as_the_shell(monkeypatch)
    assert cli.main(["mesh", "contours.txt", "-o", str(tmp_path / "heart.xdmf"), "--unit", "cm"]) == 0
    assert read_mesh(tmp_path / "heart.xdmf").unit == "cm"
