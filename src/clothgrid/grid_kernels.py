"""Numba kernels of :mod:`clothgrid.grid` for large grids: the arc-length ``uv`` in one pass, and
the ``(i, j)`` places of a mask's true entries (:func:`mask_places`, NumPy's ``argwhere`` of a 2D mask
in parallel rows: the fold-free step's node lists and the quality's folded cells).

The NumPy form (:func:`clothgrid.grid.arc_length_uv`) builds the edge vectors, their lengths
and strided running sums as full-size temporaries: about 50 ms at 1024^2 nodes, a quarter of
the command's write. This kernel reads each node twice and writes ``uv`` once, with the NumPy
form's arithmetic term by term (the same bits: tests check it on fresh grids).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .jit_variants import fork_safe

__all__ = ["arc_length_uv_into", "mask_places"]

#: columns per block of the u pass (the running sums of a block stay in the cache)
_COLUMNS = 256


@fork_safe
@njit(cache=True, parallel=True)
def arc_length_uv_into(P, uv, flat_u, flat_v):
    """Write the normalised arc-length parameters of ``P`` (``(nu, nv, 3)``) into ``uv``.

    ``uv[..., 0]`` runs along ``i`` (each column ``j``), ``uv[..., 1]`` along ``j`` (each row
    ``i``). A line of total length 0 is marked in ``flat_u[j]`` / ``flat_v[i]`` and left for the
    caller (its parameters are uniform).
    """
    nu, nv = P.shape[0], P.shape[1]
    for r in prange(nu):                      # v: along each row i
        i = np.int64(r)
        uv[i, 0, 1] = 0.0
        s = 0.0
        for j in range(1, nv):
            dx = P[i, j, 0] - P[i, j - 1, 0]
            dy = P[i, j, 1] - P[i, j - 1, 1]
            dz = P[i, j, 2] - P[i, j - 1, 2]
            s += math.sqrt(dx * dx + dy * dy + dz * dz)
            uv[i, j, 1] = s
        flat_v[i] = not s > 0
        if s > 0:
            for j in range(nv):
                uv[i, j, 1] /= s
    blocks = (nv + _COLUMNS - 1) // _COLUMNS
    for b in prange(blocks):                  # u: along each column j, a block of columns at a time
        j0 = b * _COLUMNS
        j1 = min(nv, j0 + _COLUMNS)
        acc = np.zeros(j1 - j0)
        for j in range(j0, j1):
            uv[0, j, 0] = 0.0
        for i in range(1, nu):
            for j in range(j0, j1):
                dx = P[i, j, 0] - P[i - 1, j, 0]
                dy = P[i, j, 1] - P[i - 1, j, 1]
                dz = P[i, j, 2] - P[i - 1, j, 2]
                acc[j - j0] += math.sqrt(dx * dx + dy * dy + dz * dz)
                uv[i, j, 0] = acc[j - j0]
        for j in range(j0, j1):
            flat_u[j] = not acc[j - j0] > 0
        for i in range(1, nu):
            for j in range(j0, j1):
                t = acc[j - j0]
                if t > 0:
                    uv[i, j, 0] /= t


@fork_safe
@njit(cache=True, parallel=True)
def _mask_places(mask, out, starts):
    """Fill ``out`` (``(K, 2)``) with the true entries' places, row ``i``'s from ``starts[i]``."""
    for r in prange(mask.shape[0]):
        i = np.int64(r)
        q = starts[i]
        for j in range(mask.shape[1]):
            if mask[i, j]:
                out[q, 0], out[q, 1] = i, j
                q += 1


@njit(cache=True, inline="always")
def row_counts_into(mask, counts):
    """``counts[i + 1]``: how many entries of row ``i`` of a 2D bool ``mask`` are true, rows in
    ``prange`` (parallel where the kernel it is inlined into is)."""
    for r in prange(mask.shape[0]):
        c = 0
        for j in range(mask.shape[1]):
            if mask[r, j]:
                c += 1
        counts[r + 1] = c


@fork_safe
@njit(cache=True, parallel=True)
def _row_counts(mask, counts):
    """:func:`row_counts_into`, rows in parallel."""
    row_counts_into(mask, counts)


#: below this many entries a mask is listed by NumPy (a parallel kernel's start costs more)
_PARALLEL_ENTRIES = 1 << 16


def mask_places(mask: np.ndarray) -> np.ndarray:
    """``(K, 2)`` int64 places ``(i, j)`` of the true entries of a 2D bool ``mask``, row by row:
    ``numpy.argwhere(mask)``, without its index arrays (rows counted, then listed, in parallel)."""
    mask = np.ascontiguousarray(mask, dtype=np.bool_)
    if mask.ndim != 2:
        raise ValueError(f"a 2D mask, not shape {mask.shape}")
    if mask.size < _PARALLEL_ENTRIES:
        return np.argwhere(mask).astype(np.int64)
    starts = np.zeros(mask.shape[0] + 1, np.int64)
    _row_counts(mask, starts)
    np.cumsum(starts, out=starts)
    out = np.empty((int(starts[-1]), 2), np.int64)
    _mask_places(mask, out, starts)
    return out
