"""The summary of a cohort: ``summary.csv`` (one row per case) and ``report.html`` (the same rows, failures first,
sortable, each done case with a picture of a cut through its mesh), readable offline: the pictures are inline
base64 PNGs, the sorting inline JavaScript.  The pictures need matplotlib; without it the report has none."""
from __future__ import annotations

import base64
import csv
import html
import io
from pathlib import Path

import numpy as np

from ..io import atomic_output
from .cases import RECORDS

#: the report's order of statuses: what needs a look first
STATUS_ORDER = {"failed": 0, "cancelled": 1, "done": 2, "skipped": 3}
#: the edges of a tetrahedron, as pairs of its corners
EDGES = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])


def cut_polygons(points: np.ndarray, cells: np.ndarray, axis: int = 2):
    """The cut of a tetrahedral mesh by the plane through the middle of its box normal to ``axis``.

    Returns
    -------
    triangles : (a, 3, 2) float64, quads : (b, 4, 2) float64, the cut's polygons in the plane's two other
        coordinates (input units), and the indices (a,), (b,) of the cells they cut
    """
    middle = 0.5 * (points[:, axis].min() + points[:, axis].max())
    side = points[:, axis][cells] - middle                               # (m, 4) signed distances
    above = side >= 0
    crossing = above.any(axis=1) & ~above.all(axis=1)
    cells, side, above = cells[crossing], side[crossing], above[crossing]
    first, second = side[:, EDGES[:, 0]], side[:, EDGES[:, 1]]          # (k, 6)
    cut = above[:, EDGES[:, 0]] != above[:, EDGES[:, 1]]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(cut, first / (first - second), np.nan)
    plane = [other for other in range(3) if other != axis]
    start, end = points[cells[:, EDGES[:, 0]]][..., plane], points[cells[:, EDGES[:, 1]]][..., plane]
    corners = start + t[..., None] * (end - start)                      # (k, 6, 2), NaN where no cut
    centre = np.nanmean(corners, axis=1, keepdims=True)
    angle = np.arctan2(corners[..., 1] - centre[..., 1], corners[..., 0] - centre[..., 0])
    order = np.argsort(np.where(cut, angle, np.inf), axis=1)           # the cut corners first, around the centre
    corners = np.take_along_axis(corners, order[..., None], axis=1)
    count = cut.sum(axis=1)
    index = np.flatnonzero(crossing)
    return corners[count == 3, :3], corners[count == 4, :4], index[count == 3], index[count == 4]


def render_cut(mesh, pixels: int = 160):
    """PNG bytes of a cut through ``mesh`` (the middle plane normal to z; a 2D mesh whole), its cells coloured by
    radius ratio (0 dark, 1 yellow); None without matplotlib."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.collections import PolyCollection
        from matplotlib.figure import Figure
    except ImportError:
        return None
    points, cells = np.asarray(mesh.points, dtype=np.float64), np.asarray(mesh.cells)
    quality = np.asarray(mesh.cell_data.get("RadiusRatio", np.ones(len(cells))), dtype=np.float64)
    if points.shape[1] == 2:
        polygons, values = list(points[cells]), quality
    else:
        triangles, quads, of_triangles, of_quads = cut_polygons(points, cells)
        polygons, values = list(triangles) + list(quads), np.concatenate([quality[of_triangles], quality[of_quads]])
    figure = Figure(figsize=(1, 1), dpi=pixels)
    axes = figure.add_axes((0, 0, 1, 1))
    axes.add_collection(PolyCollection(polygons, array=values, cmap="viridis", clim=(0, 1), edgecolors="0.2",
                                       linewidths=0.15))
    axes.autoscale_view()
    axes.set_aspect("equal")
    axes.axis("off")
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    from PIL import Image   # matplotlib's own dependency: a 64-colour palette makes the PNG 4x smaller
    buffer = io.BytesIO()
    Image.fromarray(np.asarray(canvas.buffer_rgba())).convert("RGB").quantize(64).save(buffer, "PNG", optimize=True)
    return buffer.getvalue()


def picture_path(output_dir, name: str) -> Path:
    return Path(output_dir) / RECORDS / f"{name}.png"


def save_picture(output_dir, name: str, png) -> None:
    """Keep a case's picture for the report (nothing when there is none)."""
    if png is None:
        return
    path = picture_path(output_dir, name)
    path.parent.mkdir(exist_ok=True)
    with atomic_output(path, "a picture") as temporary:
        temporary.write_bytes(png)


def text(value) -> str:
    """A cell of the summary: floats to 6 significant digits."""
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def write_summary(rows, output_dir, columns) -> Path:
    """``output_dir/summary.csv``, one row per case (written atomically)."""
    path = Path(output_dir) / "summary.csv"
    with atomic_output(path, "the summary") as temporary:
        with open(temporary, "w", newline="") as stream:
            writer = csv.writer(stream)
            writer.writerow(columns)
            writer.writerows([text(row[column]) for column in columns] for row in rows)
    return path


SCRIPT = """
function sortBy(column) {
  const table = document.getElementById("cases"), body = table.tBodies[0];
  const rows = Array.from(body.rows), header = table.tHead.rows[0].cells[column];
  const down = header.dataset.order !== "up";
  const key = row => row.cells[column].dataset.key ?? row.cells[column].textContent;
  rows.sort((a, b) => {
    const x = key(a), y = key(b), p = parseFloat(x), q = parseFloat(y);
    const order = (isNaN(p) || isNaN(q)) ? x.localeCompare(y) : p - q;
    return down ? order : -order;
  });
  header.dataset.order = down ? "up" : "down";
  rows.forEach(row => body.appendChild(row));
}
"""
STYLE = ("body{font-family:sans-serif;margin:1em}table{border-collapse:collapse}th{cursor:pointer;"
         "background:#eee}th,td{border:1px solid #ccc;padding:2px 6px;font-size:90%}td.failed{color:#b00;"
         "font-weight:bold}td.cancelled{color:#a60}td.message{max-width:40em}")
#: the report's columns: (summary column, heading)
HEADINGS = (("case", "case"), ("status", "status"), ("message", "message"), ("cells", "cells"),
            ("points", "points"), ("R", "R"), ("mean_Q", "mean Q"), ("min_Q", "min Q"),
            ("min_dihedral", "min dihedral (deg)"), ("fidelity", "fidelity"), ("volume", "volume"),
            ("seconds", "seconds"))


def modes_section(modes: list) -> list:
    """The report's lines on a fitted cohort's shape model (:func:`~bitemesh.cohorts.shapes.write_shape_model`'s
    rows)."""
    if not modes:
        return ["<h2>Shape model</h2><p>None: fewer than two cases were fitted, or their shapes differ by a rigid "
                "motion only.</p>"]
    lines = ["<h2>Shape model</h2><p>Every case is the template fitted to its data (one connectivity). In "
             "<code>shape/</code>: <code>mean.vtu</code>, the mean after aligning the cases by rotations and "
             "translations, and the first modes at -2 and +2 standard deviations; <code>modes.csv</code> lists "
             "every mode.</p>",
             "<table><thead><tr><th>mode</th><th>node movement at 1 SD (RMS)</th><th>variance explained</th>"
             "<th>cumulative</th><th>meshes</th></tr></thead><tbody>"]
    for row in modes:
        lines.append(f"<tr><td>{row['mode']}</td><td>{row['node_rms']:.4g}</td><td>{row['explained']:.1%}</td>"
                     f"<td>{row['cumulative']:.1%}</td><td>{html.escape(row['files'])}</td></tr>")
    lines.append("</tbody></table>")
    return lines


def write_report(rows, output_dir, modes: list | None = None) -> Path:
    """``output_dir/report.html``: the rows (failed, cancelled, done, skipped, each by name), a picture of each
    mesh's cut, the columns sorted by a click on their heading, and for a fitted cohort (``modes``, a list, maybe
    empty) its shape model; no file outside the page."""
    output_dir = Path(output_dir)
    ordered = sorted(rows, key=lambda row: (STATUS_ORDER.get(row["status"], 9), row["case"]))
    counts = {status: sum(row["status"] == status for row in rows) for status in STATUS_ORDER}
    lines = ["<!DOCTYPE html>", "<html><head><meta charset='utf-8'><title>bitemesh cohort</title>",
             f"<style>{STYLE}</style><script>{SCRIPT}</script></head><body>",
             f"<h1>bitemesh cohort: {len(rows)} cases</h1><p>"
             + ", ".join(f"{count} {status}" for status, count in counts.items() if count)
             + ". Pictures: the cut through the middle of each mesh normal to z, cells coloured by radius ratio "
               "(dark 0, yellow 1). Click a heading to sort.</p>",
             "<table id='cases'><thead><tr><th onclick='sortBy(0)'>cut</th>"
             + "".join(f"<th onclick='sortBy({number})'>{html.escape(heading)}</th>"
                       for number, (_, heading) in enumerate(HEADINGS, start=1)) + "</tr></thead><tbody>"]
    for row in ordered:
        picture = picture_path(output_dir, row["case"])
        image = ""
        if row["status"] in ("done", "skipped") and picture.is_file():
            image = f"<img alt='cut' src='data:image/png;base64,{base64.b64encode(picture.read_bytes()).decode()}'>"
        cells = [f"<td data-key='{STATUS_ORDER.get(row['status'], 9)}'>{image}</td>"]
        for column, _ in HEADINGS:
            value = html.escape(text(row[column]))
            kind = row["status"] if column == "status" else column
            cells.append(f"<td class='{kind}'>{value}</td>")
        lines.append("<tr>" + "".join(cells) + "</tr>")
    lines.append("</tbody></table>")
    lines += [] if modes is None else modes_section(modes)
    lines.append("</body></html>")
    path = output_dir / "report.html"
    with atomic_output(path, "the report") as temporary:
        temporary.write_text("\n".join(lines), encoding="utf-8")
    return path
