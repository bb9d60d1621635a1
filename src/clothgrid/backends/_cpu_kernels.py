"""Numba kernels of the CPU backend, imported on first use (numba's start-up is ~0.5 s)."""

from __future__ import annotations

import numba
import numpy as np

from ..jit_variants import fork_safe


@fork_safe
@numba.njit(parallel=True, cache=True)
def _sweep(r, out, wu, wv):
    nu, nv = r.shape[0], r.shape[1]
    rowmax = np.zeros(nu)
    for i in numba.prange(1, nu - 1):
        m = 0.0
        for j in range(1, nv - 1):
            a = wu[i - 1, j]
            b = wu[i, j]
            c = wv[i, j - 1]
            d = wv[i, j]
            inv = 1.0 / (a + b + c + d)
            s2 = 0.0
            for k in range(3):
                new = (a * r[i - 1, j, k] + b * r[i + 1, j, k] + c * r[i, j - 1, k] + d * r[i, j + 1, k]) * inv
                dlt = new - r[i, j, k]
                s2 += dlt * dlt
                out[i, j, k] = new
            if s2 > m:
                m = s2
        rowmax[i] = m
    return np.sqrt(rowmax.max())
