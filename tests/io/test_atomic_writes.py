"""bitemesh.io writes every mesh atomically: a failing writer leaves no file where there was none, and every
format is written whole and replaces the previous file without leftovers.  (The ``bitemesh`` command's full disk and
Ctrl-C: tests/cli/test_safe_writing.py.)"""
from __future__ import annotations

import os
import time

from pathlib import Path

import numpy as np
import pytest
from bitemesh.core.mesh.simplicial import Mesh
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


def aged(path, seconds: float = 120.0):
    """Write ``path`` as a run killed ``seconds`` ago would have left it (its last write then)."""
    path.write_text("x")
    then = time.time() - seconds
    os.utime(path, (then, then))
    return path


def test_the_stale_partials_of_a_file_are_its_own_alone(tmp_path):
    """What atomic writes of p1.vtu left when killed: found; another file's (even p1.v2.vtu's or p10.vtu's), a
    finished file, a name without the token and one written a moment ago (another run writing p1.vtu): not."""
    from bitemesh.io import stale_partials
    stale = [tmp_path / ".p1.0a1b2c3d.partial.vtu", tmp_path / ".p1.deadbeef.partial.vtu"]
    others = [tmp_path / ".p1.v2.0a1b2c3d.partial.vtu", tmp_path / ".p10.0a1b2c3d.partial.vtu", tmp_path / "p1.vtu",
              tmp_path / ".p1.0a1b2c3d.partial.msh", tmp_path / ".p1.notahex0.partial.vtu"]
    for path in stale + others:
        aged(path)
    (tmp_path / ".p1.0a1b2c3e.partial.vtu").write_text("x")   # another run writing p1.vtu now: not stale
    assert stale_partials(tmp_path / "p1.vtu") == sorted(stale)
    assert stale_partials(tmp_path / "absent" / "p1.vtu") == []
    aged(tmp_path / ".seg.0a1b2c3d.partial.nii.gz")   # the double extension is kept whole
    assert stale_partials(tmp_path / "seg.nii.gz") == []
    aged(tmp_path / ".seg.nii.0a1b2c3d.partial.nii.gz")
    assert stale_partials(tmp_path / "seg.nii.gz") == [tmp_path / ".seg.nii.0a1b2c3d.partial.nii.gz"]


# --- a mesh and its companions committed together ---------------------------------------------------------------------

def tagged_tetrahedron(shift: float = 0.0) -> Mesh:
    """One tetrahedron with its four faces tagged (a .vtu of it is two files: the cells and the facets)."""
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float) + shift
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return Mesh(points, np.array([[0, 1, 2, 3]]), facets=faces, facet_tags=np.array([1, 1, 1, 2]),
                tag_names={"SIDE": (1, 2), "TOP": (2, 2)})


def test_ctrl_c_between_the_two_renames_of_a_vtu_waits_until_both_are_new(monkeypatch, tmp_path):
    """The interrupt arrives after the mesh's rename, before its facets': it is delivered once both files are in
    place, so the pair on disk is never the new mesh with the old facets."""
    import os
    import signal

    from bitemesh.io import files
    path = tmp_path / "heart.vtu"
    write_mesh(tagged_tetrahedron(), path)
    real_replace, renamed = os.replace, []

    def interrupted(source, target):
        real_replace(source, target)
        renamed.append(target)
        if len(renamed) == 1:
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(files.os, "replace", interrupted)
    before = signal.signal(signal.SIGINT, signal.default_int_handler)   # Python's own, whatever ran before
    try:
        with pytest.raises(KeyboardInterrupt, match=f"a mesh was written to '{path}' first"):
            write_mesh(tagged_tetrahedron(shift=5.0), path)
    finally:
        signal.signal(signal.SIGINT, before)
    monkeypatch.undo()
    assert len(renamed) == 2
    mesh = read_mesh(path)   # the pair reads back: both new
    np.testing.assert_allclose(mesh.points.min(axis=0), 5.0)
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("extension", [".msh", ".npz"])
def test_an_output_that_is_a_symbolic_link_is_written_through_it(tmp_path, extension):
    target = tmp_path / "meshes" / f"heart{extension}"
    target.parent.mkdir()
    link = tmp_path / f"latest{extension}"
    link.symlink_to(target)
    write_mesh(tagged_tetrahedron(), link)
    assert link.is_symlink() and target.is_file() and len(read_mesh(link).cells) == 1


@pytest.mark.parametrize("extension", [".vtu", ".xdmf"])
def test_a_mesh_written_through_a_link_has_its_companions_beside_its_target(tmp_path, extension):
    """latest.vtu -> meshes/heart.vtu: heart_facets.vtu (heart.h5 and heart_facets.* for XDMF) go beside the target,
    so the target and the link read the same mesh with its tags (the companions went beside the link, named after
    it, and the target read alone lost its tags without a word)."""
    target = tmp_path / "meshes" / f"heart{extension}"
    target.parent.mkdir()
    link = tmp_path / f"latest{extension}"
    link.symlink_to(target)
    mesh = tagged_tetrahedron()
    write_mesh(mesh, link)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["latest" + extension, "meshes"]
    for path in (target, link):
        back = read_mesh(path)
        assert back.tag_names == mesh.tag_names and len(back.facets) == len(mesh.facets)


def test_the_half_written_files_of_a_killed_run_are_removed_with_a_note(tmp_path, caplog):
    path = tmp_path / "heart.msh"
    stale = aged(tmp_path / ".heart.0a1b2c3d.partial.msh")   # a run killed before it could remove it
    live = tmp_path / ".heart.1b2c3d4e.partial.msh"
    live.write_text("$MeshFormat\n")   # another run writing heart.msh at this moment: its file is left to it
    with caplog.at_level("INFO", logger="bitemesh"):
        write_mesh(tagged_tetrahedron(), path)
    assert not stale.exists() and live.exists() and path.is_file()
    assert "removed 1 half-written file(s) of 'heart.msh'" in caplog.text
