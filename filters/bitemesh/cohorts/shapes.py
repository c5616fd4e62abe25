"""The shape model of a cohort fitted with one template (``bitemesh batch --template``): every case has the
template's cells, so node i is the same point on every heart; their mean shape and main modes of variation
(:func:`bitemesh.core.fem.shape_modes.shape_modes`) are written as meshes in ``OUTDIR/shape/`` with a table."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..core.fem.shape_modes import shape_modes
from ..core.mesh.quality import cell_quality
from ..core.mesh.simplicial import Mesh
from ..io import atomic_output, read_mesh, write_mesh

#: the folder of OUTDIR holding the shape model
FOLDER = "shape"
#: the modes written as meshes (the first, by variance), each at -SPREAD and +SPREAD standard deviations
MESHED_MODES, SPREAD = 3, 2.0


def shape_mesh(template: Mesh, points: np.ndarray) -> Mesh:
    """The template's cells, regions and tags on ``points`` (n, 3), with the cells' quality arrays (its fibres left
    out: they belong to no one case)."""
    shape = Mesh(points, template.cells)
    cell_data = {name: values for name, values in template.cell_data.items() if name == "Region"}
    return Mesh(points, template.cells, {**cell_data, **cell_quality(shape)}, template.facets, template.facet_tags,
                template.tag_names, unit=template.unit)


def write_shape_model(rows: list, output_dir, template: Mesh) -> list:
    """The mean shape and modes of the cases of ``rows`` (summary rows) that were fitted ("done" or "skipped"),
    written to ``output_dir/shape/``: ``mean.vtu``, ``modeK_minus2sd.vtu`` and ``modeK_plus2sd.vtu`` for the first
    :data:`MESHED_MODES` modes, ``modes.csv`` (every mode: ``node_rms``, how far a node moves, RMS over the
    nodes, at one standard deviation, in input units; the share of the variance it explains; the cumulative share).

    Returns the rows of modes.csv as dicts (``mode``, ``node_rms``, ``explained``, ``cumulative``, ``files``);
    none when fewer than two cases were fitted."""
    output_dir = Path(output_dir)
    fitted = [row for row in rows if row["status"] in ("done", "skipped")]
    if len(fitted) < 2:
        return []
    model = shape_modes([read_mesh(output_dir / row["output"]).points for row in fitted])
    folder = output_dir / FOLDER
    folder.mkdir(exist_ok=True)
    write_mesh(shape_mesh(template, model.mean), folder / "mean.vtu")
    table = []
    for number, (deviation, explained) in enumerate(zip(model.deviations, model.explained), start=1):
        files = []
        if number <= MESHED_MODES:
            for sign, side in ((-1, "minus"), (1, "plus")):
                weights = np.zeros(number)
                weights[-1] = sign * SPREAD
                name = f"mode{number}_{side}{SPREAD:g}sd.vtu"
                write_mesh(shape_mesh(template, model.shape(weights)), folder / name)
                files.append(name)
        table.append({"mode": number, "node_rms": float(deviation / np.sqrt(len(model.mean))),
                      "explained": float(explained), "cumulative": float(model.explained[:number].sum()),
                      "files": " ".join(files)})
    written = {name for row in table for name in row["files"].split()}
    for stale in folder.glob("mode*sd.vtu"):   # of an earlier run with more modes
        if stale.name not in written:
            stale.unlink()
    with atomic_output(folder / "modes.csv", "the shape modes") as temporary:
        with open(temporary, "w", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=list(table[0]) if table else ["mode"])
            writer.writeheader()
            writer.writerows(table)
    return table
