"""A-posteriori error bounds for any approximate solution.

``A`` (MATH.md) is an M-matrix, so ``(D^-1 A)^-1 >= 0`` and for any grid ``R``
with the right boundary nodes, ``s = D^-1 (b - A R)`` (the step one Jacobi sweep
would take) bounds the error node by node:

    |R*[i,j] - R[i,j]| <= max|s| * z[i,j],     where D^-1 A z = 1, z >= 0 on the boundary.

For separable weights with constant ``cu``, ``cv`` (the paper's and uniform
weights) ``z[i,j] = i (nu-1-i) + j (nv-1-j)`` solves ``D^-1 A z = 1`` exactly, so
the bound costs one residual evaluation. For other weights ``z`` takes one
extra linear solve (``A z = D 1``), done with whatever factorisation is at hand.
Distances are Euclidean per node (the triangle inequality carries the bound
over from one coordinate to the 3-vector).

**Band barriers** (:class:`BandBarriers`, same weights). ``max|s| * max z`` is
hundreds to 10^5 times the true error, because ``s`` peaks within a few lines of
the boundary, where the error's real sensitivity to it is small. Any ``W >= 0``
on the boundary with ``D^-1 A W >= |s|`` bounds the error node by node (the same
maximum principle), and for a band of width ``w`` (lines ``1 .. w-1`` from each
side) the function ``B_w[i, j] = F(i) + F(j)``, ``F(t) = min(phi(t), phi(n-1-t))``,
``phi(t) = t (2w - t)`` up to ``w`` and ``w^2`` beyond, is concave along each line,
so ``D^-1 A B_w >= (a [i in band] + b [j in band]) / (a + b)`` (``a``, ``b`` the
node's couplings along ``i`` and ``j``), and ``max B_w = 2 w^2``. Each node is
charged to the cheapest of: ``z`` (cost ``max z``), its narrowest band (cost
``2 w^2`` over that coverage) or the band holding it in both directions (cost
``2 w^2``), and

    |R* - R| <= alpha max z + sum_k beta_k 2 w_k^2,

``alpha`` the largest ``|s|`` charged to ``z`` and ``beta_k`` the largest
``|s| / coverage`` charged to band ``k`` (widths 2, 4, 8, ...). On the T-shirt
front at 1024^2 this is 160-250x the true error with the paper's weights and
about 100x with uniform ones, against 800-3600x and 10^5x for ``max|s| max z``;
the solve stops one to three V-cycles sooner (docs/performance.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..backends.protocol import Backend
from .problem import Problem

__all__ = ["BandBarriers", "band_steps", "barrier_max", "error_bound"]


def _analytic_barrier_max(nu: int, nv: int) -> float:
    hu, hv = (nu - 1) // 2, (nv - 1) // 2
    return float(hu * (nu - 1 - hu) + hv * (nv - 1 - hv))


def barrier_max(problem: Problem, solve: Callable[[np.ndarray], np.ndarray] | None = None) -> float:
    """``max z`` of the barrier function ``D^-1 A z = 1``.

    Parameters
    ----------
    problem : Problem
    solve : callable, optional
        ``solve(rhs)`` returning ``A^-1 rhs`` for an ``(nu-2)*(nv-2)`` vector;
        needed only for weights without the analytic barrier. Without it a
        sparse direct solve is made.
    """
    nu, nv = problem.shape
    if problem.weights.unit_stencil:
        return _analytic_barrier_max(nu, nv)
    d = problem.diagonal().ravel()
    if solve is None:
        from scipy.sparse.linalg import splu

        lu = splu(problem.interior_matrix(), permc_spec="MMD_AT_PLUS_A")
        solve = lu.solve
    return float(np.max(solve(d)))


def error_bound(points: Any, problem: Problem, backend: Backend, zmax: float, weights: tuple | None = None) -> float:
    """Guaranteed bound on ``max |R* - R|`` (absolute) for the grid ``points``.

    ``weights``: ``(wu, wv)`` as arrays of the backend where ``points`` lives
    (a GPU's); by default the problem's own.
    """
    wu, wv = weights if weights is not None else (problem.weights.wu, problem.weights.wv)
    return backend.max_step(points, wu, wv) * zmax


@dataclass(frozen=True)
class BandBarriers:
    """The band barriers of an ``nu x nv`` grid with unit-stencil weights (module docstring).

    Attributes
    ----------
    zmax : float
        ``max z`` of the whole-grid barrier.
    cost : numpy.ndarray
        ``(K,)`` float64: ``2 w_k^2``, the largest value of band ``k``'s barrier
        (widths ``w_k = 2, 4, 8, ...`` up to ``(min(nu, nv) - 1) / 2``).
    ku, kv : numpy.ndarray
        ``(nu,)`` and ``(nv,)`` int64: the narrowest band holding line ``i``
        (``j``), ``K`` for none.
    """

    zmax: float
    cost: np.ndarray
    ku: np.ndarray
    kv: np.ndarray

    @classmethod
    def for_grid(cls, nu: int, nv: int) -> "BandBarriers":
        widths = []
        w = 2
        while w <= (min(nu, nv) - 1) // 2:
            widths.append(w)
            w *= 2
        wk = np.array(widths, dtype=np.int64)

        def band(n: int) -> np.ndarray:
            t = np.arange(n)
            return np.searchsorted(wk, np.minimum(t, n - 1 - t), side="right").astype(np.int64)

        return cls(_analytic_barrier_max(nu, nv), 2.0 * wk.astype(np.float64) ** 2, band(nu), band(nv))

    @property
    def bands(self) -> int:
        return len(self.cost)

    def bound(self, steps: np.ndarray) -> float:
        """The error bound from :func:`band_steps`' answer (absolute, never above ``max|s| max z``)."""
        K = self.bands
        banded = float(steps[K]) * self.zmax + float(np.dot(steps[:K], self.cost))
        return min(banded, float(steps[K + 1]) * self.zmax)


def band_steps(points: np.ndarray, weights: Any, barriers: BandBarriers) -> np.ndarray:
    """What :meth:`BandBarriers.bound` needs of a grid, in NumPy (the reference of the kernels).

    Returns the ``(K + 2,)`` array ``beta_0 .. beta_{K-1}, alpha, max|s|`` (module docstring) for
    ``s = D^-1 (b - A R)`` of ``points`` (``(nu, nv, k)``, zero right-hand side) with the
    unit-stencil ``weights`` (:class:`~clothgrid.weights.Weights`).
    """
    from ..backends.cpu import interior_diagonal, residual

    wu, wv = np.ascontiguousarray(weights.wu), np.ascontiguousarray(weights.wv)
    K = barriers.bands
    out = np.zeros(K + 2)
    if points.shape[0] < 3 or points.shape[1] < 3:
        return out
    s = np.linalg.norm(residual(points, wu, wv), axis=-1) / interior_diagonal(wu, wv)
    a, b = wu[1:, 1:-1], wv[1:-1, 1:]                         # the couplings along i and along j
    ku, kv = np.broadcast_arrays(barriers.ku[1:-1, None], barriers.kv[None, 1:-1])
    k1, k2 = np.minimum(ku, kv), np.maximum(ku, kv)
    cost = np.append(barriers.cost, np.inf)
    cover = (a * (ku == k1) + b * (kv == k1)) / (a + b)
    c1 = np.where(k1 < K, cost[k1] / cover, np.inf)
    c2 = np.where((k2 < K) & (k2 != k1), cost[np.minimum(k2, K)], np.inf)
    slot = np.where((c1 < barriers.zmax) & (c1 <= c2), k1, np.where(c2 < barriers.zmax, k2, K))
    value = np.where(slot == k1, s / np.where(k1 < K, cover, 1.0), s)
    np.maximum.at(out, slot.ravel(), value.ravel())
    out[K + 1] = s.max()
    return out
