"""CPU backend: fused Numba kernels over ``(nu, nv, 3)`` float64 grids.

Each kernel works on the whole grid at once, boundary nodes untouched, and is
parallel over rows ``i`` (``numba.prange``). Edge weights follow
:mod:`clothgrid.weights`: ``wu (nu-1, nv)``, ``wv (nu, nv-1)``.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["name", "sweep", "max_step", "residual", "sweeps"]

name = "cpu"


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


@numba.njit(parallel=True, cache=True)
def _max_step(r, wu, wv):
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
            if s2 > m:
                m = s2
        rowmax[i] = m
    return np.sqrt(rowmax.max())


@numba.njit(parallel=True, cache=True)
def _residual(r, wu, wv, out):
    nu, nv = r.shape[0], r.shape[1]
    for i in numba.prange(1, nu - 1):
        for j in range(1, nv - 1):
            a = wu[i - 1, j]
            b = wu[i, j]
            c = wv[i, j - 1]
            d = wv[i, j]
            for k in range(3):
                x = r[i, j, k]
                out[i - 1, j - 1, k] = (a * (r[i - 1, j, k] - x) + b * (r[i + 1, j, k] - x)
                                        + c * (r[i, j - 1, k] - x) + d * (r[i, j + 1, k] - x))
    return out


def sweep(r: np.ndarray, out: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> float:
    """One Jacobi sweep (eq. 3 with per-edge weights) from ``r`` into ``out``.

    ``out`` must already hold the boundary nodes. Returns the largest
    Euclidean node step ``max |out[i, j] - r[i, j]|`` of the sweep.
    """
    return float(_sweep(r, out, wu, wv))


def max_step(r: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> float:
    """The largest step a Jacobi sweep would make from ``r``, without making it.

    This is ``max |D^-1 (b - A r)|``: the Jacobi-scaled residual, used in the
    a-posteriori error bound of :mod:`clothgrid.solvers.bounds`.
    """
    return float(_max_step(r, wu, wv))


def residual(r: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> np.ndarray:
    """``b - A r`` over the interior nodes, as an ``(nu-2, nv-2, 3)`` array.

    The unscaled residual of the SPD system of :mod:`clothgrid.solvers.problem`:
    ``sum over the four edges of w * (R[neighbour] - R[i, j])``.
    """
    out = np.empty((r.shape[0] - 2, r.shape[1] - 2, 3))
    return _residual(r, wu, wv, out)


def sweeps(r: np.ndarray, wu: np.ndarray, wv: np.ndarray, count: int, scratch: np.ndarray | None = None):
    """Run ``count`` Jacobi sweeps in place on ``r``; return the last step.

    ``scratch`` (same shape as ``r``, boundary set) is reused when given.
    """
    if scratch is None:
        scratch = r.copy()
    step = 0.0
    a, b = r, scratch
    for _ in range(count):
        step = sweep(a, b, wu, wv)
        a, b = b, a
    if a is not r:
        r[...] = a
    return step
