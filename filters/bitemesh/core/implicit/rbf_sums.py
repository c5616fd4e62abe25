"""One RBF patch at many points, compiled: f = sum_j w_j phi(|y - c_j|) + b + a . y and, for the gradient,
sum_j w_j phi'(r_j) / r_j and sum_j w_j phi'(r_j) / r_j c_j; no BLAS, so no BLAS thread count in the values.

The centres are the outer loop and the points of a block the inner one, so that each point's sum runs over the
centres in their order (the same value, bit for bit, whatever the thread count or the vector width) and the inner
loop has no carried sum: the compiler vectorizes it without reassociating anything (about 4 times BLAS's form:
a matrix product with an inner dimension of 3 and five passes over the distances).
"""
from __future__ import annotations

import numpy as np
from numba import prange

from ..compiled import kernel

#: the kernels by number, as :func:`patch_sums` takes them
KERNEL_NUMBERS = {"cubic": 0, "linear": 1, "thin_plate": 2}
#: points a block: the block's coordinates, distances and sums stay in the first-level cache
_BLOCK = 128


@kernel(parallel=True)
def patch_sums(y, centres, weights, polynomial, kind, slope):
    """At (q, k) points ``y`` (the patch's scaled coordinates) of the RBF through (m, k) ``centres`` with (m,)
    ``weights`` and (k + 1,) ``polynomial`` (b, a), kernel number ``kind`` (:data:`KERNEL_NUMBERS`): (q,)
    f = sum_j w_j phi(r_j) + b + a . y and, with ``slope``, (q,) sum_j w_j phi'(r_j) / r_j and (q, k)
    sum_j w_j phi'(r_j) / r_j c_j (else empty)."""
    q, k = y.shape
    values = np.empty(q)
    factors = np.empty(q if slope else 0)
    moments = np.empty((q if slope else 0, k))
    for block in prange((q + _BLOCK - 1) // _BLOCK):
        start = block * _BLOCK
        n = min(_BLOCK, q - start)
        coordinates = np.empty((k, _BLOCK))
        for d in range(k):
            for p in range(n):
                coordinates[d, p] = y[start + p, d]
        squared, r = np.empty(_BLOCK), np.empty(_BLOCK)
        total, factor, moment = np.zeros(_BLOCK), np.zeros(_BLOCK), np.zeros((k, _BLOCK))
        for j in range(len(weights)):
            squared[:n] = 0.0
            for d in range(k):
                c = centres[j, d]
                for p in range(n):
                    t = coordinates[d, p] - c
                    squared[p] += t * t
            w = weights[j]
            for p in range(n):
                r[p] = np.sqrt(squared[p])
            if kind == 0:
                for p in range(n):
                    total[p] += w * (r[p] * r[p] * r[p])
            elif kind == 1:
                for p in range(n):
                    total[p] += w * r[p]
            else:
                for p in range(n):
                    total[p] += w * (r[p] * r[p] * np.log(r[p]) if r[p] > 0 else 0.0)
            if slope:   # w_j phi'(r) / r into r, in place
                if kind == 0:
                    for p in range(n):
                        r[p] = w * (3.0 * r[p])
                elif kind == 1:
                    for p in range(n):
                        r[p] = w / r[p] if r[p] > 0 else 0.0
                else:
                    for p in range(n):
                        r[p] = w * (2.0 * np.log(r[p]) + 1.0 if r[p] > 0 else 1.0)
                for p in range(n):
                    factor[p] += r[p]
                for d in range(k):
                    c = centres[j, d]
                    for p in range(n):
                        moment[d, p] += r[p] * c
        for p in range(n):
            values[start + p] = total[p] + polynomial[0]
        for d in range(k):
            for p in range(n):
                values[start + p] += coordinates[d, p] * polynomial[d + 1]
        if slope:
            for p in range(n):
                factors[start + p] = factor[p]
                for d in range(k):
                    moments[start + p, d] = moment[d, p]
    return values, factors, moments
