"""The examples run as a user runs them (a fresh interpreter, PYTHONPATH=filters) and make what they promise."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOImage import vtkPNGReader

from tests.builders import sphere_samples

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "vtk_pipeline.py"


def run_example(*arguments, timeout=180, script=EXAMPLE) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "filters"), env.get("PYTHONPATH")]))
    done = subprocess.run([sys.executable, str(script), *arguments], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=timeout, check=False)
    assert done.returncode == 0, done.stderr
    assert "ERROR" not in done.stderr and "Warning" not in done.stderr and "WARN" not in done.stderr, done.stderr
    return done


def read_png(path: Path) -> np.ndarray:
    """(height, width, components) uint8 pixels of a PNG, read with VTK."""
    reader = vtkPNGReader()
    reader.SetFileName(str(path))
    reader.Update()
    image = reader.GetOutput()
    width, height, _ = image.GetDimensions()
    scalars = image.GetPointData().GetScalars()
    return vtk_to_numpy(scalars).reshape(height, width, scalars.GetNumberOfComponents())


def assert_coloured_picture(path: Path) -> None:
    """An 800 x 600 picture with many colours: cells in several hues on the white background."""
    assert path.is_file()
    pixels = read_png(path)[..., :3]
    assert pixels.shape == (600, 800, 3)
    colours = np.unique(pixels.reshape(-1, 3), axis=0)
    assert len(colours) > 50
    coloured = pixels.max(axis=-1).astype(int) - pixels.min(axis=-1) > 80  # saturated: not white, grey or black
    assert coloured.mean() > 0.05
    dominant = np.bincount(np.argmax(pixels[coloured], axis=-1), minlength=3)
    assert (dominant > 100).sum() >= 2, dominant  # cells of different quality: more than one hue


def test_the_vtk_pipeline_example_meshes_the_die_and_renders_a_coloured_cut(tmp_path):
    picture = tmp_path / "cut.png"
    done = run_example("-o", str(picture))
    assert "q_mean" in done.stdout and "radius ratio histogram" in done.stdout
    assert f"wrote {picture}" in done.stdout
    cells = int(float(next(line.split()[1] for line in done.stdout.splitlines() if line.split()[:1] == ["n_cells"])))
    assert 8000 < cells < 12000
    assert_coloured_picture(picture)


def test_the_vtk_pipeline_example_reads_points_from_a_file(tmp_path):
    points, normals = sphere_samples(0.1, seed=3)
    source = tmp_path / "sphere.xyz"
    np.savetxt(source, np.column_stack([points, normals]))
    picture = tmp_path / "sphere.png"
    done = run_example(str(source), "-o", str(picture), "--cells", "2000")
    assert f"{len(points)} scattered points with normals" in done.stdout
    assert_coloured_picture(picture)


def test_the_example_explains_itself():
    assert "scattered points" in run_example("--help").stdout


def test_the_heart_fibres_example_renders_the_helix_from_endocardium_to_epicardium(tmp_path):
    from bitemesh.core.fem.fibres import with_fibres
    from bitemesh.io import write_mesh

    from tests.fibrecheck import tagged_shell

    mesh = tmp_path / "shell.vtu"
    write_mesh(with_fibres(tagged_shell())[0], mesh)
    picture = tmp_path / "fibres.png"
    done = run_example(str(mesh), "-o", str(picture), script=ROOT / "examples" / "heart_fibres.py")
    assert f"wrote {picture}" in done.stdout
    pixels = read_png(picture)[..., :3]
    assert pixels.shape == (700, 1000, 3)
    heart = pixels[:, :860].reshape(-1, 3).astype(int)   # the heart's view, left of the legend's (x > 870)
    saturated = heart[heart.max(axis=1) - heart.min(axis=1) > 80]
    # the fibres' colours span the helix: red to yellow (endocardium, about +40 deg) and blue (epicardium, -50);
    # fibres of one angle (all green at 0 deg, say) would give neither
    warm = (saturated[:, 0] > 200) & (saturated[:, 2] < 100)
    cold = (saturated[:, 2] > 200) & (saturated[:, 0] < 100)
    assert warm.sum() > 500 and cold.sum() > 500, (warm.sum(), cold.sum())
