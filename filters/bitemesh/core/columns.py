"""What the columns of a point table and the point arrays of a dataset are called: one table of names, shared by
the readers (bitemesh.io) and the VTK filters (bitemesh.convert), so that both understand the same files."""
from __future__ import annotations

import re

#: the coordinates a point may have, in order (2 to 5 of them): w and v only beyond 3-D, named by --columns or
#: --dimension (a header's "w" or "v" is more often a weight or a value than a fourth axis).
AXES = ("x", "y", "z", "w", "v")
#: what a column may be.
ROLES = (*AXES, *(f"n{axis}" for axis in AXES), "label", "slice", "frame", "skip")
#: names (see :func:`normalised`) -> role.  A GPFile's label is "contour type", its slice "frameID" (or "sliceID")
#: and its "time frame" the cardiac phase (role "frame").
NAMES = {
    **{name: axis for axis in "xyz" for name in (axis, f"pos{axis}", f"position{axis}", f"point{axis}",
                                                   f"coord{axis}", f"coordinate{axis}", f"{axis}coord")},
    **{name: f"n{axis}" for axis in "xyz" for name in (f"n{axis}", f"normal{axis}", f"normals{axis}")},
    **{name: "label" for name in ("label", "labels", "contourtype", "type", "region", "surface")},
    **{name: "slice" for name in ("frameid", "sliceid", "slice", "sliceindex", "imageid")},
    **{name: "frame" for name in ("timeframe", "time", "frame", "phase", "cardiacphase", "timeframeid")},
}
#: names read past with a note: what point clouds and biv-me files carry beside the coordinates.
KNOWN_OTHERS = ("r", "g", "b", "a", "red", "green", "blue", "alpha", "intensity", "i", "weight", "scalar", "value",
                "confidence", "curvature", "id", "index")


def normalised(name: str) -> str:
    """A column or array name as a key of :data:`NAMES`: lower case, without units in brackets, spaces,
    underscores, dots and dashes ("Contour type" -> "contourtype", "X [mm]" -> "x")."""
    return re.sub(r"[\s_.\-]", "", re.sub(r"[\[(].*?[\])]", "", str(name).lower()))


def role(name: str) -> str:
    """The role (:data:`ROLES`) of a column or array name; "skip" for names it does not know."""
    return NAMES.get(normalised(name), "skip")
