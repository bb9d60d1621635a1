"""The Numba kernel of the multigrid hierarchy's Galerkin coarse operator ``P^T A P``.

Low level on purpose: it imports neither :mod:`clothgrid.backends` nor
:mod:`clothgrid.solvers`, only Numba and NumPy, and works on plain arrays.
:func:`clothgrid.multigrid_levels.coarsen` wraps it into a
:class:`~clothgrid.multigrid_levels.Level`; it is imported on first use (Numba's
start-up costs ~0.5 s), only for weights without a separable form, compiled
once and cached on disk.
"""

from __future__ import annotations

import numba
import numpy as np

from .jit_variants import fork_safe


@numba.njit(inline="always", error_model="numpy")
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


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _coarsen(C, E, N, NE, nine, Cc, Ec, Nc, NEc):
    """Galerkin coarse stencil ``P^T A P`` (linear interpolation along j).

    On level 0 (``nine`` False) ``E``, ``N`` are ``wu``, ``wv`` and ``C``, ``NE``
    are unused. Fills the coarse arrays' interior rows; the rest is zero. A 9-point
    level's ``NW`` is ``NE`` of the column before (:class:`~clothgrid.multigrid_levels.Level`),
    the coarse level's too, so neither is read or formed here.
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
                        lo1[j] = -NE[i, j - 1]          # NW[i + 1, j - 1]
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
