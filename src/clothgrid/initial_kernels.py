"""Numba kernel of :mod:`clothgrid.initial` for large grids: the transfinite interpolation in one pass.

The NumPy form (:func:`clothgrid.initial.transfinite`) runs four whole-array passes with a
temporary each over blocks of rows: 17-24 ms at 1024^2 nodes (x, y, z). This kernel writes each
interior node once, rows in parallel, with the NumPy form's arithmetic term by term, in its order
(the same bits: a test checks it on fresh grids).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .jit_variants import fork_safe

__all__ = ["transfinite_into"]


@fork_safe
@njit(cache=True, parallel=True)
def transfinite_into(r, u, v):
    """Fill the interior of ``r`` (``(nu, nv, d)``, C-contiguous) from its boundary by eq. (4).

    ``u``, ``v``: ``np.linspace(0, 1, nu)`` and ``np.linspace(0, 1, nv)``. Regrouped as
    ``(1-u) L'(v) + u R'(v) + (1-v) B(u) + v T(u)``, where ``L'`` and ``R'`` are the sides at
    ``i = 0`` and ``i = nu-1`` less the corners' linear interpolation, summed in that order.
    """
    nu, nv, d = r.shape
    left = np.empty((nv, d))
    right = np.empty((nv, d))
    for j in range(1, nv - 1):
        vj = v[j]
        for c in range(d):
            left[j, c] = r[0, j, c] - ((1 - vj) * r[0, 0, c] + vj * r[0, nv - 1, c])
            right[j, c] = r[nu - 1, j, c] - ((1 - vj) * r[nu - 1, 0, c] + vj * r[nu - 1, nv - 1, c])
    for a in prange(nu - 2):
        i = a + 1
        ui = u[i]
        for j in range(1, nv - 1):
            vj = v[j]
            for c in range(d):
                o = (1 - ui) * left[j, c]
                o += ui * right[j, c]
                o += (1 - vj) * r[i, 0, c]
                o += vj * r[i, nv - 1, c]
                r[i, j, c] = o
