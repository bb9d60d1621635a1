"""Fused Numba kernels of the CPU multigrid (:mod:`clothgrid.solvers.multigrid`).

Iterates are ``(nu, nv, k)`` arrays (``k`` coordinates). Level 0 works in
float64 straight from the edge weights ``wu``, ``wv`` (for the paper's and
uniform weights these are stride-0 views of 1D arrays, so a sweep streams only
the grid); coarser levels hold corrections and 9-point stencils in float32,
which halves their memory traffic and costs nothing in accuracy: every cycle
starts from the exact float64 residual of level 0.

Line solves run along ``i`` (Thomas algorithm, factorised on the fly) for a
block of rows ``j`` at a time, blocks in parallel. Two exact identities save
work: after the pre-smoothing sweep (even rows, then odd rows) the odd rows'
residual is zero, so restriction reads the even rows only; and the
post-smoothing sweep starts by solving the odd rows from their neighbours, so
prolongation only adds the correction to the even rows.

Imported on first use (Numba's start-up costs ~0.5 s), compiled once and
cached on disk.
"""

from __future__ import annotations

import numba
import numpy as np

_BLOCK = 16   # rows j per line-solve block
_PARALLEL_NODES = 1 << 16   # smaller levels run serial kernels: thread start-up would cost more


def _nlines(nv: int, first: int) -> int:
    return (nv - first) // 2 if first <= nv - 2 else 0


@numba.njit(parallel=True, cache=True, nogil=True)
def _relax5(x, b, wu, wv, first, has_b):
    """Level 0: solve rows ``j = first, first+2, ...`` exactly along ``i``."""
    nu, nv, k = x.shape
    nl = (nv - first) // 2 if first <= nv - 2 else 0
    nblk = (nl + _BLOCK - 1) // _BLOCK
    for blk in numba.prange(nblk):
        l0 = blk * _BLOCK
        nb = min(_BLOCK, nl - l0)
        g = np.zeros((nu, _BLOCK))
        for i in range(1, nu - 1):
            for l in range(nb):
                j = first + 2 * (l0 + l)
                e_lo = wu[i - 1, j]
                e_hi = wu[i, j]
                n_lo = wv[i, j - 1]
                n_hi = wv[i, j]
                inv = 1.0 / (e_lo + e_hi + n_lo + n_hi - e_lo * g[i - 1, l])
                g[i, l] = e_hi * inv
                for c in range(k):
                    r = n_lo * x[i, j - 1, c] + n_hi * x[i, j + 1, c] + e_lo * x[i - 1, j, c]
                    if has_b:
                        r += b[i, j, c]
                    x[i, j, c] = r * inv
        for i in range(nu - 2, 0, -1):
            for l in range(nb):
                j = first + 2 * (l0 + l)
                gi = g[i, l]
                for c in range(k):
                    x[i, j, c] += gi * x[i + 1, j, c]


@numba.njit(parallel=True, cache=True, nogil=True)
def _relax9(x, b, C, E, N, NE, NW, first):
    """Coarse levels: the same line solves for a 9-point stencil."""
    nu, nv, k = x.shape
    nl = (nv - first) // 2 if first <= nv - 2 else 0
    nblk = (nl + _BLOCK - 1) // _BLOCK
    for blk in numba.prange(nblk):
        l0 = blk * _BLOCK
        nb = min(_BLOCK, nl - l0)
        g = np.zeros((nu, _BLOCK), dtype=x.dtype)
        for i in range(1, nu - 1):
            for l in range(nb):
                j = first + 2 * (l0 + l)
                e_lo = E[i - 1, j]
                inv = 1.0 / (C[i, j] - e_lo * g[i - 1, l])
                g[i, l] = E[i, j] * inv
                n_lo = N[i, j - 1]
                n_hi = N[i, j]
                ne_hi = NE[i, j]
                ne_lo = NE[i - 1, j - 1]
                nw_hi = NW[i, j]
                nw_lo = NW[i + 1, j - 1]
                for c in range(k):
                    r = (b[i, j, c] + n_lo * x[i, j - 1, c] + n_hi * x[i, j + 1, c]
                         + ne_hi * x[i + 1, j + 1, c] + ne_lo * x[i - 1, j - 1, c]
                         + nw_hi * x[i - 1, j + 1, c] + nw_lo * x[i + 1, j - 1, c])
                    x[i, j, c] = (r + e_lo * x[i - 1, j, c]) * inv
        for i in range(nu - 2, 0, -1):
            for l in range(nb):
                j = first + 2 * (l0 + l)
                gi = g[i, l]
                for c in range(k):
                    x[i, j, c] += gi * x[i + 1, j, c]


@numba.njit(inline="always")
def _res5(x, b, wu, wv, i, j, c, has_b):
    xc = x[i, j, c]
    r = (wu[i - 1, j] * (x[i - 1, j, c] - xc) + wu[i, j] * (x[i + 1, j, c] - xc)
         + wv[i, j - 1] * (x[i, j - 1, c] - xc) + wv[i, j] * (x[i, j + 1, c] - xc))
    if has_b:
        r += b[i, j, c]
    return r


@numba.njit(parallel=True, cache=True, nogil=True)
def _restrict5(x, b, wu, wv, has_b, bc, xc):
    """``bc[:, J] = r[:, 2J]`` (odd rows' residual is zero after pre-smoothing), ``xc = 0``."""
    nu, nv, k = x.shape
    nc = bc.shape[1]
    for i in numba.prange(nu):
        for J in range(nc):
            for c in range(k):
                xc[i, J, c] = 0.0
                bc[i, J, c] = 0.0
        if i == 0 or i == nu - 1:
            continue
        for J in range(1, nc - 1):
            for c in range(k):
                bc[i, J, c] = _res5(x, b, wu, wv, i, 2 * J, c, has_b)


@numba.njit(parallel=True, cache=True, nogil=True)
def _restrict9(x, b, C, E, N, NE, NW, bc, xc):
    nu, nv, k = x.shape
    nc = bc.shape[1]
    for i in numba.prange(nu):
        for J in range(nc):
            for c in range(k):
                xc[i, J, c] = 0.0
                bc[i, J, c] = 0.0
        if i == 0 or i == nu - 1:
            continue
        for J in range(1, nc - 1):
            j = 2 * J
            for c in range(k):
                bc[i, J, c] = (b[i, j, c] - C[i, j] * x[i, j, c]
                               + E[i - 1, j] * x[i - 1, j, c] + E[i, j] * x[i + 1, j, c]
                               + N[i, j - 1] * x[i, j - 1, c] + N[i, j] * x[i, j + 1, c]
                               + NE[i, j] * x[i + 1, j + 1, c] + NE[i - 1, j - 1] * x[i - 1, j - 1, c]
                               + NW[i, j] * x[i - 1, j + 1, c] + NW[i + 1, j - 1] * x[i + 1, j - 1, c])


@numba.njit(parallel=True, cache=True, nogil=True)
def _prolong_even(x, xc):
    """``x[:, 2J] += xc[:, J]`` (odd rows are re-solved by the next sweep)."""
    nu, nv, k = x.shape
    nc = xc.shape[1]
    for i in numba.prange(1, nu - 1):
        for J in range(1, nc - 1):
            for c in range(k):
                x[i, 2 * J, c] += xc[i, J, c]


@numba.njit(parallel=True, cache=True, nogil=True)
def _max_step5(x, b, wu, wv, has_b):
    """``max |D^-1 (b - A x)|`` (Euclidean per node) on level 0."""
    nu, nv, k = x.shape
    rowmax = np.zeros(nu)
    for i in numba.prange(1, nu - 1):
        m = 0.0
        for j in range(1, nv - 1):
            s2 = 0.0
            for c in range(k):
                r = _res5(x, b, wu, wv, i, j, c, has_b)
                s2 += r * r
            d = wu[i - 1, j] + wu[i, j] + wv[i, j - 1] + wv[i, j]
            s2 /= d * d
            if s2 > m:
                m = s2
        rowmax[i] = m
    return np.sqrt(rowmax.max())


@numba.njit(inline="always")
def _gal(lo, c, up, nv, J, nc):
    """Coarse (diag, up) of P^T T P at coarse row J, for one column's tridiagonal T.

    ``lo(j)``, ``c(j)``, ``up(j)`` are T[j, j-1], T[j, j], T[j, j+1] as arrays over j.
    """
    f = 2 * J
    d = c[f] + 0.25 * c[f - 1] + 0.5 * (lo[f] + up[f - 1])
    if f + 1 <= nv - 2:
        d += 0.25 * c[f + 1] + 0.5 * (up[f] + lo[f + 1])
    u = 0.0
    if J + 1 <= nc - 2:
        u = 0.5 * up[f] + 0.25 * c[f + 1] + 0.5 * up[f + 1]
    return d, u


@numba.njit(parallel=True, cache=True, nogil=True)
def _coarsen(C, E, N, NE, NW, nine, Cc, Ec, Nc, NEc, NWc):
    """Galerkin coarse stencil ``P^T A P`` (linear interpolation along j).

    On level 0 (``nine`` False) ``E``, ``N`` are ``wu``, ``wv`` and ``C``, ``NE``,
    ``NW`` are unused. Fills the coarse arrays' interior rows; the rest is zero.
    """
    nu = Cc.shape[0]
    nc = Cc.shape[1]
    nv = N.shape[1] + (0 if nine else 1)
    for i in numba.prange(nu):
        lo0 = np.zeros(nv)
        c0 = np.zeros(nv)
        up0 = np.zeros(nv)
        lo1 = np.zeros(nv)
        c1 = np.zeros(nv)
        up1 = np.zeros(nv)
        for j in range(nv):
            if nine:
                c0[j] = C[i, j]
                up0[j] = -N[i, j]
                if j > 0:
                    lo0[j] = -N[i, j - 1]
                if i < nu - 1:
                    c1[j] = -E[i, j]
                    up1[j] = -NE[i, j]
                    if j > 0:
                        lo1[j] = -NW[i + 1, j - 1]
            else:
                s = 0.0
                if i > 0:
                    s += E[i - 1, j]
                if i < nu - 1:
                    s += E[i, j]
                    c1[j] = -E[i, j]
                if j > 0:
                    s += N[i, j - 1]
                    lo0[j] = -N[i, j - 1]
                if j < nv - 1:
                    s += N[i, j]
                    up0[j] = -N[i, j]
                c0[j] = s
        for J in range(nc):
            Cc[i, J] = 0.0
            Ec[i, J] = 0.0
            Nc[i, J] = 0.0
            NEc[i, J] = 0.0
        for J in range(1, nc - 1):
            d0, u0 = _gal(lo0, c0, up0, nv, J, nc)
            d1, u1 = _gal(lo1, c1, up1, nv, J, nc)
            Cc[i, J] = d0
            Nc[i, J] = -u0
            Ec[i, J] = -d1
            NEc[i, J] = -u1
    # NW: coupling (i, J) -> (i-1, J+1) is the di=+1 operator of column i-1 at (J+1 -> J)
    for i in numba.prange(nu):
        for J in range(nc):
            NWc[i, J] = 0.0
        if i == 0:
            continue
        lo1 = np.zeros(nv)
        c1 = np.zeros(nv)
        for j in range(nv):
            if nine:
                c1[j] = -E[i - 1, j]
                if j > 0:
                    lo1[j] = -NW[i, j - 1]
            else:
                c1[j] = -E[i - 1, j]
        for J in range(1, nc - 2):
            # T_c[J+1, J] = 0.5 lo[f] + 0.25 c[f-1] + 0.5 lo[f-1] with f = 2(J+1)
            f = 2 * (J + 1)
            NWc[i, J] = -(0.5 * lo1[f] + 0.25 * c1[f - 1] + 0.5 * lo1[f - 1])


def _serial(kernel):
    """The same kernel compiled without threads (``prange`` runs as ``range``)."""
    return numba.njit(cache=True, nogil=True)(kernel.py_func)


_KERNELS = {name: (globals()[name], _serial(globals()[name]))
            for name in ("_relax5", "_relax9", "_restrict5", "_restrict9", "_prolong_even", "_max_step5")}


def _pick(name: str, shape) -> callable:
    par, ser = _KERNELS[name]
    return par if shape[0] * shape[1] >= _PARALLEL_NODES else ser


class CpuMultigrid:
    """The CPU backend's :class:`~clothgrid.solvers.multigrid.MultigridOps`.

    Parameters
    ----------
    levels : list of Level
        The hierarchy, finest first (:func:`~clothgrid.solvers.multigrid.build_hierarchy`).
    x0 : numpy.ndarray
        ``(nu, nv, k)`` float64 level-0 iterate (boundary nodes hold the data); updated in place.
    rhs : numpy.ndarray, optional
        ``(nu-2, nv-2, k)`` level-0 right-hand side over interior nodes (zero if omitted).
    """

    def __init__(self, levels, x0: np.ndarray, rhs: np.ndarray | None = None):
        self._lv = levels
        self.levels = len(levels)
        k = x0.shape[2]
        self.x = [x0]
        self.b = [np.zeros((1, 1, k))]
        self._has_b = rhs is not None
        if rhs is not None:
            b0 = np.zeros_like(x0)
            b0[1:-1, 1:-1] = rhs
            self.b[0] = b0
        for lv in levels[1:]:
            self.x.append(np.zeros(lv.shape + (k,), dtype=lv.C.dtype))
            self.b.append(np.zeros(lv.shape + (k,), dtype=lv.C.dtype))

    def smooth(self, level: int, reverse: bool = False) -> None:
        lv, x, b = self._lv[level], self.x[level], self.b[level]
        for first in ((1, 2) if reverse else (2, 1)):
            if level == 0:
                _pick("_relax5", x.shape)(x, b, lv.E, lv.N, first, self._has_b)
            else:
                _pick("_relax9", x.shape)(x, b, lv.C, lv.E, lv.N, lv.NE, lv.NW, first)

    def restrict(self, level: int) -> None:
        lv, x, b = self._lv[level], self.x[level], self.b[level]
        if level == 0:
            _pick("_restrict5", x.shape)(x, b, lv.E, lv.N, self._has_b, self.b[1], self.x[1])
        else:
            _pick("_restrict9", x.shape)(x, b, lv.C, lv.E, lv.N, lv.NE, lv.NW, self.b[level + 1], self.x[level + 1])

    def prolong(self, level: int) -> None:
        _pick("_prolong_even", self.x[level].shape)(self.x[level], self.x[level + 1])

    def max_step(self) -> float:
        lv = self._lv[0]
        return float(_pick("_max_step5", self.x[0].shape)(self.x[0], self.b[0], lv.E, lv.N, self._has_b))

    def solution(self) -> np.ndarray:
        return self.x[0]


def coarsen(level, dtype=np.float32):
    """The Galerkin coarse level of ``level`` (semi-coarsening along v), stencils in ``dtype``."""
    from ..solvers.multigrid import Level, coarse_rows

    nu, nv = level.shape
    nc = len(coarse_rows(nv))
    out = [np.empty((nu, nc), dtype=dtype) for _ in range(5)]
    nine = level.C is not None
    dummy = np.zeros((1, 1))
    _coarsen(level.C if nine else dummy, level.E, level.N, level.NE if nine else dummy,
             level.NW if nine else dummy, nine, *out)
    return Level(C=out[0], E=out[1], N=out[2], NE=out[3], NW=out[4])
