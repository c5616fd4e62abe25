"""One frozen dataclass of parameters per step: defaults, units and valid ranges in one place.

Each field's metadata holds ``help``, ``unit`` and either ``range`` (low, high, low_open, high_open), ``choices``
or ``text`` (free text).
The CLI flags, the VTK setters, the ParaView domains and the Slicer parameter node read them from here.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass, field, fields
from typing import Optional

from .errors import InvalidInputError, check_choice, check_number


def parameter(default, help: str, *, unit: str = "", low=None, high=None, low_open=False, high_open=False,
              choices=None, integer=False, text=False):
    """A dataclass field carrying its help text, unit and valid range (None: optional, chosen automatically);
    ``text``: any string."""
    metadata = {"help": help, "unit": unit, "integer": integer}
    if text:
        metadata["text"] = True
    elif choices is not None:
        metadata["choices"] = tuple(choices)
    else:
        metadata["range"] = (low, high, low_open, high_open)
    return field(default=default, metadata=metadata)


def is_optional(item) -> bool:
    """True for a numeric field that is None by default: chosen automatically."""
    return item.default is None and "range" in item.metadata


#: the number that stands for None ("chosen automatically") where a number must be given: the VTK setters, the
#: ParaView properties, the Slicer parameter node and the CLI.  Below the range of every optional field.
AUTOMATIC = -1


#: the radial basis functions of the RBF fits: phi(r) = r, r^3, r^2 log r.
KERNELS = ("linear", "cubic", "thin_plate")


class Parameters:
    """Checks every field against its metadata when the dataclass is made."""

    def __post_init__(self):
        for item in fields(self):
            value = getattr(self, item.name)
            if value is None:
                continue
            if "text" in item.metadata:
                if not isinstance(value, str):
                    raise InvalidInputError(f"{item.name} must be text, got {value!r}")
                continue
            if "choices" in item.metadata:
                check_choice(value, item.name, item.metadata["choices"])
                continue
            low, high, low_open, high_open = item.metadata["range"]
            number = check_number(value, item.name, low=low, high=high, low_open=low_open, high_open=high_open)
            if item.metadata["integer"] and number != int(number):
                raise InvalidInputError(f"{item.name} must be a whole number, got {value!r}")
            object.__setattr__(self, item.name, int(number) if item.metadata["integer"] else number)


@dataclass(frozen=True)
class ImplicitParameters(Parameters):
    """PointsToImplicit: scattered points to f sampled on the grid I."""

    method: str = parameter("auto", "implicit reconstruction: multilevel partition of unity (3D), or (sparse data, "
                            "2D or 3D) polyharmonic RBFs on patches blended by a partition of unity; auto: mpu for 3D "
                            "points, rbf for 2D", choices=("auto", "mpu", "rbf"))
    error_bound: Optional[float] = parameter(
        None, "eps0, the largest local fitting error of MPU; default 0.005 x bounding-box diagonal",
        unit="input units", low=0, low_open=True)
    grid_spacing: Optional[float] = parameter(
        None, "h, the spacing of the grid I on which f is sampled; default radius / 4", unit="input units",
        low=0, low_open=True)
    margin: Optional[float] = parameter(None, "extra grid around the data; default 3 grid spacings",
                                        unit="input units", low=0)
    max_memory_mb: float = parameter(4096.0, "largest grid the mesher may allocate", unit="MiB", low=1)
    outliers: str = parameter("drop", "points far from the others or off the surface their neighbours sample: drop "
                              "them (and say how many), or keep them", choices=("drop", "keep"))


#: the cells aimed for when neither radius nor cells is given and the data carries no size of its own.
DEFAULT_CELLS = 10000


@dataclass(frozen=True)
class BitingParameters(Parameters):
    """BitingSampler: node placement on the grid (Algorithm 1 of the paper)."""

    radius: Optional[float] = parameter(
        None, "R, the minimum distance between nodes (close to the mean edge length); default: chosen for about "
        "`cells` cells", unit="input units", low=0, low_open=True)
    cells: Optional[int] = parameter(
        None, f"the number of cells to aim for when radius is not given; default: the size the data carries (R = 2 "
        f"mm for cardiac contours), else {DEFAULT_CELLS}", low=100, high=50_000_000, integer=True)
    order: str = parameter("boundary", "SelectNode order: the border layer first then inward, or random",
                           choices=("boundary", "random"))
    seed: int = parameter(0, "seed of the random generator (same input and seed give the same mesh)", low=0,
                          high=2**32 - 1, integer=True)

    @property
    def aimed_cells(self) -> int:
        """``cells``, or :data:`DEFAULT_CELLS` when it is left to choose."""
        return DEFAULT_CELLS if self.cells is None else self.cells


@dataclass(frozen=True)
class SpuriousParameters(Parameters):
    """SpuriousCellFilter: drop the cells outside the domain, then make the domain valid."""

    threshold: float = parameter(0.4, "a cell is outside when f < 0 at its circumcentre and the distance from it "
                                 "to the surface exceeds threshold x circumradius", low=0, high=1)
    min_component: float = parameter(0.01, "drop connected parts smaller than this fraction of the largest part's "
                                     "volume", low=0, high=1)
    handles: str = parameter("auto", "remove: cut or fill the handles of the domain (tunnels and bridges thinner "
                             "than a cell) and fill its closed voids, for a domain known to be a ball (its cavities "
                             "open); keep: the topology the cells give; auto: remove for a biv-me heart (a "
                             "myocardium with its cavities open through the base), else keep",
                             choices=("auto", "keep", "remove"))


@dataclass(frozen=True)
class LabelMapParameters(Parameters):
    """PointsToImplicit on a label map: which label is the domain."""

    label: Optional[int] = parameter(None, "the label of the domain (0 is the background); default every nonzero "
                                     "label", low=1, integer=True)


@dataclass(frozen=True)
class LabelledParameters(Parameters):
    """Labelled contours: points with a label each (a biv-me GPFile, a table or a ``Label`` array) to a domain."""

    domain: str = parameter("", "CSG of the labelled surfaces, e.g. 'EPI - LV_ENDO - RV_ENDO' (- difference, "
                            "+ union, & intersection, parentheses); empty: the two-cavity myocardium for biv-me "
                            "labels, else the only surface", text=True)
    base_plane: str = parameter("auto", "what closes the domain at the base: auto (biv-me labels: the surface "
                                "through the valve annuli and the long-axis contours' upper ends, else the "
                                "basal short-axis slice; other labels: the plane of the valve points, if any), "
                                "valves (valve points required), or none", choices=("auto", "valves", "none"))
    min_wall: Optional[float] = parameter(
        None, "the thinnest wall the domain keeps between a surface and what is subtracted from it (a wall thinner "
        "than a cell opens in holes); default the larger of 2.5 and 1.25 R (R = 4 grid spacings in "
        "PointsToImplicit)", unit="input units", low=0)
    rv_wall: Optional[float] = parameter(
        None, "biv-me contours without RV epicardial points: the RV free wall thickness the RV epicardium is derived "
        "with; default 3 mm (normal adult RV walls: 2 to 5 mm), a smaller heart's in proportion", unit="mm", low=0,
        low_open=True, high=20)
    allow_implausible: int = parameter(0, "1 keeps a heart mesh that fails the plausibility checks (a cavity closed "
                                       "or filled, volume or wall thickness out of range, guide points far from "
                                       "the boundary), with a warning, instead of refusing it", low=0, high=1,
                                       integer=True)
    kernel: str = parameter("linear", "the radial basis function of each surface's fit: r (Carr's biharmonic), "
                            "r^3, or r^2 log r", choices=KERNELS)
    offset: Optional[float] = parameter(
        None, "the largest distance of the fit's off-surface constraints from the contours (halved where another "
        "contour is near); default 4 (an adult heart's mm; contours spanning less than 140 mm in proportion)",
        unit="input units", low=0, low_open=True)
    smoothing: float = parameter(0.0, "added to the diagonal of each patch's kernel matrix, in units of phi(patch "
                                 "diameter): 0 interpolates the contours, more smooths tracing noise", low=0)
    base_offset: float = parameter(0.0, "moves the base along its normal (> 0: away from the apex)",
                                   unit="input units", low=-50, high=50)
    resolution: Optional[float] = parameter(
        None, "the spacing of the grid each surface is sampled on; default 0.35 x the median spacing of its points "
        "(at least offset / 4 and 1/400 of its box's diagonal)", unit="input units", low=0, low_open=True)
    slice_shifts: str = parameter("auto", "auto: cardiac contours (biv-me / CAP labels) have every slice moved in "
                                  "its plane so that the contours meet where the slices cross (breath-hold "
                                  "misregistration, reported in the notes), other labelled contours stay as given; "
                                  "none: the slices as given", choices=("auto", "none"))


@dataclass(frozen=True)
class QualityParameters(Parameters):
    """QualityFilter: the radius-ratio histogram."""

    bins: int = parameter(20, "bins of the radius-ratio histogram over [0, 1]", low=1, high=1000, integer=True)


@dataclass(frozen=True)
class OptimizeParameters(Parameters):
    """MeshOptimizer: relax the nodes, remove the slivers, keep the boundary on f = 0.

    ``optimize`` is the one switch of every interface (``--optimize``, ``SetOptimize``, the ParaView and Slicer
    checkbox); the MeshOptimizer filter itself always runs and has only the other fields.
    """

    optimize: int = parameter(1, "1 runs the MeshOptimizer (relaxation, sliver removal) on the valid domain, for "
                              "FEM-grade cells (beyond 3-D the relaxation alone, by new triangulations); 0 skips it: "
                              "the paper's plain method, faster, with slivers",
                              low=0, high=1, integer=True)
    iterations: int = parameter(30, "the most relaxation (ODT smoothing and Delaunay) iterations; the relaxation stops "
                                "earlier once the mean radius ratio stops rising; 0 skips it", low=0, high=1000,
                                integer=True)
    min_dihedral: float = parameter(20.0, "the sliver removal goes on, for a bounded number of rounds, until no cell "
                                    "has a smaller dihedral angle (interior angle in 2D)", unit="degrees", low=0,
                                    high=60, high_open=True)
    min_quality: float = parameter(0.3, "the sliver removal also goes on until no cell has a smaller radius ratio Q",
                                   low=0, high=1, high_open=True)


@dataclass(frozen=True)
class TableParameters(Parameters):
    """Reading a point table: which column is what."""

    columns: str = parameter("", "the role of each column of a text table, comma-separated: x, y, z, nx, ny, nz, "
                             "label, slice, frame or skip (e.g. x,y,z,skip,skip,skip for a table with colours; w, v, "
                             "nw, nv for a fourth and fifth axis); default: from the header's names, else from the "
                             "column count", text=True)
    dimension: Optional[int] = parameter(None, "the coordinates of a point in a text table: its first DIMENSION "
                                         "columns are the point, the next DIMENSION (when there) its outward normal "
                                         "(4 or 5 meshes in that dimension); default: from "
                                         "the header's names, else from the column count (2 or 3)", low=2, high=5,
                                         integer=True)
    frame: Optional[float] = parameter(None, "labelled contours: the time frame to read (a value of the 'time "
                                       "frame' column); default every point (a file whose slices are traced at "
                                       "several frames is refused)", low=0)


@dataclass(frozen=True)
class FidelityParameters(Parameters):
    """Fidelity: how closely the mesh boundary must follow the input points (see bitemesh.core.steps.fidelity)."""

    far_samples: float = parameter(0.5, "the largest share of input points that may lie farther than R + 3 x noise "
                                   "from the mesh boundary", unit="%", low=0, high=100)
    unsupported_area: float = parameter(2.0, "the largest share of the boundary's area that may lie farther than R "
                                        "+ half the data's gap from every input point", unit="%", low=0, high=100)
    allow_unfaithful: int = parameter(0, "1 keeps a mesh that misses these bounds, with a warning, instead of "
                                      "refusing it", low=0, high=1, integer=True)


#: the parameters of the meshing spine's steps, in the order of ``run``'s arguments.
STEP_PARAMETERS = (ImplicitParameters, BitingParameters, SpuriousParameters, OptimizeParameters, FidelityParameters)


def parameters_from_keywords(keywords: dict, classes) -> list:
    """One instance of each parameter dataclass, filled from the keywords named like its fields (each checks its
    ranges); a keyword that names no field is refused with the closest name."""
    owner = {item.name: cls for cls in classes for item in fields(cls)}
    for name in keywords:
        if name not in owner:
            close = difflib.get_close_matches(name, owner, n=1)
            hint = f"did you mean {close[0]}?" if close else "the parameters are " + ", ".join(sorted(owner))
            raise InvalidInputError(f"{name} is not a parameter of this function; {hint}")
    return [cls(**{name: value for name, value in keywords.items() if owner[name] is cls}) for cls in classes]
