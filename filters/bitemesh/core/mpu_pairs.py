"""The (leaf, point) pairs of the MPU evaluation at grid nodes, found from the grid's structure.

A leaf with centre c and support radius R pairs with the nodes x where |x - c| <= R; its candidates are the grid rows
(nodes with the same first two indices) its support sphere crosses, the z range of each row's chord, and the test is
the one ``cKDTree.sparse_distance_matrix`` makes, on the same squared distance.  The pairs are listed in the blocks
of :data:`bitemesh.core.mpu_function._PAIR_BLOCK` that the k-d tree's listing of them would give, each point's pairs
in the same order, so the sums over them are bit-identical to the k-d tree's (:func:`lattice_pairs`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

#: candidate nodes are sought this much (relative) beyond a support radius, then tested exactly.
_REACH = 1.0 + 1e-6
#: scipy's ``ckdtreenode``, the items of a cKDTree's node array (_less, _greater: the children's places in it).
_NODE = np.dtype([("split_dim", np.intp), ("children", np.intp), ("split", np.float64), ("start_idx", np.intp),
                  ("end_idx", np.intp), ("less", np.uintp), ("greater", np.uintp), ("_less", np.intp),
                  ("_greater", np.intp)])


@dataclass(frozen=True)
class TreeOrder:
    """Where each point of a ``cKDTree`` sits in its leaves, numbered depth first (the lesser side first).

    Attributes
    ----------
    leaf : (n,) int64, the leaf of each point (by its index in the tree's data)
    local : (n,) int64, the point's place in its leaf's slice of ``tree.indices``
    depth : (k,) int64, each leaf's depth (the root's is 0)
    path : (k,) int64, each leaf's turns from the root as bits, the first turn highest (1 = the greater side)
    """

    leaf: np.ndarray
    local: np.ndarray
    depth: np.ndarray
    path: np.ndarray

    @classmethod
    def of(cls, tree: cKDTree, *, by_place: bool = False) -> TreeOrder | None:
        """The tree's order, read from its node array (its pickled state), or None where that is not laid out as
        ``ckdtreenode`` (:data:`_NODE`) or does not describe the tree; by_place: the points numbered by their
        place in ``tree.indices``, not in the data."""
        buffer = tree.__getstate__()[0]
        if not isinstance(buffer, np.ndarray) or buffer.nbytes % _NODE.itemsize:
            return None
        nodes = np.frombuffer(buffer.tobytes(), dtype=_NODE)
        found, level, path = [], np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64)
        for depth in range(64):   # breadth first
            node = nodes[level]
            leaf = node["split_dim"] == -1
            found.append((node["start_idx"][leaf], node["end_idx"][leaf], np.full(leaf.sum(), depth), path[leaf]))
            level, path = np.stack([node["_less"][~leaf], node["_greater"][~leaf]], axis=1).ravel(), \
                np.stack([2 * path[~leaf], 2 * path[~leaf] + 1], axis=1).ravel()
            if not len(level) or level.min() < 0 or level.max() >= len(nodes):
                break
        start, end, depth, path = (np.concatenate(column) for column in zip(*found))
        order = np.argsort(start)   # depth first
        start, end, depth, path = start[order], end[order], depth[order], path[order]
        if len(level) or start[0] != 0 or end[-1] != tree.n or np.any(start[1:] != end[:-1]) \
                or np.any(end <= start):
            return None
        place = np.arange(tree.n)
        if not by_place:
            place[tree.indices] = np.arange(tree.n)
        leaf = np.repeat(np.arange(len(start)), end - start)[place]
        return cls(leaf=leaf, local=place - start[leaf], depth=depth, path=path)


def traversal_keys(first: TreeOrder, second: TreeOrder, i: np.ndarray, j: np.ndarray):
    """(p,) int64 keys that sort the pairs (point i of the first tree, point j of the second) as
    ``first.sparse_distance_matrix(second)`` lists them; None where that takes more than 63 bits.

    The dual traversal descends both trees at once, the lesser sides first: while both nodes are inner, step k
    turns both (the digit 2 a_k + b_k of the turns a_k, b_k), then only the deeper tree's (a_k or b_k); in a pair of
    leaves it lists the first's points, each with the second's in order.
    """
    steps = int(max(first.depth.max(), second.depth.max()))
    low_first = int(first.local.max()).bit_length()
    low_second = int(second.local.max()).bit_length()
    if 2 * steps + low_first + low_second > 63:
        return None
    k = np.arange(1, steps + 1)
    place = 2 * (steps - k)

    def turns(order: TreeOrder) -> np.ndarray:
        """(leaves, steps) the turn a_k of each leaf's path at step k, 0 past its depth."""
        ahead = order.depth[:, None] - k
        return np.where(ahead >= 0, order.path[:, None] >> np.maximum(ahead, 0), 0) & 1

    # a_k is the high bit of step k's digit where the second tree's leaf is k or more deep, else the low one; the
    # two trees' bits never overlap, so the key is the sum of a part of i (given the depth of j's leaf) and one of j.
    high = (k <= np.arange(steps + 1)[:, None]).astype(np.int64)                 # (second's depth, steps)
    shift = low_first + low_second
    part_first = (((turns(first)[:, None, :] << (place + high)).sum(axis=2) << shift)[first.leaf]
                  | (first.local << low_second)[:, None])                        # (n_first, steps + 1)
    part_second = ((turns(second) << place).sum(axis=1) << shift)[second.leaf] | second.local
    return part_first.reshape(-1)[i * (steps + 1) + second.depth[second.leaf][j]] + part_second[j]


def _expand(start: np.ndarray, stop: np.ndarray):
    """(owner, position) of the ranges [start, stop), one after another: the range's index and each position."""
    count = np.maximum(stop - start, 0)
    owner = np.repeat(np.arange(len(count)), count)
    return owner, np.arange(len(owner)) - np.repeat(np.cumsum(count) - count - start, count)


class _Nodes:
    """Grid nodes in C order, ``x[:, d] = axes[d][index[d]]`` on uniform axes, and the lookups their search needs."""

    #: the flat-index span of the nodes up to which positions are looked up in a table (x the node count).
    TABLE_SPAN = 64

    def __init__(self, x: np.ndarray, index: tuple, axes: tuple, flat: np.ndarray):
        self.axes, self.flat, self.height = axes, flat, np.ascontiguousarray(x[:, 2])
        self.first = np.array([i.min() for i in index])
        self.last = np.array([i.max() for i in index])
        self.lower = np.array([a[i] for a, i in zip(axes, self.first)])
        self.upper = np.array([a[i] for a, i in zip(axes, self.last)])
        self.origin = np.array([a[0] for a in axes])
        self.step = np.array([(a[-1] - a[0]) / (len(a) - 1) if len(a) > 1 else 1.0 for a in axes])
        span = int(flat[-1] - flat[0]) + 2
        self.before = None
        if span <= self.TABLE_SPAN * len(flat):
            marks = np.zeros(span, dtype=np.int64)
            marks[flat - flat[0] + 1] = 1
            self.before = np.cumsum(marks)

    def position(self, key: np.ndarray) -> np.ndarray:
        """``np.searchsorted(flat, key)``: how many nodes precede the flat indices ``key``."""
        if self.before is None:
            return np.searchsorted(self.flat, key)
        return self.before[np.clip(key - self.flat[0], 0, len(self.before) - 1)]

    def span(self, axis: int, centre: np.ndarray, half: np.ndarray):
        """(first, stop) indices along ``axis`` of the nodes within ``half`` of ``centre``, a few more at most
        (the axes are uniform to rounding, far finer than the reach beyond a support radius)."""
        u = (centre - self.origin[axis]) / self.step[axis]
        w = half / self.step[axis]
        return (np.clip(np.ceil(u - w), self.first[axis], self.last[axis] + 1).astype(np.int64),
                np.clip(np.floor(u + w) + 1, self.first[axis], self.last[axis] + 1).astype(np.int64))


def _group_pairs(centres, radius: float, nodes: _Nodes):
    """(centre, node, distance) with |x_node - c| <= radius for (L, 3) centres, by centre (in their order), then
    node: the grid rows (first two indices) within the support disc, each over its chord."""
    reach = radius * _REACH
    near = np.flatnonzero(np.all((centres + reach >= nodes.lower) & (centres - reach <= nodes.upper), axis=1))
    c = centres[near].T
    axes = nodes.axes
    start, stop = nodes.span(0, c[0], reach)
    owner, i0 = _expand(start, stop)                                   # (centre, plane)
    dx = c[0, owner] - axes[0][i0]
    start, stop = nodes.span(1, c[1, owner], np.sqrt(np.maximum(reach * reach - dx * dx, 0.0)))
    plane, i1 = _expand(start, stop)                                   # (centre, row) in C order
    owner, i0 = owner[plane], i0[plane]
    dy = c[1, owner] - axes[1][i1]
    across = dx[plane] * dx[plane] + dy * dy
    height = c[2, owner]
    start, stop = nodes.span(2, height, np.sqrt(np.maximum(reach * reach - across, 0.0)))
    base = (i0 * len(axes[1]) + i1) * len(axes[2])
    start = nodes.position(base + start)
    count = np.maximum(nodes.position(base + stop) - start, 0)
    node = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count - start, count)
    # |c - x|^2 summed over the axes in order, as the k-d tree does
    dz = np.repeat(height, count) - nodes.height[node]
    square = np.repeat(across, count) + dz * dz
    centre = np.repeat(near[owner], count)
    within = square <= radius * radius
    if not within.all():
        centre, node, square = centre[within], node[within], square[within]
    return centre, node, np.sqrt(square)


def lattice_pairs(groups, x: np.ndarray, index: tuple, axes: tuple, block: int):
    """(leaf, point, distance) of the pairs |x_point - c_leaf| <= R_leaf at grid nodes, or None where the nodes are
    not in C order or the pairs' order cannot be keyed (then the k-d tree's own listing is needed).

    Listed so that consecutive slices of ``block`` pairs hold the same pairs, with each point's in the same order,
    as the slices of the k-d tree listing: the groups' ``tree.sparse_distance_matrix(cKDTree(x), radius)``
    one after another.

    Parameters
    ----------
    groups : per support radius (radius, (g,) its leaves' indices, (g, 3) their centres, the :class:`TreeOrder`
        of their k-d tree by place, or None), the leaves in the order of the tree's ``indices``
    x : (m, 3) float64, grid nodes, ``x[:, d] = axes[d][index[d]]``, their C-order flat indices ascending
    index : 3 (m,) int64 arrays, the nodes' grid indices; axes : 3 ascending float64 arrays, the node coordinates
    """
    flat = np.ravel_multi_index(index, tuple(len(a) for a in axes))
    if np.any(np.diff(flat) <= 0):
        return None
    nodes = _Nodes(x, index, axes, flat)
    queries = None
    parts, offset = [], 0
    for radius, leaf, centres, order in groups:
        position, point, distance = _group_pairs(centres, radius, nodes)
        blocks = np.arange(offset // block + 1, (offset + len(point) - 1) // block + 1)
        if len(blocks):
            # a block boundary inside this group: rank its pairs as the dual traversal lists them
            if queries is None:
                queries = TreeOrder.of(cKDTree(x))
            keys = None if order is None or queries is None else traversal_keys(order, queries, position, point)
            if keys is None:
                return None
            ranks = blocks * block - offset
            bounds = np.partition(keys, ranks)[ranks]
            ordered = np.argsort(np.searchsorted(bounds, keys, "right").astype(np.uint16), kind="stable")  # radix
            position, point, distance = position[ordered], point[ordered], distance[ordered]
        parts.append((leaf[position], point, distance))
        offset += len(point)
    return tuple(np.concatenate(column) for column in zip(*parts))
