"""Numba kernel of :func:`clothgrid.patterns.annotations.outline_distance` for large inputs.

Sorting a file's closed outlines (seam allowance around a cut line, the same outline twice)
measures how far one outline's points lie from another closed polyline: every point against
every segment, 400 points against up to 2000 segments a pair. The NumPy form builds
``(256, m, 2)`` temporaries for each block of points and took 1.5 s over the 28 real pattern
files of ``benchmarks/pattern_survey.py``; this kernel keeps nothing but the running minimum.

The arithmetic is the NumPy form's, term by term (the same bits): ``t = clip(((p - a) . ab) /
L2, 0, 1)`` with ``L2 = |ab|^2`` (1 where a segment has no length), the squared distance of ``p``
from ``a + t ab`` summed over the coordinates in order, and the square root of the smallest
(the root is monotone: the root of the minimum is the minimum of the roots).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["dist_to_polyline"]


@njit(cache=True)
def dist_to_polyline(points, poly):
    """Distance of each of ``points`` (``(n, k)`` float64) to the closed polyline ``poly``
    (``(m, k)``, its last point joined to its first)."""
    n, m, k = points.shape[0], poly.shape[0], points.shape[1]
    ab = np.empty((m, k))
    L2 = np.empty(m)
    for s in range(m):
        nxt = s + 1 if s + 1 < m else 0
        acc = 0.0
        for c in range(k):
            ab[s, c] = poly[nxt, c] - poly[s, c]
            acc += ab[s, c] * ab[s, c]
        L2[s] = acc if acc > 0 else 1.0
    out = np.empty(n)
    for i in range(n):
        best = np.inf
        for s in range(m):
            dot = 0.0
            for c in range(k):
                dot += (points[i, c] - poly[s, c]) * ab[s, c]
            t = min(max(dot / L2[s], 0.0), 1.0)
            d2 = 0.0
            for c in range(k):
                e = points[i, c] - (poly[s, c] + t * ab[s, c])
                d2 += e * e
            if d2 < best:
                best = d2
        out[i] = math.sqrt(best)
    return out
