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
maximum principle). For a band of width ``w`` (lines ``1 .. w-1`` from each side)
the profile ``F(t) = min(phi(t), phi(n-1-t))``, ``phi(t) = t (2w - t)`` up to ``w``
and ``w^2`` beyond, is concave, so ``U_w[i, j] = F(i)`` has
``D^-1 A U_w >= a / (a + b)`` on the lines ``i`` of the band and ``>= 0`` elsewhere,
and ``V_w[i, j] = F(j)`` likewise with ``b / (a + b)`` (``a``, ``b`` the node's
couplings along ``i`` and ``j``); ``max U_w = max V_w = w^2``. Each node is charged
to the cheapest of: ``z`` (cost ``max z``); ``U`` of its narrowest band along ``i``
(cost ``w^2 (a + b) / a``); ``V`` of its narrowest along ``j`` (``w^2 (a + b) / b``);
both of those at once (coverage 1, cost ``w_i^2 + w_j^2``); and

    |R* - R| <= alpha max z + sum_k (beta_k + gamma_k) w_k^2,

``alpha`` the largest ``|s|`` charged to ``z``, ``beta_k`` (``gamma_k``) the largest
``|s| / coverage`` charged to ``U`` (``V``) of band ``k`` (widths 2, 4, 8, ...).
``z`` also takes every node below a threshold (free while ``alpha`` is above it),
chosen over half-octave buckets of ``|s|`` collected in the same pass. The bound
is never above ``max|s| max z``; ``docs/accuracy.md`` has its figures.

**Per-edge weights** (four weights a node). The same ``U_w`` and ``V_w`` serve, with
their coverage ``c = D^-1 A U_w`` taken node by node from the node's own four weights
(``(a_lo (F(i) - F(i-1)) + a_hi (F(i) - F(i+1))) / D``; ``a / (a + b)`` when ``a_lo =
a_hi``). Where the weights grow towards the interior faster than the profile flattens,
a barrier's coverage is negative at some nodes; the table then also carries, for each
barrier, the largest ``-c`` over the grid (``N_k``), and ``alpha`` grows by ``sum_k
beta_k N_k + gamma_k N'_k``, which ``z`` (coverage 1 everywhere) makes up node by node.
A node is charged only to barriers whose coverage there is positive. ``max z`` is then the
barrier solve's upper bound (``zmax`` of :meth:`BandBarriers.for_grid`).
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


#: Half-octave buckets of ``|s|`` below the reference level, for the choice of what ``z`` takes
THRESHOLDS = 24


@dataclass(frozen=True)
class BandBarriers:
    """The band barriers of an ``nu x nv`` grid (module docstring).

    Attributes
    ----------
    zmax : float
        ``max z`` of the whole-grid barrier (for per-edge weights an upper bound of it).
    cost : numpy.ndarray
        ``(K,)`` float64: ``w_k^2``, the largest value of band ``k``'s barriers
        ``U`` and ``V`` (widths ``w_k = 2, 4, 8, ...`` up to ``(min(nu, nv) - 1) / 2``).
    ku, kv : numpy.ndarray
        ``(nu,)`` and ``(nv,)`` int64: the narrowest band holding line ``i``
        (``j``), ``K`` for none.
    reference : float
        The level of ``|s|`` whose ``z`` term alone is the tolerance (``tol * scale
        / max z``): nodes are sorted into :data:`THRESHOLDS` half-octave buckets
        below it, so that ``z`` may take every node under a threshold (it costs
        nothing more than ``alpha`` already does) and the bands only the rest.
    """

    zmax: float
    cost: np.ndarray
    ku: np.ndarray
    kv: np.ndarray
    reference: float

    @classmethod
    def for_grid(cls, nu: int, nv: int, reference: float, zmax: float | None = None) -> "BandBarriers":
        """The barriers of an ``nu x nv`` grid; ``zmax`` an upper bound of ``max z`` for per-edge
        weights (the unit stencils' analytic one by default)."""
        widths = []
        w = 2
        while w <= (min(nu, nv) - 1) // 2:
            widths.append(w)
            w *= 2
        wk = np.array(widths, dtype=np.int64)

        def band(n: int) -> np.ndarray:
            t = np.arange(n)
            return np.searchsorted(wk, np.minimum(t, n - 1 - t), side="right").astype(np.int64)

        if not (reference > 0 and np.isfinite(reference)):
            raise ValueError(f"the reference level must be positive and finite, not {reference!r}")
        if zmax is None:
            zmax = _analytic_barrier_max(nu, nv)
        elif not (zmax > 0 and np.isfinite(zmax)):
            raise ValueError(f"max z must be positive and finite, not {zmax!r}")
        return cls(float(zmax), wk.astype(np.float64) ** 2, band(nu), band(nv), float(reference))

    @property
    def bands(self) -> int:
        return len(self.cost)

    @property
    def widths(self) -> np.ndarray:
        """``(K,)`` int64: the bands' widths ``w_k`` (``cost`` is their squares)."""
        return np.sqrt(self.cost).round().astype(np.int64)

    @property
    def buckets(self) -> int:
        """:data:`THRESHOLDS`: half-octave buckets of ``|s|`` below :attr:`reference`."""
        return THRESHOLDS

    def slopes(self, axis: int) -> np.ndarray:
        """``(2, n)`` float64: for each line ``t`` along ``axis`` (0: ``i``, 1: ``j``), the profile
        of the narrowest band holding it less its neighbours', ``F(t) - F(t - 1)`` and ``F(t) -
        F(t + 1)`` (zero for lines in no band and the boundary's): a coverage is then ``(a_lo
        slope[0] + a_hi slope[1]) / D``."""
        lines = self.ku if axis == 0 else self.kv
        n = len(lines)
        out = np.zeros((2, n))
        t = np.arange(1, n - 1)
        for k, w in enumerate(self.widths):
            f = profile(n, int(w))
            on = t[lines[1:-1] == k]
            out[0, on], out[1, on] = f[on] - f[on - 1], f[on] - f[on + 1]
        return out

    @property
    def deficits_at(self) -> int:
        """Where :func:`band_steps`' table holds the barriers' negative coverages (``2 K`` values
        to its end)."""
        return 2 + (THRESHOLDS + 1) * (2 * self.bands + 1)

    @property
    def table_size(self) -> int:
        """Length of :func:`band_steps`' answer."""
        return self.deficits_at + 2 * self.bands

    def coefficients(self, table: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """``(alpha, beta, gamma)`` of the least bound from :func:`band_steps`' table (``alpha``
        including ``sum beta_k N_k + gamma_k N'_k``, the barriers' negative coverages): over the
        thresholds ``reference * 2^(-m/2)`` (``z`` takes every node below it) and none, and the
        plain ``(max|s|, 0, 0)``. ``W = alpha z + sum_k beta_k U_k + gamma_k V_k`` is then a
        supersolution."""
        K, M = self.bands, THRESHOLDS
        smax2, base2 = float(table[0]), float(table[1])
        sa = table[2:2 + M + 1]                             # bucket h + 1: max s^2 of the nodes a band could take
        end = self.deficits_at
        sb = table[2 + M + 1:end].reshape(M + 1, 2 * K)     # ... their s^2 / coverage^2 in U_k (k < K), V_k
        deficit = table[end:end + 2 * K]                    # the largest -coverage of U_k, V_k (per-edge weights)
        # z takes the buckets from row r on (r = 0 .. M + 1; M + 1: none of them), the bands the rows before
        alpha2 = np.maximum(base2, np.maximum.accumulate(np.append(sa, 0.0)[::-1])[::-1])
        beta2 = np.vstack([np.zeros((1, 2 * K)), np.maximum.accumulate(sb, axis=0)])
        alpha, beta = np.sqrt(alpha2), np.sqrt(beta2)
        alpha = alpha + beta @ deficit                      # z makes up the barriers' negative coverage
        totals = alpha * self.zmax + beta @ np.concatenate([self.cost, self.cost])
        r = int(np.argmin(totals))
        if not totals[r] < np.sqrt(smax2) * self.zmax:
            return float(np.sqrt(smax2)), np.zeros(K), np.zeros(K)
        return float(alpha[r]), beta[r, :K].copy(), beta[r, K:].copy()

    def bound(self, table: np.ndarray) -> float:
        """The error bound (absolute) from :func:`band_steps`' table: ``alpha max z + sum_k
        (beta_k + gamma_k) w_k^2`` of :meth:`coefficients`, never above ``max|s| max z``."""
        alpha, beta, gamma = self.coefficients(table)
        return alpha * self.zmax + float((beta + gamma) @ self.cost)


def _exponent(x: Any) -> Any:
    """The biased binary exponent field of float64 ``x`` (0 for zero and subnormals)."""
    return (np.asarray(x, dtype=np.float64).view(np.int64) >> 52) & 0x7FF


def band_steps(points: np.ndarray, weights: Any, barriers: BandBarriers) -> np.ndarray:
    """What :meth:`BandBarriers.bound` needs of a grid, in NumPy (the reference of the kernels).

    For ``s = D^-1 (b - A R)`` of ``points`` (``(nu, nv, k)``, zero right-hand side) with the
    unit-stencil ``weights`` (:class:`~clothgrid.weights.Weights`), a flat table of squares:
    ``max s^2``; the largest ``s^2`` of the nodes only ``z`` takes; then, by half-octave
    bucket ``h`` of ``s`` below the reference (the binary exponent of ``reference^2`` less that
    of ``s^2``, held to ``-1 .. THRESHOLDS - 1``, stored at ``h + 1``), the largest ``s^2`` of
    the other nodes, and for each barrier ``U_0 .. U_{K-1}, V_0 .. V_{K-1}`` the largest
    ``s^2 / coverage^2`` of the nodes of that bucket charged to it; last, for per-edge weights,
    each barrier's largest negative coverage ``N_k`` (``U_0 .. V_{K-1}``, not squared; zero
    for unit stencils). A node is charged to the
    cheapest of the options in the module docstring (costs compared cross-multiplied, as the
    kernels do). (Which bucket a node falls in only steers the choice of
    threshold: the coefficients are exact maxima of the nodes charged to them.) Any weights:
    the unit stencils' coverages are ``a / (a + b)``, per-edge weights' their own.
    """
    from ..backends.cpu import interior_diagonal, residual

    wu, wv = np.ascontiguousarray(weights.wu), np.ascontiguousarray(weights.wv)
    K, M = barriers.bands, THRESHOLDS
    out = np.zeros(barriers.table_size)
    if points.shape[0] < 3 or points.shape[1] < 3:
        return out
    r2 = np.sum(residual(points, wu, wv) ** 2, axis=-1)
    if not weights.unit_stencil:
        return _band_steps_per_edge(r2, wu, wv, barriers, out)
    s2 = r2 / interior_diagonal(wu, wv) ** 2
    a, b = wu[1:, 1:-1], wv[1:-1, 1:]                         # the couplings along i and along j
    ku, kv = np.broadcast_arrays(barriers.ku[1:-1, None], barriers.kv[None, 1:-1])
    cost = np.append(barriers.cost, np.inf)
    cu, cv = cost[ku], cost[kv]
    den = a + b
    options = np.stack([cu * den * b,                        # U of the band along i
                        cv * den * a,                        # V of the band along j
                        (cu + cv) * a * b,                   # both
                        np.full(s2.shape, barriers.zmax) * a * b])     # z
    choice = np.argmin(options, axis=0)                       # ties: the first
    charged = np.where(choice == 0, s2 * (den / a) ** 2, np.where(choice == 1, s2 * (den / b) ** 2, s2))
    return _table(out, s2, choice, charged, ku, kv, barriers)


def _table(out: np.ndarray, s2: np.ndarray, choice: np.ndarray, charged: np.ndarray, ku: np.ndarray,
           kv: np.ndarray, barriers: BandBarriers) -> np.ndarray:
    """:func:`band_steps`' table into ``out`` from each node's ``s^2``, its choice (0: U, 1: V, 2:
    both, 3: z) and the ``s^2 / coverage^2`` charged to its barriers."""
    K, M = barriers.bands, THRESHOLDS
    h = _exponent(np.float64(barriers.reference) ** 2) - _exponent(s2)
    row = np.clip(h, -1, M - 1) + 1
    out[0] = s2.max()
    z_only = choice == 3
    out[1] = s2[z_only].max() if z_only.any() else 0.0
    np.maximum.at(out[2:2 + M + 1], row[~z_only], s2[~z_only])
    sb = np.zeros((M + 1, 2 * K))
    for option, slot in ((0, ku), (1, K + kv), (2, ku), (2, K + kv)):
        pick = choice == option
        np.maximum.at(sb, (row[pick], slot[pick]), charged[pick])
    out[2 + M + 1:barriers.deficits_at] = sb.ravel()
    return out


def profile(n: int, w: int) -> np.ndarray:
    """The band profile ``F`` of width ``w`` over ``0 .. n-1`` (module docstring), float64."""
    t = np.arange(n)
    u = np.minimum(t, n - 1 - t).astype(np.float64)
    return np.where(u < w, u * (2.0 * w - u), float(w) * w)


def coverages(wu: np.ndarray, wv: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray]:
    """``D^-1 A U_w`` and ``D^-1 A V_w`` over the interior nodes, ``(nu-2, nv-2)`` each, computed as
    the kernels do: ``(a_lo (F(i) - F(i-1)) + a_hi (F(i) - F(i+1))) (1 / D)``."""
    from ..weights import interior_diagonal

    nu, nv = wu.shape[0] + 1, wu.shape[1]
    inv = 1.0 / interior_diagonal(wu, wv)
    fu, fv = profile(nu, w), profile(nv, w)
    cu = (wu[:-1, 1:-1] * (fu[1:-1] - fu[:-2])[:, None] + wu[1:, 1:-1] * (fu[1:-1] - fu[2:])[:, None]) * inv
    cv = (wv[1:-1, :-1] * (fv[1:-1] - fv[:-2])[None, :] + wv[1:-1, 1:] * (fv[1:-1] - fv[2:])[None, :]) * inv
    return cu, cv


def _band_steps_per_edge(r2: np.ndarray, wu: np.ndarray, wv: np.ndarray, barriers: BandBarriers,
                         out: np.ndarray) -> np.ndarray:
    """:func:`band_steps` for per-edge weights (``r2`` the squared residual's norm per node): each
    node's coverages from its own weights, a node charged only to barriers covering it
    positively, and each barrier's largest negative coverage (``N_k``) at the table's end. Costs
    are compared cross-multiplied, in the kernel's order (U, V, both, z; ties: the first)."""
    from ..weights import interior_diagonal

    K, M = barriers.bands, THRESHOLDS
    inv = 1.0 / interior_diagonal(wu, wv)
    s2 = r2 * inv * inv
    ku, kv = np.broadcast_arrays(barriers.ku[1:-1, None], barriers.kv[None, 1:-1])
    cu, cv = np.zeros(s2.shape), np.zeros(s2.shape)
    end = barriers.deficits_at
    for k, w in enumerate(barriers.widths):
        a, b = coverages(wu, wv, int(w))
        cu[ku == k], cv[kv == k] = a[ku == k], b[kv == k]
        out[end + k] = max(0.0, float(-a.min()))
        out[end + K + k] = max(0.0, float(-b.min()))
    cost = np.append(barriers.cost, np.inf)
    wcu, wcv = cost[ku], cost[kv]
    zmax = barriers.zmax
    with np.errstate(invalid="ignore"):
        valid_u, valid_v = cu > 0, cv > 0
        choice = np.where(valid_u, 0, 3)
        num, den = np.where(valid_u, wcu, zmax), np.where(valid_u, cu, 1.0)
        take = valid_v & ((choice == 3) | (wcv * den < num * cv))
        choice, num, den = np.where(take, 1, choice), np.where(take, wcv, num), np.where(take, cv, den)
        take = valid_u & valid_v & ((wcu + wcv) * den < num * (cu + cv))
        choice, num, den = np.where(take, 2, choice), np.where(take, wcu + wcv, num), np.where(take, cu + cv, den)
        choice = np.where((choice != 3) & (zmax * den < num * 1.0), 3, choice)
    return _table(out, s2, choice, s2 / (den * den), ku, kv, barriers)
