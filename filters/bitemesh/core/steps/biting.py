"""Node placement by "biting": Algorithm 1 of Schaerer et al., in any dimension k.

Alive = grid nodes with f > 0.  Repeatedly select an Alive node on the border between Alive and Dead, add it to the
node set X and kill (mark Dead) every Alive node within R of it, until nothing is Alive.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..compiled import kernel
from ..errors import InvalidInputError, MeshingError, check_choice, check_number
from ..grid.sampled import SampledGrid, inside_extents
from ..mesh.topology import sorted_by
from ..progress import ProgressCallback, report

ORDERS = ("boundary", "random")
#: fewer nodes than this cannot make a useful mesh.
MIN_NODES = 8


def ball_offsets(radius: float, spacing: np.ndarray, padded_shape: tuple) -> np.ndarray:
    """Flat-index offsets, in an array of ``padded_shape``, of the grid nodes within ``radius`` of a node."""
    reach = np.floor(radius / spacing).astype(int)
    axes = [np.arange(-r, r + 1) for r in reach]
    index = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(reach))
    inside = np.sum((index * spacing) ** 2, axis=1) < radius**2
    strides = np.cumprod((1,) + padded_shape[:0:-1])[::-1]
    return index[inside] @ strides


def selection_order(grid: SampledGrid, alive: np.ndarray, border: np.ndarray, order: str,
                    rng: np.random.Generator) -> np.ndarray:
    """The flat indices of the Alive nodes in the order SelectNode visits them.

    ``boundary``: first the border layer (Alive nodes with a Dead axis neighbour) as a front that advances over the
    surface from a seeded start (by distance from it), which packs the surface nodes densely; then the others by
    increasing f, a front advancing inward.  Every pick is on the border between Alive and Dead.
    ``random``: a seeded shuffle.  Ties are broken by the seeded generator.
    """
    candidates = np.flatnonzero(alive)
    tie_break = rng.random(candidates.size)
    if order == "random":
        return candidates[np.argsort(tie_break)]
    on_border = border.ravel()[candidates]
    layer = np.flatnonzero(on_border)   # the border layer first, by distance from a seeded start
    start = grid.node_coordinates(candidates[layer[rng.integers(layer.size)]][None])
    distance = np.linalg.norm(grid.node_coordinates(candidates[layer]) - start, axis=1)
    ordered = np.empty_like(candidates)
    _sort_into(ordered[:layer.size], candidates[layer], distance, tie_break[layer])
    first, layer = layer.size, np.flatnonzero(~on_border)   # then the others by f
    inner, tie_break = candidates[layer], tie_break[layer]
    del candidates, layer   # the sort's memory, 48 bytes an Alive node at most, is the biting's largest
    _sort_into(ordered[first:], inner, grid.node_values(inner), tie_break)
    return ordered


def _sort_into(out: np.ndarray, items: np.ndarray, key: np.ndarray, tie: np.ndarray) -> None:
    """``out`` (n,) = ``items`` (n,) ordered by ``key``, equal keys by ``tie``, then by position (what
    ``items[np.lexsort((tie, key))]`` gives), sorted by one quicksort and the runs of equal keys put in order after."""
    order = np.argsort(key)
    _order_runs(order, key, tie)
    np.take(items, order, out=out)


@kernel
def _order_runs(order, key, tie) -> None:
    """Within each run of equal ``key[order]``, order ``order`` (n,) by (tie, index), in place."""
    start = 0
    for end in range(1, order.size + 1):
        if end < order.size and key[order[end]] == key[order[start]]:
            continue
        if end - start > 1:
            order[start:end] = sorted_by(order[start:end], tie)
        start = end


@kernel
def _bite_block(ordered, start, stop, shape, padded_shape, pads, alive, offsets):
    """SelectNode and KillNodes over ``ordered[start:stop]`` (C-order flat indices of a grid of ``shape`` (k,)): the
    positions in ``ordered`` of the nodes still Alive in ``alive``, the flat padded grid (``pads`` (k,) nodes added
    on each side of each axis, ``padded_shape`` (k,)), each killing the Alive nodes at ``offsets`` from it."""
    selected = np.empty(stop - start, np.int64)
    count = 0
    for position in range(start, stop):
        rest, node, stride = ordered[position], 0, 1
        for axis in range(len(shape) - 1, -1, -1):
            rest, index = divmod(rest, shape[axis])
            node += (index + pads[axis]) * stride
            stride *= padded_shape[axis]
        if alive[node]:
            selected[count] = position
            count += 1
            for offset in offsets:
                alive[node + offset] = False
    return selected[:count]


def interface_border(grid: SampledGrid, alive: np.ndarray, interfaces) -> np.ndarray:
    """The Alive grid nodes with an Alive axis neighbour in another region (``interfaces.node_regions``)."""
    inside = np.flatnonzero(alive.ravel())
    region = np.full(alive.shape, -1)
    region.ravel()[inside] = interfaces.node_regions(grid.node_coordinates(inside))
    border = np.zeros(alive.shape, bool)
    for axis in range(alive.ndim):
        ahead, behind = [slice(None)] * alive.ndim, [slice(None)] * alive.ndim
        ahead[axis], behind[axis] = slice(1, None), slice(None, -1)
        ahead, behind = tuple(ahead), tuple(behind)
        differ = alive[ahead] & alive[behind] & (region[ahead] != region[behind])
        border[ahead] |= differ
        border[behind] |= differ
    return border


def bite(grid: SampledGrid, radius: float, *, order: str = "boundary", seed: int = 0, jitter: float = 0.15,
         progress: ProgressCallback = None, interfaces=None) -> np.ndarray:
    """Place mesh nodes at least about ``radius`` apart inside {f > 0}.

    Parameters
    ----------
    grid : the implicit function sampled on the grid I
    radius : R, minimum distance between nodes (input units); from 2 grid spacings to the shape's extent
    order : ``"boundary"`` (border first, then inward) or ``"random"``
    seed : seed of the generator that breaks ties and jitters the nodes
    jitter : interior nodes move by up to ``jitter`` grid spacings per axis, so qhull never sees an exact lattice
    interfaces : regions inside {f > 0} whose interfaces are sampled like the boundary (a
        :class:`~bitemesh.core.mesh.interfaces.LabelRegions`: ``node_regions(points)``, ``onto_interfaces(points,
        reach, surface)``), or None.  Given, the grid nodes next to another region's join the border layer, and
        their nodes go onto the interface (those on the border too: onto where the interface meets f = 0)

    Returns
    -------
    nodes : (n, k) float64, node coordinates (input units)
    """
    check_choice(order, "order", ORDERS)
    check_number(jitter, "jitter", low=0, high=0.5)
    spacing = grid.spacing
    alive = grid.inside()
    if not alive.any():
        raise InvalidInputError("the implicit function is positive nowhere on the grid (nothing is inside); "
                                "check the normals' orientation and the grid's extent")
    extent = float(np.min(inside_extents(alive) * spacing)) + float(np.max(spacing))
    check_number(radius, "radius", low=0, low_open=True, high=extent,
                 hint="radius is R, the node spacing; it cannot exceed the extent of the shape")
    check_number(radius, "radius", low=2 * float(np.max(spacing)),
                 hint=f"the grid must resolve it: radius >= 2 x grid_spacing ({float(np.max(spacing)):g}); "
                      "lower grid_spacing for a smaller radius")
    rng = np.random.default_rng(seed)

    # Pad so that a ball around any node stays inside the array: KillNodes is then one flat fancy-index per bite.
    pad = int(np.ceil(radius / np.min(spacing)))
    padded = np.pad(alive, pad)
    offsets = ball_offsets(radius, spacing, padded.shape)
    border = alive & ~ndimage.binary_erosion(alive, border_value=0)
    between = None if interfaces is None else interface_border(grid, alive, interfaces)
    ordered = selection_order(grid, alive, border if between is None else border | between, order, rng)
    shape, padded_shape = (np.array(a.shape, np.int64) for a in (alive, padded))
    pads = np.full(alive.ndim, pad, np.int64)
    selected, chunk = [], 1 << 20
    for start in range(0, ordered.size, chunk):
        report(progress, start / ordered.size, "biting")
        selected.append(_bite_block(ordered, start, min(start + chunk, ordered.size), shape, padded_shape, pads,
                                    padded.ravel(), offsets))
    report(progress, 1.0, "biting")
    chosen = ordered[np.concatenate(selected)]
    if chosen.size < MIN_NODES:
        raise InvalidInputError(
            f"radius is too large for the shape: it leaves only {chosen.size} nodes "
            f"(at least {MIN_NODES} are needed); use a smaller radius")

    nodes = grid.node_coordinates(chosen) + rng.uniform(-jitter, jitter, (chosen.size, grid.dim)) * spacing
    on_border = border.ravel()[chosen]   # the nodes of the border layer go onto f = 0
    nodes[on_border] = grid.project(nodes[on_border])
    if between is not None:   # and those next to another region onto the interface (on the border: where the
        reach = 4 * float(np.max(spacing))    # interface meets f = 0), as far as the border's go
        for layer, surface in ((between & ~border, None), (between & border, grid)):
            chosen_layer = layer.ravel()[chosen]
            nodes[chosen_layer] = interfaces.onto_interfaces(nodes[chosen_layer], reach, surface)
    if not np.isfinite(nodes).all():
        raise MeshingError("projecting the border nodes onto f = 0 failed (non-finite coordinates); "
                           "the implicit function may be flat there: try a finer grid_spacing")
    return nodes
