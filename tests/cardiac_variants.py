"""Variants of a biv-me GPFile, built the way real exports differ from the shipped case (issue 10): denser
contours, no RV epicardium, no outflow valves, no valves at all, an LV only, another header, another time frame,
labels without their SAX/LAX prefix, scanner coordinates.  Shared by the tests and benchmarks/bivme.py.

A GPFile here is a dict of columns: points (n, 3) float64 mm, labels (n,) str, slices (n,) int64, frames (n,)
float64 (the "time frame" column).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

HEADER = ("x", "y", "z", "contour type", "frameID", "weight", "time frame")
RV_EPICARDIUM = ("SAX_RV_EPICARDIAL", "LAX_RV_EPICARDIAL")
OUTFLOW_VALVES = ("AORTA_VALVE", "PULMONARY_VALVE")
VALVES = ("MITRAL_VALVE", "TRICUSPID_VALVE") + OUTFLOW_VALVES
#: the labels of the left ventricle alone (and the points that orient and open it).
LEFT_VENTRICLE = ("SAX_LV_ENDOCARDIAL", "LAX_LV_ENDOCARDIAL", "SAX_LV_EPICARDIAL", "LAX_LV_EPICARDIAL",
                  "MITRAL_VALVE", "AORTA_VALVE", "APEX_POINT")


def read_gpfile(path) -> dict:
    """The columns of a GPFile (tab-separated, one header row)."""
    rows = [line.split("\t") for line in Path(path).read_text().splitlines()[1:] if line.strip()]
    return {"points": np.array([[float(v) for v in row[:3]] for row in rows]),
            "labels": np.array([row[3] for row in rows]), "slices": np.array([int(row[4]) for row in rows]),
            "frames": np.array([float(row[6]) for row in rows])}


def read_surface(path: Path):
    """Vertices (n, 3) and triangles (t, 3) of a legacy VTK polydata surface (biv-me's fitted surfaces)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter
    from vtkmodules.vtkIOLegacy import vtkPolyDataReader

    reader = vtkPolyDataReader()
    reader.SetFileName(str(path))
    triangulate = vtkTriangleFilter()
    triangulate.SetInputConnection(reader.GetOutputPort())
    triangulate.Update()
    surface = triangulate.GetOutput()
    vertices = vtk_to_numpy(surface.GetPoints().GetData()).astype(np.float64)
    cells = vtk_to_numpy(surface.GetPolys().GetConnectivityArray()).astype(np.int64).reshape(-1, 3)
    return vertices, cells


def write_gpfile(gp: dict, path, header=HEADER) -> Path:
    """Write ``gp`` as a GPFile with ``header`` (its names, tab-separated)."""
    lines = ["\t".join(header)] + [
        f"{x:.5f}\t{y:.5f}\t{z:.5f}\t{label}\t{slice_id}\t1.0\t{frame:g}"
        for (x, y, z), label, slice_id, frame in zip(gp["points"], gp["labels"], gp["slices"], gp["frames"])]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def subset(gp: dict, keep) -> dict:
    return {key: value[keep] for key, value in gp.items()}


def without(gp: dict, labels) -> dict:
    """Every point whose label is not one of ``labels``."""
    return subset(gp, ~np.isin(gp["labels"], labels))


def only(gp: dict, labels) -> dict:
    return subset(gp, np.isin(gp["labels"], labels))


def left_ventricle(gp: dict) -> dict:
    """An LV-only study: the LV's labels, its epicardium traced all round (biv-me's LV epicardial contours stop at
    the RV insertions; the septum's RV face, RV_SEPTUM, closes them)."""
    labels = np.array([label.replace("RV_SEPTUM", "LV_EPICARDIAL") for label in gp["labels"]])
    return only({**gp, "labels": labels}, LEFT_VENTRICLE)


def denser(gp: dict, factor: int = 4) -> dict:
    """Each contour (one label on one slice, its points in file order) resampled ``factor`` times denser: points
    interpolated along each segment no longer than 3 x the contour's median segment (gaps stay open)."""
    parts = {key: [] for key in gp}
    for label, slice_id in dict.fromkeys(zip(gp["labels"].tolist(), gp["slices"].tolist())):
        members = np.flatnonzero((gp["labels"] == label) & (gp["slices"] == slice_id))
        points = gp["points"][members]
        if len(points) < 3 or "VALVE" in label or "POINT" in label or label == "RV_INSERT":
            new = points
        else:
            steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
            short = steps <= 3 * np.median(steps)
            t = np.arange(factor)[None, :, None] / factor
            between = points[:-1, None] + t * (points[1:] - points[:-1])[:, None]
            new = np.vstack([np.vstack([segment if ok else segment[:1] for segment, ok in zip(between, short)]),
                             points[-1:]])
        parts["points"].append(new)
        for key in ("labels", "slices", "frames"):
            parts[key].append(np.full(len(new), gp[key][members[0]]))
    return {key: np.concatenate(value) for key, value in parts.items()}


def unprefixed(gp: dict) -> dict:
    """Labels without their SAX_/LAX_ prefix (LV_ENDOCARDIAL, RV_FREEWALL, ...), as some exports write them."""
    labels = np.array([label.split("_", 1)[1] if label[:4] in ("SAX_", "LAX_") else label for label in gp["labels"]])
    return {**gp, "labels": labels}


def moved(gp: dict, shift=(-180.0, 140.0, 920.0)) -> dict:
    """The same heart at scanner coordinates far from the origin (mm)."""
    return {**gp, "points": gp["points"] + np.asarray(shift)}


def in_frame(gp: dict, frame: float) -> dict:
    """Every point in time frame ``frame``."""
    return {**gp, "frames": np.full(len(gp["frames"]), float(frame))}


#: name -> (builder of the variant from the shipped case, the GPFile header it is written with)
VARIANTS = {
    "shipped": (lambda gp: gp, HEADER),
    "denser 4x": (denser, HEADER),
    "denser 6x": (lambda gp: denser(gp, 6), HEADER),
    "no RV epicardium": (lambda gp: without(gp, RV_EPICARDIUM), HEADER),
    "no outflow valves": (lambda gp: without(gp, OUTFLOW_VALVES), HEADER),
    "no valves": (lambda gp: without(gp, VALVES), HEADER),
    "LV only": (left_ventricle, HEADER),
    "sliceID header, frame 1": (lambda gp: in_frame(gp, 1), HEADER[:4] + ("sliceID",) + HEADER[5:]),
    "no SAX/LAX prefix": (unprefixed, HEADER),
    "scanner coordinates": (moved, HEADER),
    "like GPFile of issue 10": (lambda gp: in_frame(denser(without(gp, RV_EPICARDIUM + OUTFLOW_VALVES)), 1),
                                HEADER[:4] + ("sliceID",) + HEADER[5:]),
}


def variant_file(shipped, name: str, folder) -> Path:
    """Write the variant ``name`` of the shipped GPFile into ``folder``; its path."""
    build, header = VARIANTS[name]
    stem = "".join(c if c.isalnum() else "_" for c in name)
    return write_gpfile(build(read_gpfile(shipped)), Path(folder) / f"GPFile_{stem}.txt", header)


# --- classes of variation on the frames of a cine (issue 30) ---------------------------------------------------------

def contours(gp: dict):
    """(label, slice id, indices in file order) of each contour: one label on one slice, three points or more."""
    for label, slice_id in dict.fromkeys(zip(gp["labels"].tolist(), gp["slices"].tolist())):
        members = np.flatnonzero((gp["labels"] == label) & (gp["slices"] == slice_id))
        if len(members) >= 3 and "VALVE" not in label and "POINT" not in label and label != "RV_INSERT":
            yield label, slice_id, members


def in_plane_axes(points: np.ndarray) -> np.ndarray:
    """(2, 3) orthonormal axes of the least-squares plane of (n, 3) points."""
    return np.linalg.svd(points - points.mean(axis=0), full_matrices=False)[2][:2]


def short_axis_slices(gp: dict) -> list:
    """The slice ids of the short-axis contours, in file order."""
    return list(dict.fromkeys(gp["slices"][np.char.startswith(gp["labels"].astype(str), "SAX_")].tolist()))


def open_arcs(gp: dict, seed: int = 0, keep=(0.35, 0.7), share: float = 0.4) -> dict:
    """A share of the contours (at random, seeded) traced only in part: each keeps one run of its points in file
    order, 35 to 70 % of them, so that a closed contour becomes an open arc and an open one a shorter arc."""
    rng = np.random.default_rng(seed)
    drop = np.zeros(len(gp["labels"]), bool)
    for _, _, members in contours(gp):
        if rng.random() < share:
            length = max(4, int(len(members) * rng.uniform(*keep)))
            start = rng.integers(0, len(members) - length + 1)
            drop[members] = True
            drop[members[start:start + length]] = False
    return subset(gp, ~drop)


def short_arcs(gp: dict, seed: int = 0, slices: int = 4) -> dict:
    """On ``slices`` short-axis slices (the most basal and apical among them), every contour cut to a short arc of 4
    to 10 points, as dense exports leave at the base and the apex."""
    rng = np.random.default_rng(seed)
    chosen = short_axis_slices(gp)
    chosen = set(chosen[:slices // 2] + chosen[len(chosen) - (slices - slices // 2):])
    drop = np.zeros(len(gp["labels"]), bool)
    for _, slice_id, members in contours(gp):
        if slice_id in chosen:
            length = int(rng.integers(4, 11))
            start = rng.integers(0, max(1, len(members) - length + 1))
            drop[members] = True
            drop[members[start:start + length]] = False
    return subset(gp, ~drop)


def shifted_slices(gp: dict, seed: int = 0, largest: float = 5.0):
    """Each short-axis slice moved in its plane by a random shift of up to ``largest`` mm (separate breath-holds);
    the variant and slice id -> (3,) shift applied (mm)."""
    rng = np.random.default_rng(seed)
    points, shifts = gp["points"].copy(), {}
    for slice_id in short_axis_slices(gp):
        members = gp["slices"] == slice_id
        axes = in_plane_axes(points[members])
        angle, length = rng.uniform(0, 2 * np.pi), rng.uniform(0.4, 1.0) * largest
        shifts[slice_id] = length * (np.cos(angle) * axes[0] + np.sin(angle) * axes[1])
        points[members] += shifts[slice_id]
    return {**gp, "points": points}, shifts


def stack_normal(gp: dict) -> np.ndarray:
    """(3,) unit normal of the short-axis slices, pointing to the valves (the base)."""
    sax = short_axis_slices(gp)
    normal = np.cross(*in_plane_axes(gp["points"][gp["slices"] == sax[0]]))
    valves = gp["points"][np.isin(gp["labels"], VALVES)].mean(axis=0)
    return normal * np.sign((valves - gp["points"].mean(axis=0)) @ normal)


def long_axis_view_shifted(gp: dict, shift: float = 5.0) -> dict:
    """The first long-axis view moved by ``shift`` mm in its plane, across the short-axis stack's axis (a long-axis
    breath-hold off the others)."""
    sax = short_axis_slices(gp)
    view = next(number for number in dict.fromkeys(gp["slices"].tolist())
                if number not in sax and np.sum(gp["slices"] == number) > 20)
    members = gp["slices"] == view
    across = np.cross(np.cross(*in_plane_axes(gp["points"][members])), stack_normal(gp))
    points = gp["points"].copy()
    points[members] += shift * across / np.linalg.norm(across)
    return {**gp, "points": points}


def sparse_base(gp: dict) -> dict:
    """The base traced sparsely, as exports of fewer views leave it: the RV's long-axis contour points above the
    basal short-axis slice and the outflow valves' points left out."""
    normal = stack_normal(gp)
    height = gp["points"] @ normal - gp["points"][gp["slices"] == basal_slice(gp)].mean(axis=0) @ normal
    right = np.char.startswith(gp["labels"].astype(str), "LAX_RV_")
    return subset(gp, ~((right & (height > 0)) | np.isin(gp["labels"], OUTFLOW_VALVES)))


def basal_slice(gp: dict):
    """The slice id of the most basal short-axis slice."""
    normal = stack_normal(gp)
    return max(short_axis_slices(gp), key=lambda number: gp["points"][gp["slices"] == number].mean(axis=0) @ normal)


def closed_by_chord(gp: dict, share: float = 0.4) -> dict:
    """The basal short-axis slice's LV endocardial contour closed by a chord across the outflow tract, as exports
    trace it where the slice cuts the valves: the contour's points beyond a line across it, ``share`` of its width
    from its side towards the aortic valve, moved onto that line."""
    members = (gp["slices"] == basal_slice(gp)) & (gp["labels"] == "SAX_LV_ENDOCARDIAL")
    points = gp["points"].copy()
    centre = points[members].mean(axis=0)
    axes = in_plane_axes(points[members])
    towards = (points[gp["labels"] == "AORTA_VALVE"].mean(axis=0) - centre) @ axes.T @ axes
    towards /= np.linalg.norm(towards)
    reach = (points[members] - centre) @ towards
    line = reach.max() - share * np.ptp(reach)
    beyond = np.flatnonzero(members)[reach > line]
    points[beyond] -= np.outer(reach[reach > line] - line, towards)
    return {**gp, "points": points}


def stray_mitral_point(gp: dict, depth: float = 12.0) -> dict:
    """The first mitral point placed ``depth`` mm inside the LV cavity, towards the LV endocardial points' centre (a
    valve point clicked off the annulus, as biv-me's test patient_1 has one 11 mm from its view's contours' ends)."""
    points = gp["points"].copy()
    row = np.flatnonzero(gp["labels"] == "MITRAL_VALVE")[0]
    towards = points[np.char.find(gp["labels"].astype(str), "LV_ENDOCARDIAL") >= 0].mean(axis=0) - points[row]
    points[row] += depth * towards / np.linalg.norm(towards)
    return {**gp, "points": points}


def tilted_base(gp: dict, degrees: float = 30.0) -> dict:
    """The base tilted by ``degrees`` against the short-axis stack: every point above the data's centre moved across
    the stack's axis by its height there times tan(degrees) (a shear of the basal half: the annuli, the long-axis
    contours' upper parts and the basal short-axis slices together, as hearts whose mitral annulus leans more)."""
    normal = stack_normal(gp)
    height = (gp["points"] - gp["points"].mean(axis=0)) @ normal
    across = np.cross(normal, [1.0, 0.0, 0.0])
    across /= np.linalg.norm(across)
    shear = np.tan(np.radians(degrees)) * np.maximum(height, 0.0)
    return {**gp, "points": gp["points"] + np.outer(shear, across)}


def rotated(gp: dict, degrees: float = 30.0) -> dict:
    """Every point turned about the data's centre (another scanner's orientation of the same heart)."""
    angle = np.radians(degrees)
    turn = np.array([[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(angle), -np.sin(angle)], [0.0, np.sin(angle), np.cos(angle)]])
    centre = gp["points"].mean(axis=0)
    return {**gp, "points": (gp["points"] - centre) @ (turn @ tilt).T + centre}


def thinned_contours(gp: dict, step: int = 3) -> dict:
    """Every ``step``-th point of each contour (a sparser export), the valves and landmarks kept."""
    keep = np.ones(len(gp["labels"]), bool)
    for _, _, members in contours(gp):
        keep[members] = False
        keep[members[::step]] = True
    return subset(gp, keep)


def merged(first: dict, second: dict) -> dict:
    """Two frames in one file (each keeps its time-frame column)."""
    return {key: np.concatenate([first[key], second[key]]) for key in first}


#: name -> builder (the frames' folder, the frame) -> (the variant, the time frame to read or None)
CLASSES = {
    "open arcs": lambda folder, frame: (open_arcs(read_frame(folder, frame)), None),
    "short arcs": lambda folder, frame: (short_arcs(read_frame(folder, frame)), None),
    "slices shifted 5 mm": lambda folder, frame: (shifted_slices(read_frame(folder, frame))[0], None),
    "long-axis view shifted 5 mm": lambda folder, frame: (long_axis_view_shifted(read_frame(folder, frame)), None),
    "sparse base": lambda folder, frame: (sparse_base(read_frame(folder, frame)), None),
    "sparser 3x": lambda folder, frame: (thinned_contours(read_frame(folder, frame)), None),
    "stray mitral point": lambda folder, frame: (stray_mitral_point(read_frame(folder, frame)), None),
    "basal contour closed by a chord": lambda folder, frame: (closed_by_chord(read_frame(folder, frame)), None),
    "base tilted 30 deg": lambda folder, frame: (tilted_base(read_frame(folder, frame)), None),
    "rotated 30 deg": lambda folder, frame: (rotated(read_frame(folder, frame)), None),
    "denser 4x": lambda folder, frame: (denser(read_frame(folder, frame)), None),
    "no RV epicardium": lambda folder, frame: (without(read_frame(folder, frame), RV_EPICARDIUM), None),
    "frames merged": lambda folder, frame: (merged(read_frame(folder, frame), read_frame(folder, (frame + 8) % 25)),
                                            float(frame)),
}


def read_frame(folder, frame: int) -> dict:
    """Frame ``frame`` of a cine's folder of GPFile_NNN.txt."""
    return read_gpfile(Path(folder) / f"GPFile_{frame:03d}.txt")


def class_file(folder, frame: int, name: str, scratch):
    """Write the class of variation ``name`` of ``frame`` into ``scratch``: its path and the time frame to read."""
    gp, time_frame = CLASSES[name](folder, frame)
    stem = "".join(c if c.isalnum() else "_" for c in name)
    return write_gpfile(gp, Path(scratch) / f"GPFile_{frame:03d}_{stem}.txt"), time_frame
