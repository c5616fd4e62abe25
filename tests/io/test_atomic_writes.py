"""bitemesh.io writes every mesh atomically: a failing writer leaves no file where there was none, and every
format is written whole and replaces the previous file without leftovers.  (The ``bitemesh`` command's full disk and
Ctrl-C: tests/cli/test_safe_writing.py.)"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bitemesh.core.mesh import Mesh
from bitemesh.io import read_mesh, write_mesh

from tests.builders import leftovers


def test_a_failing_writer_leaves_no_file_where_there_was_none(monkeypatch, tmp_path):
    import meshio
    path = tmp_path / "new.msh"

    def failing(target, mesh, **options):
        Path(target).write_text("$MeshFormat\n2.2 0 8\n")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(meshio, "write", failing)
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    with pytest.raises(Exception, match="No space left on device"):
        write_mesh(Mesh(points, np.array([[0, 1, 2, 3]])), path)
    assert not path.exists() and leftovers(tmp_path) == []


@pytest.mark.parametrize("extension", [".vtu", ".vtk", ".msh", ".inp", ".mesh"])
def test_every_format_is_written_whole_and_replaces_the_previous_file(tmp_path, extension):
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float)
    path = tmp_path / f"mesh{extension}"
    write_mesh(Mesh(points[:4], np.array([[0, 1, 2, 3]])), path)
    write_mesh(Mesh(points, np.array([[0, 1, 2, 3], [1, 2, 3, 4]])), path)
    assert len(read_mesh(path).cells) == 2
    assert leftovers(tmp_path) == []


def test_the_stale_partials_of_a_file_are_its_own_alone(tmp_path):
    """What atomic writes of p1.vtu left when killed: found; another file's (even p1.v2.vtu's or p10.vtu's), a
    finished file and a name without the token: not."""
    from bitemesh.io import stale_partials
    stale = [tmp_path / ".p1.0a1b2c3d.partial.vtu", tmp_path / ".p1.deadbeef.partial.vtu"]
    others = [tmp_path / ".p1.v2.0a1b2c3d.partial.vtu", tmp_path / ".p10.0a1b2c3d.partial.vtu", tmp_path / "p1.vtu",
              tmp_path / ".p1.0a1b2c3d.partial.msh", tmp_path / ".p1.notahex0.partial.vtu"]
    for path in stale + others:
        path.write_text("x")
    assert stale_partials(tmp_path / "p1.vtu") == sorted(stale)
    assert stale_partials(tmp_path / "absent" / "p1.vtu") == []
    (tmp_path / ".seg.0a1b2c3d.partial.nii.gz").write_text("x")   # the double extension is kept whole
    assert stale_partials(tmp_path / "seg.nii.gz") == []
    (tmp_path / ".seg.nii.0a1b2c3d.partial.nii.gz").write_text("x")
    assert stale_partials(tmp_path / "seg.nii.gz") == [tmp_path / ".seg.nii.0a1b2c3d.partial.nii.gz"]
