"""Fused Numba kernels of the CPU multigrid (:mod:`clothgrid.solvers.multigrid`) and its operations.

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

:class:`CpuMultigrid` turns the hierarchy (plain data from
:func:`clothgrid.multigrid_levels.build_hierarchy`) into the CPU backend's
:class:`~clothgrid.backends.protocol.MultigridOps`. Imported on first use
(Numba's start-up costs ~0.5 s), compiled once and cached on disk.
"""

from __future__ import annotations

import weakref
from typing import Any

import numba
import numpy as np

from ..jit_variants import fork_safe, serial_twin
from ..memory import DISCARD_MIN_BYTES, Arena, discard
from ..multigrid_levels import LINE_BLOCK, Level, diagonal_partner

_PARALLEL_NODES = 1 << 16   # smaller levels run serial kernels: thread start-up would cost more
# ... except in a hierarchy whose finest level has at least this many nodes: there the parallel
# kernels run every level. Its few small levels cost some 100 thread start-ups a solve (under a
# millisecond at 1024^2), while loading the five serial twins from Numba's cache cost a fresh
# process (the command line) about 20 ms.
_ALL_PARALLEL_NODES = 1 << 18


# Coarse row J lives in the even array at J // 2 when J is even, else in the odd
# one: the kernels below spell that choice out at each use. Helper functions
# for it (inline="always") made restriction and prolongation 10-40x slower.
# Likewise the three line-solve kernels each spell out the Thomas backward
# pass: one shared inline helper made two V-cycles 2.4-2.7x slower (1024^2 and
# 2048^2, measured side by side in one process).
#
# Layout. A level's iterate is split by row parity into two coordinate-plane
# arrays, ``xe[c, i, m]`` = x[i, 2m, c] and ``xo[c, i, m]`` = x[i, 2m+1, c],
# and so are its stencil arrays. A zebra half-sweep then reads one parity's
# coefficients and writes one array, and its inner loops run over ``m``
# through contiguous memory, where the compiler vectorises them.
#
# For a row of parity ``p`` ("own"), the rows below and above belong to the
# other parity, at index ``m + ob`` and ``m + ob + 1``, ``ob = 0`` for odd
# rows and ``-1`` for even rows. Couplings owned by the row below (``N`` to
# it, ``NE`` and ``NW`` from it) are read from the other parity's arrays.

# Lines per block of a half-sweep (``CpuMultigrid.mbs``): at most LINE_BLOCK (512), and fewer where that would leave a thread
# without a block. Long blocks pay: a block reads each array row's ``mb`` contiguous values, and runs
# of 4 KB (512 float64) let the prefetchers keep up where 1 KB runs did not (4096^2: a level-0 sweep
# 90 -> 72 ms at 256 lines, a whole solve 2.7 -> 1.8 s at 512); at 1024^2 128 and 256 lines tie.


@numba.njit(inline="always", error_model="numpy")
def _line_range(nv, p):
    """Interior rows of parity p as a range of m: j = 2m + p in 1 .. nv-2."""
    if p == 1:
        return 0, (nv - 3) // 2 + 1
    return 1, (nv - 2) // 2 + 1


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _relax5(xo, xt, bo, Eo, No, Nt, p, nv, has_b, mb, scr):
    """Level 0: solve the interior rows of parity ``p`` exactly along ``i``, ``mb`` rows a block."""
    k, nu = xo.shape[0], xo.shape[1]
    ob = 0 if p == 1 else -1
    m_lo, m_hi = _line_range(nv, p)
    nblk = (m_hi - m_lo + mb - 1) // mb if m_hi > m_lo else 0
    for blk in numba.prange(nblk):
        m0 = m_lo + blk * mb
        nb = min(mb, m_hi - m0)
        a, z = m0, m0 + nb          # own rows
        ta, tz = m0 + ob, m0 + ob + nb   # rows below, in the other parity
        tid = numba.get_thread_id()
        g = scr[tid]
        ivi = g[nu]
        g[0] = 0.0
        for i in range(1, nu - 1):     # factorise and eliminate forward, all coordinates at once
            elo, ehi, nlo, nhi = Eo[i - 1, a:z], Eo[i, a:z], Nt[i, ta:tz], No[i, a:z]
            gp, gi = g[i - 1], g[i]
            for q in range(nb):
                d = elo[q] + ehi[q] + nlo[q] + nhi[q] - elo[q] * gp[q]
                ivi[q] = 1.0 / d
                gi[q] = ehi[q] * ivi[q]
            for c in range(k):
                t = xt[c]
                tlo, thi, xp, xi = t[i, ta:tz], t[i, ta + 1:tz + 1], xo[c, i - 1, a:z], xo[c, i, a:z]
                if has_b:
                    bi = bo[c, i, a:z]
                    for q in range(nb):
                        xi[q] = (bi[q] + nlo[q] * tlo[q] + nhi[q] * thi[q] + elo[q] * xp[q]) * ivi[q]
                else:
                    for q in range(nb):
                        xi[q] = (nlo[q] * tlo[q] + nhi[q] * thi[q] + elo[q] * xp[q]) * ivi[q]
        for i in range(nu - 2, 0, -1):
            gi = g[i]
            for c in range(k):
                xi, xn = xo[c, i, a:z], xo[c, i + 1, a:z]
                for q in range(nb):
                    xi[q] += gi[q] * xn[q]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _relax5u(xo, xt, bo, eo, nn, p, nv, has_b, mb, scr):
    """:func:`_relax5` for a unit-stencil level 0 (the paper's and uniform weights): ``E[i, j] = e[j]``
    and ``N[i, j] = nn[i]``, given as the own rows' ``eo`` and the columns' ``nn`` (1D, contiguous).

    The same line solves with two coefficient loads less per node and contiguous ones: about 1.8x
    faster than reading the stride-0 views of the 2D arrays (1024^2, one thread).
    """
    k, nu = xo.shape[0], xo.shape[1]
    ob = 0 if p == 1 else -1
    m_lo, m_hi = _line_range(nv, p)
    nblk = (m_hi - m_lo + mb - 1) // mb if m_hi > m_lo else 0
    for blk in numba.prange(nblk):
        m0 = m_lo + blk * mb
        nb = min(mb, m_hi - m0)
        a, z = m0, m0 + nb
        ta, tz = m0 + ob, m0 + ob + nb
        tid = numba.get_thread_id()
        g = scr[tid]
        ivi = g[nu]
        g[0] = 0.0
        e = eo[a:z]
        for i in range(1, nu - 1):
            ni = nn[i]
            gp, gi = g[i - 1], g[i]
            for q in range(nb):
                d = 2.0 * (e[q] + ni) - e[q] * gp[q]
                ivi[q] = 1.0 / d
                gi[q] = e[q] * ivi[q]
            for c in range(k):
                t = xt[c]
                tlo, thi, xp, xi = t[i, ta:tz], t[i, ta + 1:tz + 1], xo[c, i - 1, a:z], xo[c, i, a:z]
                if has_b:
                    bi = bo[c, i, a:z]
                    for q in range(nb):
                        xi[q] = (bi[q] + ni * (tlo[q] + thi[q]) + e[q] * xp[q]) * ivi[q]
                else:
                    for q in range(nb):
                        xi[q] = (ni * (tlo[q] + thi[q]) + e[q] * xp[q]) * ivi[q]
        for i in range(nu - 2, 0, -1):
            gi = g[i]
            for c in range(k):
                xi, xn = xo[c, i, a:z], xo[c, i + 1, a:z]
                for q in range(nb):
                    xi[q] += gi[q] * xn[q]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _relax9(xo, xt, bo, Co, Eo, No, Nt, NEo, NEt, p, nv, mb, scr):
    """Coarse levels: the same line solves for a 9-point stencil. A cell's two diagonal couplings are
    equal (``NW[i, J] = NE[i - 1, J]``, :class:`~clothgrid.multigrid_levels.Level`): the couplings to
    the rows below and above come from ``NE`` of columns ``i - 1`` and ``i``, one row of each
    parity's array read from memory a column (the column before's is still in cache)."""
    k, nu = xo.shape[0], xo.shape[1]
    ob = 0 if p == 1 else -1
    m_lo, m_hi = _line_range(nv, p)
    nblk = (m_hi - m_lo + mb - 1) // mb if m_hi > m_lo else 0
    for blk in numba.prange(nblk):
        m0 = m_lo + blk * mb
        nb = min(mb, m_hi - m0)
        a, z = m0, m0 + nb
        ta, tz = m0 + ob, m0 + ob + nb
        tid = numba.get_thread_id()
        g = scr[tid]
        ivi = g[nu]
        g[0] = 0.0
        for i in range(1, nu - 1):     # factorise and eliminate forward, all coordinates at once
            ci, elo, ehi = Co[i, a:z], Eo[i - 1, a:z], Eo[i, a:z]
            gp, gi = g[i - 1], g[i]
            for q in range(nb):
                d = ci[q] - elo[q] * gp[q]
                ivi[q] = 1.0 / d
                gi[q] = ehi[q] * ivi[q]
            nlo, nhi = Nt[i, ta:tz], No[i, a:z]
            ne_o, ne_t, nw_o, nw_t = NEo[i, a:z], NEt[i - 1, ta:tz], NEo[i - 1, a:z], NEt[i, ta:tz]
            for c in range(k):
                t = xt[c]
                bi, xp, xi = bo[c, i, a:z], xo[c, i - 1, a:z], xo[c, i, a:z]
                t0lo, t0hi = t[i, ta:tz], t[i, ta + 1:tz + 1]
                tmlo, tmhi = t[i - 1, ta:tz], t[i - 1, ta + 1:tz + 1]
                tplo, tphi = t[i + 1, ta:tz], t[i + 1, ta + 1:tz + 1]
                for q in range(nb):
                    r = (bi[q] + nlo[q] * t0lo[q] + nhi[q] * t0hi[q] + ne_o[q] * tphi[q] + ne_t[q] * tmlo[q]
                         + nw_o[q] * tmhi[q] + nw_t[q] * tplo[q] + elo[q] * xp[q])
                    xi[q] = r * ivi[q]
        for i in range(nu - 2, 0, -1):
            gi = g[i]
            for c in range(k):
                xi, xn = xo[c, i, a:z], xo[c, i + 1, a:z]
                for q in range(nb):
                    xi[q] += gi[q] * xn[q]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _relax9s(xo, xt, bo, cu, kud, du, mdo, muo, kdo, kuo, mut, kut, p, nv, mb, scr):
    """Coarse levels of separable weights: :func:`_relax9` with the stencil formed on the fly.

    The stencil is ``Ku (x) M + Du (x) K`` (:class:`~clothgrid.multigrid_levels.Separable`):
    ``cu``, ``kud`` (``Ku``'s diagonal), ``du`` over columns ``i``; ``md``, ``mu``, ``kd``,
    ``ku`` over rows, own (``o``) and other (``t``) parity. A sweep streams only the iterate.
    """
    k, nu = xo.shape[0], xo.shape[1]
    ob = 0 if p == 1 else -1
    m_lo, m_hi = _line_range(nv, p)
    nblk = (m_hi - m_lo + mb - 1) // mb if m_hi > m_lo else 0
    for blk in numba.prange(nblk):
        m0 = m_lo + blk * mb
        nb = min(mb, m_hi - m0)
        a, z = m0, m0 + nb
        ta, tz = m0 + ob, m0 + ob + nb
        tid = numba.get_thread_id()
        g = scr[tid]
        ivi = g[nu]
        g[0] = 0.0
        md, mu, kd, ku, mt, kt = mdo[a:z], muo[a:z], kdo[a:z], kuo[a:z], mut[ta:tz], kut[ta:tz]
        for i in range(1, nu - 1):
            cl, cr, kk, dd = cu[i - 1], cu[i], kud[i], du[i]
            gp, gi = g[i - 1], g[i]
            for q in range(nb):
                d = kk * md[q] + dd * kd[q] - cl * md[q] * gp[q]
                ivi[q] = 1.0 / d
                gi[q] = cr * md[q] * ivi[q]
            for c in range(k):
                t = xt[c]
                bi, xp, xi = bo[c, i, a:z], xo[c, i - 1, a:z], xo[c, i, a:z]
                t0lo, t0hi = t[i, ta:tz], t[i, ta + 1:tz + 1]
                tmlo, tmhi = t[i - 1, ta:tz], t[i - 1, ta + 1:tz + 1]
                tplo, tphi = t[i + 1, ta:tz], t[i + 1, ta + 1:tz + 1]
                # the couplings to the rows below and above formed here, not kept in scratch rows:
                # two stores and 2k loads a node fewer, 8-16 % off a coarse sweep, the same bits
                for q in range(nb):
                    r = (bi[q] - (kk * mt[q] + dd * kt[q]) * t0lo[q] - (kk * mu[q] + dd * ku[q]) * t0hi[q]
                         + mu[q] * (cr * tphi[q] + cl * tmhi[q])
                         + mt[q] * (cl * tmlo[q] + cr * tplo[q]) + cl * md[q] * xp[q])
                    xi[q] = r * ivi[q]
        for i in range(nu - 2, 0, -1):
            gi = g[i]
            for c in range(k):
                xi, xn = xo[c, i, a:z], xo[c, i + 1, a:z]
                for q in range(nb):
                    xi[q] += gi[q] * xn[q]


@numba.njit(inline="always", error_model="numpy")
def _res5(x, t, b, Eo, No, Nt, c, i, m, ob, has_b):
    """Residual of level 0 at own-parity node (i, row m) for coordinate c."""
    xc = x[c, i, m]
    r = (Eo[i - 1, m] * (x[c, i - 1, m] - xc) + Eo[i, m] * (x[c, i + 1, m] - xc)
         + Nt[i, m + ob] * (t[c, i, m + ob] - xc) + No[i, m] * (t[c, i, m + ob + 1] - xc))
    if has_b:
        r += b[c, i, m]
    return r


@numba.njit(inline="always", error_model="numpy")
def _zero_rows(i, a, b, c, d):
    """Zero column ``i`` of the coarse right-hand sides and corrections."""
    a[:, i, :] = 0.0
    b[:, i, :] = 0.0
    c[:, i, :] = 0.0
    d[:, i, :] = 0.0


# Restriction: the residual of one column ``i`` is formed in a contiguous row of the
# per-thread scratch ``rows`` (``row[J]``, coarse row J = fine row 2J, zero at J = 0 and
# nc - 1), then stored by J's parity in two strided loops; the coarse corrections are
# zeroed, and the right-hand sides written once (no zero-fill first).


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _restrict5(xe, xo, be, Ee, Ne, No, has_b, bce, bco, xce, xco, rows):
    """Coarse right-hand side from level 0's even rows (the odd rows' residual is zero
    after pre-smoothing); coarse row J is fine row 2J, stored by J's parity."""
    k, nu = xe.shape[0], xe.shape[1]
    nce, nco = bce.shape[2], bco.shape[2]
    nc = nce + nco
    for i in numba.prange(nu):
        xce[:, i, :] = 0.0
        xco[:, i, :] = 0.0
        if i == 0 or i == nu - 1 or nc < 3:
            bce[:, i, :] = 0.0
            bco[:, i, :] = 0.0
            continue
        row = rows[numba.get_thread_id()]
        row[0] = 0.0
        row[nc - 1] = 0.0
        elo, ehi, nlo, nhi = Ee[i - 1, 1:nc - 1], Ee[i, 1:nc - 1], No[i, 0:nc - 2], Ne[i, 1:nc - 1]
        for c in range(k):
            xm, x0, xp = xe[c, i - 1, 1:nc - 1], xe[c, i, 1:nc - 1], xe[c, i + 1, 1:nc - 1]
            tlo, thi = xo[c, i, 0:nc - 2], xo[c, i, 1:nc - 1]
            r = row[1:nc - 1]
            for q in range(nc - 2):
                r[q] = (elo[q] * (xm[q] - x0[q]) + ehi[q] * (xp[q] - x0[q])
                        + nlo[q] * (tlo[q] - x0[q]) + nhi[q] * (thi[q] - x0[q]))
            if has_b:
                bi = be[c, i, 1:nc - 1]
                for q in range(nc - 2):
                    r[q] += bi[q]
            oe, oo = bce[c, i], bco[c, i]
            for K in range(nce):
                oe[K] = row[2 * K]
            for K in range(nco):
                oo[K] = row[2 * K + 1]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _restrict5u(xe, xo, be, ee, nn, has_b, bce, bco, xce, xco, rows):
    """:func:`_restrict5` for a unit-stencil level 0 (``E[i, j] = e[j]``, ``N[i, j] = nn[i]``, see
    :func:`_relax5u`); ``ee`` the even rows' ``e``."""
    k, nu = xe.shape[0], xe.shape[1]
    nce, nco = bce.shape[2], bco.shape[2]
    nc = nce + nco
    for i in numba.prange(nu):
        xce[:, i, :] = 0.0
        xco[:, i, :] = 0.0
        if i == 0 or i == nu - 1 or nc < 3:
            bce[:, i, :] = 0.0
            bco[:, i, :] = 0.0
            continue
        row = rows[numba.get_thread_id()]
        row[0] = 0.0
        row[nc - 1] = 0.0
        e, ni = ee[1:nc - 1], nn[i]
        for c in range(k):
            xm, x0, xp = xe[c, i - 1, 1:nc - 1], xe[c, i, 1:nc - 1], xe[c, i + 1, 1:nc - 1]
            tlo, thi = xo[c, i, 0:nc - 2], xo[c, i, 1:nc - 1]
            r = row[1:nc - 1]
            for q in range(nc - 2):
                r[q] = e[q] * (xm[q] - x0[q] + xp[q] - x0[q]) + ni * (tlo[q] - x0[q] + thi[q] - x0[q])
            if has_b:
                bi = be[c, i, 1:nc - 1]
                for q in range(nc - 2):
                    r[q] += bi[q]
            oe, oo = bce[c, i], bco[c, i]
            for K in range(nce):
                oe[K] = row[2 * K]
            for K in range(nco):
                oo[K] = row[2 * K + 1]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _restrict9(xe, xo, be, Ce, Ee, Ne, No, NEe, NEo, bce, bco, xce, xco, rows):
    """:func:`_restrict5` for a 9-point level (``NW`` read as ``NE`` of the column before, see
    :func:`_relax9`)."""
    k, nu = xe.shape[0], xe.shape[1]
    nce, nco = bce.shape[2], bco.shape[2]
    nc = nce + nco
    for i in numba.prange(nu):
        xce[:, i, :] = 0.0
        xco[:, i, :] = 0.0
        if i == 0 or i == nu - 1 or nc < 3:
            bce[:, i, :] = 0.0
            bco[:, i, :] = 0.0
            continue
        row = rows[numba.get_thread_id()]
        row[0] = 0.0
        row[nc - 1] = 0.0
        for c in range(k):
            x = xe[c]
            t = xo[c]
            for J in range(1, nc - 1):
                m = J
                mb = m - 1
                row[J] = (be[c, i, m] - Ce[i, m] * x[i, m] + Ee[i - 1, m] * x[i - 1, m] + Ee[i, m] * x[i + 1, m]
                          + No[i, mb] * t[i, mb] + Ne[i, m] * t[i, mb + 1]
                          + NEe[i, m] * t[i + 1, mb + 1] + NEo[i - 1, mb] * t[i - 1, mb]
                          + NEe[i - 1, m] * t[i - 1, mb + 1] + NEo[i, mb] * t[i + 1, mb])
            oe, oo = bce[c, i], bco[c, i]
            for K in range(nce):
                oe[K] = row[2 * K]
            for K in range(nco):
                oo[K] = row[2 * K + 1]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _restrict9s(xe, xo, be, cu, kud, du, mde, mue, kde, kue, muo, kuo, bce, bco, xce, xco, rows):
    """:func:`_restrict9` for a separable level (the stencil formed on the fly, see :func:`_relax9s`)."""
    k, nu = xe.shape[0], xe.shape[1]
    nce, nco = bce.shape[2], bco.shape[2]
    nc = nce + nco
    for i in numba.prange(nu):
        xce[:, i, :] = 0.0
        xco[:, i, :] = 0.0
        if i == 0 or i == nu - 1 or nc < 3:
            bce[:, i, :] = 0.0
            bco[:, i, :] = 0.0
            continue
        row = rows[numba.get_thread_id()]
        row[0] = 0.0
        row[nc - 1] = 0.0
        cl, cr, kk, dd = cu[i - 1], cu[i], kud[i], du[i]
        n = nc - 2
        md, mu, kd, ku, mo, ko = mde[1:nc - 1], mue[1:nc - 1], kde[1:nc - 1], kue[1:nc - 1], muo[0:n], kuo[0:n]
        for c in range(k):
            bi = be[c, i, 1:nc - 1]
            xm, x0, xp = xe[c, i - 1, 1:nc - 1], xe[c, i, 1:nc - 1], xe[c, i + 1, 1:nc - 1]
            tm_lo, t0_lo, tp_lo = xo[c, i - 1, 0:n], xo[c, i, 0:n], xo[c, i + 1, 0:n]
            tm_hi, t0_hi, tp_hi = xo[c, i - 1, 1:n + 1], xo[c, i, 1:n + 1], xo[c, i + 1, 1:n + 1]
            r = row[1:nc - 1]
            for q in range(n):
                r[q] = (bi[q] - (kk * md[q] + dd * kd[q]) * x0[q]
                        + md[q] * (cl * xm[q] + cr * xp[q])
                        - (kk * mo[q] + dd * ko[q]) * t0_lo[q] - (kk * mu[q] + dd * ku[q]) * t0_hi[q]
                        + mu[q] * (cr * tp_hi[q] + cl * tm_hi[q])
                        + mo[q] * (cl * tm_lo[q] + cr * tp_lo[q]))
            oe, oo = bce[c, i], bco[c, i]
            for K in range(nce):
                oe[K] = row[2 * K]
            for K in range(nco):
                oo[K] = row[2 * K + 1]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _prolong(xe, xce, xco):
    """Add the coarse correction to the even rows (odd rows are re-solved next)."""
    k, nu = xe.shape[0], xe.shape[1]
    nce, nco = xce.shape[2], xco.shape[2]
    nc = nce + nco
    for i in numba.prange(1, nu - 1):
        for c in range(k):
            x, ce, co = xe[c, i], xce[c, i], xco[c, i]
            for K in range(1, (nc - 2) // 2 + 1):      # J = 2K <= nc - 2
                x[2 * K] += ce[K]
            for K in range(0, (nc - 3) // 2 + 1):      # J = 2K + 1 <= nc - 2
                x[2 * K + 1] += co[K]


@numba.njit(inline="always", error_model="numpy")
def _add_rhs_row(b, c, i, a, z, has_b, out):
    """``out[q] += b[c, i, a + q]`` where level 0 has a right-hand side (:func:`_res5_row`,
    :func:`_res5u_row`)."""
    if has_b:
        bi = b[c, i, a:z]
        for q in range(z - a):
            out[q] += bi[q]


@numba.njit(inline="always", error_model="numpy")
def _res5_row(x, t, b, Eo, No, Nt, c, i, a, z, ob, has_b, out):
    """``out[q]`` = residual of level 0 at own-parity rows ``m = a + q`` (``m < z``) of column ``i``."""
    elo, ehi, nlo, nhi = Eo[i - 1, a:z], Eo[i, a:z], Nt[i, a + ob:z + ob], No[i, a:z]
    xm, x0, xp = x[c, i - 1, a:z], x[c, i, a:z], x[c, i + 1, a:z]
    tlo, thi = t[c, i, a + ob:z + ob], t[c, i, a + ob + 1:z + ob + 1]
    for q in range(z - a):
        out[q] = (elo[q] * (xm[q] - x0[q]) + ehi[q] * (xp[q] - x0[q])
                  + nlo[q] * (tlo[q] - x0[q]) + nhi[q] * (thi[q] - x0[q]))
    _add_rhs_row(b, c, i, a, z, has_b, out)


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _restrict5_full(xe, xo, be, bo, Ee, Eo, Ne, No, has_b, nv, bce, bco, xce, xco):
    """``P^T (b - A x)`` from level 0 with every row's residual (for the full multigrid start)."""
    k, nu = xe.shape[0], xe.shape[1]
    nc = bce.shape[2] + bco.shape[2]
    n_odd = (nv - 3) // 2 + 1          # interior odd rows m = 0 .. n_odd-1
    for i in numba.prange(nu):
        _zero_rows(i, bce, bco, xce, xco)
        if i == 0 or i == nu - 1 or nc < 3:
            continue
        re = np.empty(nc)              # even rows J = 1 .. nc-2 at re[J]
        ro = np.zeros(nc)              # odd rows m at ro[m]; zero where there is none
        for c in range(k):
            _res5_row(xe, xo, be, Ee, Ne, No, c, i, 1, nc - 1, -1, has_b, re[1:])
            _res5_row(xo, xe, bo, Eo, No, Ne, c, i, 0, n_odd, 0, has_b, ro)
            for J in range(1, nc - 1):
                r = re[J] + 0.5 * (ro[J - 1] + ro[J])
                if J % 2 == 0:
                    bce[c, i, J // 2] = r
                else:
                    bco[c, i, J // 2] = r


@numba.njit(inline="always", error_model="numpy")
def _res5u_row(x, t, b, e, ni, c, i, a, z, ob, has_b, out):
    """:func:`_res5_row` for a unit-stencil level 0 (``e[q]`` the coupling along ``i`` of row
    ``m = a + q``, ``ni`` the column's along ``j``): the same sums in the same order."""
    xm, x0, xp = x[c, i - 1, a:z], x[c, i, a:z], x[c, i + 1, a:z]
    tlo, thi = t[c, i, a + ob:z + ob], t[c, i, a + ob + 1:z + ob + 1]
    for q in range(z - a):
        out[q] = e[q] * (xm[q] - x0[q]) + e[q] * (xp[q] - x0[q]) + ni * (tlo[q] - x0[q]) + ni * (thi[q] - x0[q])
    _add_rhs_row(b, c, i, a, z, has_b, out)


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _restrict5u_full(xe, xo, be, bo, ee, eo, nn, has_b, nv, bce, bco, xce, xco, rows):
    """:func:`_restrict5_full` for a unit-stencil level 0 (``E[i, j] = e[j]``, ``N[i, j] = nn[i]``, see
    :func:`_relax5u`): the same sums in the same order (the same bits), each column's residuals in
    contiguous per-thread rows (``rows``: at least ``nv + 2`` a thread) and stored by the coarse
    row's parity in two strided loops, instead of a branch per coarse row."""
    k, nu = xe.shape[0], xe.shape[1]
    nce, nco = bce.shape[2], bco.shape[2]
    nc = nce + nco
    n_odd = (nv - 3) // 2 + 1          # interior odd rows m = 0 .. n_odd-1
    for i in numba.prange(nu):
        _zero_rows(i, bce, bco, xce, xco)
        if i == 0 or i == nu - 1 or nc < 3:
            continue
        row = rows[numba.get_thread_id()]
        re = row[:nc]                  # even rows J = 1 .. nc-2 at re[J]
        ro = row[nc:2 * nc]            # odd rows m at ro[m]; zero where there is none
        ni = nn[i]
        for c in range(k):
            _res5u_row(xe, xo, be, ee[1:nc - 1], ni, c, i, 1, nc - 1, -1, has_b, re[1:])
            _res5u_row(xo, xe, bo, eo[0:n_odd], ni, c, i, 0, n_odd, 0, has_b, ro)
            for q in range(n_odd, nc):
                ro[q] = 0.0
            for J in range(1, nc - 1):
                re[J] = re[J] + 0.5 * (ro[J - 1] + ro[J])
            oe, oo = bce[c, i], bco[c, i]
            for K in range(1, (nc - 2) // 2 + 1):      # J = 2K <= nc - 2
                oe[K] = re[2 * K]
            for K in range(0, (nc - 3) // 2 + 1):      # J = 2K + 1 <= nc - 2
                oo[K] = re[2 * K + 1]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _restrict_rhs(be, bo, nv, bce, bco, xce, xco):
    """``b_c = P^T b`` and ``x_c = 0`` (the full multigrid start's coarse right-hand sides)."""
    k, nu = be.shape[0], be.shape[1]
    nc = bce.shape[2] + bco.shape[2]
    for i in numba.prange(nu):
        _zero_rows(i, bce, bco, xce, xco)
        if i == 0 or i == nu - 1:
            continue
        for c in range(k):
            for J in range(1, nc - 1):
                r = be[c, i, J] + 0.5 * bo[c, i, J - 1]
                if 2 * J + 1 <= nv - 2:
                    r += 0.5 * bo[c, i, J]
                if J % 2 == 0:
                    bce[c, i, J // 2] = r
                else:
                    bco[c, i, J // 2] = r


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _prolong_full(xe, xo, xce, xco, nv):
    """``x += P x_c`` on every interior row (odd rows take the mean of their neighbours)."""
    k, nu = xe.shape[0], xe.shape[1]
    nc = xce.shape[2] + xco.shape[2]
    for i in numba.prange(1, nu - 1):
        for c in range(k):
            for J in range(1, nc - 1):
                xe[c, i, J] += xce[c, i, J // 2] if J % 2 == 0 else xco[c, i, J // 2]
            for m in range(0, (nv - 3) // 2 + 1):   # odd row 2m+1 between coarse rows m and m+1
                lo = xce[c, i, m // 2] if m % 2 == 0 else xco[c, i, m // 2]
                hi = xce[c, i, (m + 1) // 2] if (m + 1) % 2 == 0 else xco[c, i, (m + 1) // 2]
                xo[c, i, m] += 0.5 * (lo + hi)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _residual_line5(xe, xo, be, bo, Ee, Eo, Ne, No, nv, has_b, i, p, c, out):
    """``b - A x`` of coordinate ``c`` on line ``i``, rows of parity ``p`` (a per-edge level 0), into
    ``out[:n]``; returns ``(m_lo, n)`` (rows ``j = 2 m + p``, ``m`` from ``m_lo``)."""
    m_lo, m_hi = _line_range(nv, p)
    n = m_hi - m_lo
    if n <= 0:
        return m_lo, 0
    ob = 0 if p == 1 else -1
    x, t = (xe[c], xo[c]) if p == 0 else (xo[c], xe[c])
    Eown, Nown, Noth = (Ee, Ne, No) if p == 0 else (Eo, No, Ne)
    a, z, ta, tz = m_lo, m_hi, m_lo + ob, m_hi + ob
    elo, ehi, nlo, nhi = Eown[i - 1, a:z], Eown[i, a:z], Noth[i, ta:tz], Nown[i, a:z]
    xm, x0, xp, tlo, thi = x[i - 1, a:z], x[i, a:z], x[i + 1, a:z], t[i, ta:tz], t[i, ta + 1:tz + 1]
    if has_b:
        bi = (be if p == 0 else bo)[c, i, a:z]
        for q in range(n):
            out[q] = (bi[q] + elo[q] * (xm[q] - x0[q]) + ehi[q] * (xp[q] - x0[q])
                      + nlo[q] * (tlo[q] - x0[q]) + nhi[q] * (thi[q] - x0[q]))
    else:
        for q in range(n):
            out[q] = (elo[q] * (xm[q] - x0[q]) + ehi[q] * (xp[q] - x0[q])
                      + nlo[q] * (tlo[q] - x0[q]) + nhi[q] * (thi[q] - x0[q]))
    return m_lo, n


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _residual2_line5(xe, xo, be, bo, Ee, Eo, Ne, No, nv, has_b, i, p, r, s2):
    """``|b - A x|^2`` (summed over the coordinates) of a per-edge level 0 on line ``i``, rows of parity
    ``p``, into ``s2[:n]`` (``r`` scratch of the same length); returns ``(m_lo, n)``."""
    s2[:] = 0.0
    m_lo, n = 0, 0
    for c in range(xe.shape[0]):
        m_lo, n = _residual_line5(xe, xo, be, bo, Ee, Eo, Ne, No, nv, has_b, i, p, c, r)
        for q in range(n):
            s2[q] += r[q] * r[q]
    return m_lo, n


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _max_step5(xe, xo, be, bo, Ee, Eo, Ne, No, nv, has_b, eps, qe, qo, write):
    """``max |D^-1 (b - A x)|`` (Euclidean per node) on a per-edge level 0. With ``write``, also the
    residual solve's right-hand side (``clothgrid.solvers.multigrid._residual_solve_bound``) ``q =
    |b - A x| + eps D`` on the interior nodes, into the one-coordinate parity planes ``qe``, ``qo``
    (their boundary ring zero); without, those are not touched."""
    nu = xe.shape[1]
    rowmax = np.zeros(nu)
    for i in numba.prange(nu):
        if write:
            qe[0, i, :] = 0.0
            qo[0, i, :] = 0.0
        if i == 0 or i == nu - 1:
            continue
        best = 0.0
        r, s2 = np.empty(nv // 2 + 1), np.empty(nv // 2 + 1)
        for p in range(2):
            m_lo, n = _residual2_line5(xe, xo, be, bo, Ee, Eo, Ne, No, nv, has_b, i, p, r, s2)
            if n <= 0:
                continue
            ob = 0 if p == 1 else -1
            Eown, Nown, Noth = (Ee, Ne, No) if p == 0 else (Eo, No, Ne)
            a, z, ta, tz = m_lo, m_lo + n, m_lo + ob, m_lo + n + ob
            elo, ehi, nlo, nhi = Eown[i - 1, a:z], Eown[i, a:z], Noth[i, ta:tz], Nown[i, a:z]
            for q in range(n):
                d = elo[q] + ehi[q] + nlo[q] + nhi[q]
                v = s2[q] / (d * d)
                if v > best:
                    best = v
            if write:
                out = (qe if p == 0 else qo)[0, i, a:z]
                for q in range(n):
                    out[q] = np.sqrt(s2[q]) + eps * (elo[q] + ehi[q] + nlo[q] + nhi[q])
        rowmax[i] = best
    return np.sqrt(rowmax.max())


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _relative_residual5(xe, xo, be, bo, Ee, Eo, Ne, No, nv):
    """``max (b - A x) / b`` over the interior nodes of a one-coordinate per-edge level 0 whose
    right-hand side is positive there (signed: the largest shortfall of ``A x`` below ``b``)."""
    nu = xe.shape[1]
    rowmax = np.full(nu, -np.inf)
    for i in numba.prange(1, nu - 1):
        best = -np.inf
        r = np.empty(nv // 2 + 1)
        for p in range(2):
            m_lo, n = _residual_line5(xe, xo, be, bo, Ee, Eo, Ne, No, nv, True, i, p, 0, r)
            bb = (be if p == 0 else bo)[0, i, m_lo:m_lo + n]
            for q in range(n):
                v = r[q] / bb[q]
                if v > best:
                    best = v
        rowmax[i] = best
    return rowmax.max()


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _unit_steps2(xe, xo, be, bo, ee, eo, nn, nv, has_b, i, p, s2):
    """Squared Jacobi steps ``|D^-1 (b - A x)|^2`` of a unit-stencil level 0 on line ``i``, rows of
    parity ``p``, into ``s2[:n]``; returns ``(m_lo, n)`` (rows ``j = 2 m + p``, ``m`` from ``m_lo``)."""
    k = xe.shape[0]
    ni = nn[i]
    m_lo, m_hi = _line_range(nv, p)
    n = m_hi - m_lo
    if n <= 0:
        return m_lo, 0
    ob = 0 if p == 1 else -1
    xown, xoth = (xe, xo) if p == 0 else (xo, xe)
    a, z, ta, tz = m_lo, m_hi, m_lo + ob, m_hi + ob
    e = (ee if p == 0 else eo)[a:z]
    for q in range(n):
        s2[q] = 0.0
    for c in range(k):
        x, t = xown[c], xoth[c]
        xm, x0, xp, tlo, thi = x[i - 1, a:z], x[i, a:z], x[i + 1, a:z], t[i, ta:tz], t[i, ta + 1:tz + 1]
        if has_b:
            bi = (be if p == 0 else bo)[c, i, a:z]
            for q in range(n):
                r = bi[q] + e[q] * (xm[q] - x0[q] + xp[q] - x0[q]) + ni * (tlo[q] - x0[q] + thi[q] - x0[q])
                s2[q] += r * r
        else:
            for q in range(n):
                r = e[q] * (xm[q] - x0[q] + xp[q] - x0[q]) + ni * (tlo[q] - x0[q] + thi[q] - x0[q])
                s2[q] += r * r
    for q in range(n):
        d = 2.0 * (e[q] + ni)
        s2[q] = s2[q] / (d * d)
    return m_lo, n


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _max_step5u(xe, xo, be, bo, ee, eo, nn, nv, has_b, rows):
    """:func:`_max_step5` for a unit-stencil level 0 (``E[i, j] = e[j]``, ``N[i, j] = nn[i]``,
    see :func:`_relax5u`); ``rows`` per-thread scratch of at least ``nv // 2 + 1``."""
    nu = xe.shape[1]
    rowmax = np.zeros(nu)
    for i in numba.prange(1, nu - 1):
        best = 0.0
        s2 = rows[numba.get_thread_id()]
        for p in range(2):
            _, n = _unit_steps2(xe, xo, be, bo, ee, eo, nn, nv, has_b, i, p, s2)
            for q in range(n):
                if s2[q] > best:
                    best = s2[q]
        rowmax[i] = best
    return np.sqrt(rowmax.max())


@numba.njit(inline="always", error_model="numpy")
def _charge(out, v, choice, w2, kui, kvq, eref, M, nb, fbits, ibits):
    """A node's entry in a thread's band table (:func:`clothgrid.solvers.bounds.band_steps`): its
    squared step ``v``, to ``z`` (``choice`` 3) or to its bucket, with ``w2`` (``v / coverage^2``)
    charged to ``U`` of band ``kui`` (``choice`` 0 or 2) and ``V`` of band ``kvq`` (1 or 2)."""
    if choice == 3:
        if v > out[1]:
            out[1] = v
        return
    fbits[0] = v
    h = eref - ((ibits[0] >> 52) & 0x7FF)
    row = min(max(h, -1), M - 1) + 1
    if v > out[2 + row]:
        out[2 + row] = v
    base = 2 + M + 1 + row * 2 * nb
    if choice != 1 and w2 > out[base + kui]:
        out[base + kui] = w2
    if choice != 0 and w2 > out[base + nb + kvq]:
        out[base + nb + kvq] = w2


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _band_steps5u(xe, xo, be, bo, ee, eo, nn, nv, has_b, rows, ku, kve, kvo, cost, zmax, ref2, nbuckets):
    """:func:`clothgrid.solvers.bounds.band_steps`' table for a unit-stencil level 0 (the residual
    as in :func:`_max_step5u`). ``ku`` the band of each line ``i``; ``kve``, ``kvo`` of each line
    ``j`` of either parity; ``cost`` the bands' ``w^2``; ``ref2`` the reference level squared;
    ``nbuckets`` the barriers' ``buckets``."""
    nu = xe.shape[1]
    nb = cost.shape[0]
    M = nbuckets
    off = 2 + M + 1
    tabs = np.zeros((rows.shape[0], off + (M + 1) * 2 * nb))     # one table a thread (rows: one a thread)
    fref = np.empty(1)
    fref[0] = ref2
    eref = (fref.view(np.int64)[0] >> 52) & 0x7FF
    for i in numba.prange(1, nu - 1):
        s2 = rows[numba.get_thread_id()]
        out = tabs[numba.get_thread_id()]
        fbits = np.empty(1)
        ibits = fbits.view(np.int64)
        ni = nn[i]
        kui = ku[i]
        for p in range(2):
            a, n = _unit_steps2(xe, xo, be, bo, ee, eo, nn, nv, has_b, i, p, s2)
            e = (ee if p == 0 else eo)[a:a + n]
            kv = (kve if p == 0 else kvo)[a:a + n]
            for q in range(n):
                v = s2[q]
                if v > out[0]:
                    out[0] = v
                kvq = kv[q]
                if kui >= nb and kvq >= nb:     # in no band: z's
                    _charge(out, v, 3, v, kui, kvq, eref, M, nb, fbits, ibits)
                    continue
                # the cheapest barrier, costs cross-multiplied by a b (module bounds' options)
                ea = e[q]
                den = ea + ni
                cu = cost[kui] if kui < nb else np.inf
                cv = cost[kvq] if kvq < nb else np.inf
                choice = 0
                best = cu * den * ni
                c = cv * den * ea
                if c < best:
                    choice, best = 1, c
                c = (cu + cv) * ea * ni
                if c < best:
                    choice, best = 2, c
                if zmax * ea * ni < best:       # z is cheaper
                    choice = 3
                w2 = v * (den / ea) ** 2 if choice == 0 else (v * (den / ni) ** 2 if choice == 1 else v)
                _charge(out, v, choice, w2, kui, kvq, eref, M, nb, fbits, ibits)
    res = np.zeros(off + (M + 1) * 2 * nb + 2 * nb)     # the per-edge deficits: none for a unit stencil
    for t in range(tabs.shape[0]):
        for m in range(tabs.shape[1]):
            res[m] = max(res[m], tabs[t, m])
    return res


@numba.njit(inline="always", error_model="numpy")
def _profile(t, n, w):
    """The band profile ``F`` of width ``w`` at line ``t`` of ``n`` (:func:`clothgrid.solvers.bounds.profile`)."""
    u = min(t, n - 1 - t)
    return u * (2.0 * w - u) if u < w else float(w) * w


@numba.njit(inline="always", error_model="numpy")
def _lift(t, n, w, lo, hi):
    """``A`` of the band profile of width ``w`` along a line, at line ``t`` (couplings ``lo`` to
    ``t - 1`` and ``hi`` to ``t + 1``); over the node's diagonal it is the coverage."""
    f = _profile(t, n, w)
    return lo * (f - _profile(t - 1, n, w)) + hi * (f - _profile(t + 1, n, w))


@numba.njit(inline="always", error_model="numpy")
def _cheaper(a, b, num, den):
    """``a / b < num / den`` for positive ``b`` and ``den``, without dividing."""
    return a * den < num * b


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _band_steps5(xe, xo, be, bo, Ee, Eo, Ne, No, nv, has_b, nthreads, ku, kve, kvo, su, sve, svo, widths, cost,
                 zmax, ref2, nbuckets, deficits):
    """:func:`clothgrid.solvers.bounds.band_steps`' table for a per-edge level 0 (the residual as in
    :func:`_max_step5`): each node's coverages from its own four weights, charged only where
    positive, and each barrier's largest negative coverage at the table's end. ``nthreads`` at least
    Numba's thread count; ``su`` the slopes of the lines ``i`` (``BandBarriers.slopes``), ``sve``,
    ``svo`` of the lines ``j`` of either parity; ``widths`` the bands' ``w`` (int64); the rest as
    in :func:`_band_steps5u`.
    The negative coverages depend on the weights alone: they are sought only where ``deficits``
    (the table's last ``2 nb`` entries are zero otherwise)."""
    nu = xe.shape[1]
    nb = cost.shape[0]
    M = nbuckets
    off = 2 + M + 1
    end = off + (M + 1) * 2 * nb
    tabs = np.zeros((nthreads, end + 2 * nb))
    fref = np.empty(1)
    fref[0] = ref2
    eref = (fref.view(np.int64)[0] >> 52) & 0x7FF
    for i in numba.prange(1, nu - 1):
        out = tabs[numba.get_thread_id()]
        fbits = np.empty(1)
        ibits = fbits.view(np.int64)
        r, s2 = np.empty(nv // 2 + 1), np.empty(nv // 2 + 1)
        kui = ku[i]
        sul, suh = su[0, i], su[1, i]
        for p in range(2):
            m_lo, n = _residual2_line5(xe, xo, be, bo, Ee, Eo, Ne, No, nv, has_b, i, p, r, s2)
            if n <= 0:
                continue
            ob = 0 if p == 1 else -1
            Eown, Nown, Noth = (Ee, Ne, No) if p == 0 else (Eo, No, Ne)
            kvp = kve if p == 0 else kvo
            svp = sve if p == 0 else svo
            for q in range(n):
                m = m_lo + q
                j = 2 * m + p
                alo, ahi, blo, bhi = Eown[i - 1, m], Eown[i, m], Noth[i, m + ob], Nown[i, m]
                inv = 1.0 / (alo + ahi + blo + bhi)
                v = s2[q] * inv * inv
                if v > out[0]:
                    out[0] = v
                kvq = kvp[m]
                # the narrowest band holding line i (j) is the one charged
                cu = (alo * sul + ahi * suh) * inv
                cv = (blo * svp[0, m] + bhi * svp[1, m]) * inv
                if deficits:     # every band holding the line: only there is a coverage below zero
                    for kk in range(kui, nb):
                        c = _lift(i, nu, widths[kk], alo, ahi) * inv
                        if -c > out[end + kk]:
                            out[end + kk] = -c
                    for kk in range(kvq, nb):
                        c = _lift(j, nv, widths[kk], blo, bhi) * inv
                        if -c > out[end + nb + kk]:
                            out[end + nb + kk] = -c
                # the cheapest barrier covering the node positively (U, V, both, z; ties: the first)
                choice = 3
                num, den = zmax, 1.0
                if cu > 0:
                    choice, num, den = 0, cost[kui], cu
                if cv > 0 and (choice == 3 or _cheaper(cost[kvq], cv, num, den)):
                    choice, num, den = 1, cost[kvq], cv
                if cu > 0 and cv > 0 and _cheaper(cost[kui] + cost[kvq], cu + cv, num, den):
                    choice, num, den = 2, cost[kui] + cost[kvq], cu + cv
                if choice != 3 and _cheaper(zmax, 1.0, num, den):
                    choice = 3
                _charge(out, v, choice, v / (den * den), kui, kvq, eref, M, nb, fbits, ibits)
    res = np.zeros(end + 2 * nb)
    for t in range(nthreads):
        for m in range(res.shape[0]):
            res[m] = max(res[m], tabs[t, m])
    return res


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _split_grid(x, xe, xo):
    """``(nu, nv, k)`` grid into parity planes ``xe[c, i, m] = x[i, 2m, c]``, ``xo[c, i, m] = x[i, 2m+1, c]``."""
    nu, nv, k = x.shape
    for i in numba.prange(nu):
        for j in range(nv):
            for c in range(k):
                if j % 2 == 0:
                    xe[c, i, j // 2] = x[i, j, c]
                else:
                    xo[c, i, j // 2] = x[i, j, c]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _split_interior(r, xe, xo):
    """:func:`_split_grid` of the grid whose interior nodes hold ``r`` (``(nu-2, nv-2, k)``) and whose
    boundary ring is zero, without that grid."""
    k, nu = xe.shape[0], xe.shape[1]
    nv = xe.shape[2] + xo.shape[2]
    for i in numba.prange(nu):
        for j in range(nv):
            for c in range(k):
                v = r[i - 1, j - 1, c] if 0 < i < nu - 1 and 0 < j < nv - 1 else 0.0
                if j % 2 == 0:
                    xe[c, i, j // 2] = v
                else:
                    xo[c, i, j // 2] = v


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _merge_grid(xe, xo, x):
    """The inverse of :func:`_split_grid`."""
    nu, nv, k = x.shape
    h = nv // 2
    for i in numba.prange(nu):
        for c in range(k):             # a plane's row at a time, no branch on j: 1.5 -> 0.9 ms at 1024^2
            e, o = xe[c, i], xo[c, i]
            for m in range(h):
                x[i, 2 * m, c] = e[m]
                x[i, 2 * m + 1, c] = o[m]
            if nv % 2:
                x[i, nv - 1, c] = e[h]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _split_rows(a, ae, ao):
    """Rows ``j`` even / odd of a ``(n, nv)`` stencil array into two contiguous arrays."""
    n, nv = a.shape
    for i in numba.prange(n):
        r, e, o = a[i], ae[i], ao[i]
        for m in range(nv // 2):       # no branch on j's parity: 2.4-4.6x faster (vectorised)
            e[m] = r[2 * m]
            o[m] = r[2 * m + 1]
        if nv % 2:
            e[nv // 2] = r[nv - 1]


def _merge_rows(ae: np.ndarray, ao: np.ndarray) -> np.ndarray:
    """The inverse of :func:`_split` for a stencil array: ``(n, nv)`` from its even and odd rows."""
    out = np.empty((ae.shape[0], ae.shape[1] + ao.shape[1]), dtype=ae.dtype)
    out[:, 0::2], out[:, 1::2] = ae, ao
    return out


def _parity_planes(x: np.ndarray, dtype=np.float64, arena: Arena | None = None,
                   interior: np.ndarray | None = None):
    """``x`` (``(nu, nv, k)``) split into parity planes (:func:`_split_grid`), carved from ``arena``
    if given; with ``interior`` (``(nu-2, nv-2, k)``), that array's values on the interior nodes and
    zero on the boundary ring instead of ``x``'s."""
    nu, nv, k = x.shape
    shapes = ((k, nu, (nv + 1) // 2), (k, nu, nv // 2))
    empty = np.empty if arena is None else arena.empty
    xe, xo = (empty(s, dtype) for s in shapes)
    if interior is not None:
        _split_interior(interior, xe, xo)
        return xe, xo
    _split_grid(x, xe, xo)
    return xe, xo


# Conjugate gradients' vector operations on level 0 (CpuMultigrid.vector and what follows it). A
# vector is a pair of parity planes like the iterate's, its boundary ring zero; every sum is taken
# row by row into a per-row array and added up in order, so the results do not depend on threads.


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _in_order(part):
    """The column sums of the per-row partial sums ``part`` (``(nu, k)``), rows added in order."""
    res = np.zeros(part.shape[1])
    for i in range(part.shape[0]):
        for c in range(part.shape[1]):
            res[c] += part[i, c]
    return res


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _apply5(xe, xo, be, bo, Ee, Eo, Ne, No, nv, has_b, sign, oute, outo):
    """``out = sign (b - A x)`` on level 0's interior nodes (the ring of ``out`` is not written);
    returns ``x . out`` per coordinate, over the interior nodes."""
    k, nu = xe.shape[0], xe.shape[1]
    part = np.zeros((nu, k))
    for i in numba.prange(1, nu - 1):
        for p in range(2):
            xown, out = (xe, oute) if p == 0 else (xo, outo)
            first, _ = _line_range(nv, p)
            for c in range(k):
                m_lo, n = _residual_line5(xe, xo, be, bo, Ee, Eo, Ne, No, nv, has_b, i, p, c, out[c, i, first:])
                o, x0 = out[c, i, m_lo:m_lo + n], xown[c, i, m_lo:m_lo + n]
                s = 0.0
                for q in range(n):
                    o[q] *= sign
                    s += x0[q] * o[q]
                part[i, c] += s
    return _in_order(part)


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _dot(ae, ao, be, bo):
    """``a . b`` per coordinate of two level-0 vectors (parity planes)."""
    k, nu = ae.shape[0], ae.shape[1]
    part = np.zeros((nu, k))
    for i in numba.prange(nu):
        for c in range(k):
            s = 0.0
            for m in range(ae.shape[2]):
                s += ae[c, i, m] * be[c, i, m]
            for m in range(ao.shape[2]):
                s += ao[c, i, m] * bo[c, i, m]
            part[i, c] = s
    return _in_order(part)


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _axpy(xe, xo, re, ro, pe, po, qe, qo, alpha):
    """``x += alpha p``, ``r -= alpha q`` (``alpha`` per coordinate; ``p``, ``q`` zero on the ring, so
    the boundary nodes of ``x`` keep their bits)."""
    k, nu = xe.shape[0], xe.shape[1]
    for i in numba.prange(nu):
        for c in range(k):
            a = alpha[c]
            for m in range(xe.shape[2]):
                xe[c, i, m] += a * pe[c, i, m]
                re[c, i, m] -= a * qe[c, i, m]
            for m in range(xo.shape[2]):
                xo[c, i, m] += a * po[c, i, m]
                ro[c, i, m] -= a * qo[c, i, m]


@fork_safe
@numba.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _xpay(pe, po, ze, zo, beta):
    """``p = z + beta p`` (``beta`` per coordinate)."""
    k, nu = pe.shape[0], pe.shape[1]
    for i in numba.prange(nu):
        for c in range(k):
            g = beta[c]
            for m in range(pe.shape[2]):
                pe[c, i, m] = ze[c, i, m] + g * pe[c, i, m]
            for m in range(po.shape[2]):
                po[c, i, m] = zo[c, i, m] + g * po[c, i, m]


_KERNELS = {name: (globals()[name], serial_twin(globals()[name], nogil=True, error_model="numpy"))
            for name in ("_relax5", "_relax5u", "_relax9", "_relax9s", "_restrict5", "_restrict5u", "_restrict9",
                         "_restrict9s", "_prolong", "_max_step5", "_max_step5u", "_restrict5_full", "_restrict5u_full",
                         "_restrict_rhs",
                         "_prolong_full", "_relative_residual5", "_merge_grid", "_band_steps5u", "_band_steps5", "_apply5", "_dot", "_axpy", "_xpay")}


def _pick(name: str, nodes: int, finest: int):
    """The parallel kernel ``name`` for a level of ``nodes`` nodes (in a hierarchy whose finest level
    has ``finest``), or its serial twin."""
    par, ser = _KERNELS[name]
    return par if nodes >= _PARALLEL_NODES or finest >= _ALL_PARALLEL_NODES else ser


#: Each level's stencil split by row parity (:func:`_level_split`), kept as long as the level itself:
#: a solve with per-edge weights builds two operation sets on one hierarchy (the barrier solve's
#: and the solve's), and splitting the coarse levels' stencil arrays twice cost 13 ms at 1024^2.
_SPLITS: "weakref.WeakKeyDictionary[Level, tuple]" = weakref.WeakKeyDictionary()


def _level_split(level: Level, arrays) -> tuple:
    """The level's stencil ``arrays`` (a callable returning them) split by row parity, once per level."""
    got = _SPLITS.get(level)
    if got is None:
        got = _SPLITS[level] = sum((_split(a) for a in arrays()), ())
    return got


def _split(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``j`` even and odd of a ``(n, nv)`` stencil array; stride-0 views stay views."""
    if 0 in a.strides:
        return a[:, 0::2], a[:, 1::2]
    n, nv = a.shape
    ae, ao = np.empty((n, (nv + 1) // 2), dtype=a.dtype), np.empty((n, nv // 2), dtype=a.dtype)
    _split_rows(a, ae, ao)
    return ae, ao


class CpuMultigrid:
    """The CPU backend's :class:`~clothgrid.backends.protocol.MultigridOps`.

    Parameters
    ----------
    levels : list of Level
        The hierarchy, finest first (:func:`~clothgrid.multigrid_levels.build_hierarchy`).
    x0 : numpy.ndarray
        ``(nu, nv, k)`` level-0 iterate (boundary nodes hold the data).
    rhs : numpy.ndarray, optional
        ``(nu-2, nv-2, k)`` level-0 right-hand side over interior nodes (zero if omitted).
    spare : numpy.ndarray, optional
        Memory whose contents are dead once ``x0`` and ``rhs`` have been read (``x0`` may view
        it): the line solves' scratch and the coarse levels are carved out of it
        (:class:`~clothgrid.memory.Arena`) as far as they fit. Its contents are undefined
        afterwards.
    scratch : CpuMultigrid, optional
        Operations on a grid of the same size whose line-solve scratch these share (never used
        at the same time: :meth:`residual_solve`'s).
    """

    def __init__(self, levels: list[Level], x0: np.ndarray, rhs: np.ndarray | None = None,
                 spare: np.ndarray | None = None, scratch: "CpuMultigrid | None" = None):
        self.levels = len(levels)
        self._hierarchy = levels
        #: what _max_step5 is given for the planes it does not write
        self._no_planes = np.zeros((1, 1, 1))
        self._shape = x0.shape
        k = x0.shape[2]
        self._has_b = rhs is not None
        self.nv = [lv.shape[1] for lv in levels]
        self.nodes = [lv.shape[0] * lv.shape[1] for lv in levels]
        # Lines per block by level: a coarse level with few rows in more, shorter blocks, so that
        # every thread gets one (at 1024^2 level 2 has 128 rows a parity: one block of 128 kept
        # one of two threads idle).
        threads = numba.get_num_threads()
        per_thread = [-(-(nv // 2) // threads) for nv in self.nv]      # rows of a parity / threads, rounded up
        self.mbs = [LINE_BLOCK if n < _PARALLEL_NODES else min(LINE_BLOCK, max(16, (r + 7) // 8 * 8))
                    for n, r in zip(self.nodes, per_thread)]
        # Level 0's planes come from spare where x0 and rhs do not view it (a barrier solve run in
        # the memory of another solve's coarse levels: MultigridOps.spare), else fresh.
        self._arena = arena = Arena(spare)
        into = arena if spare is not None and not any(
            a is not None and np.may_share_memory(a, spare) for a in (x0, rhs)) else None
        self.x = [_parity_planes(x0, arena=into)]
        if rhs is not None:
            self.b = [_parity_planes(x0, arena=into, interior=rhs)]
        else:
            self.b = [(np.zeros((k, 1, 1)), np.zeros((k, 1, 1)))]
        #: where the memory spare() lends starts: after level 0's planes
        self._lend_from = arena.position
        fine = levels[0]
        # A level 0 with an explicit centre (a 9-point level: the 5-point stencil plus a diagonal
        # term, e.g. the heat solver's mass over the time step) runs the coarse levels' kernels in
        # float64; it always has a right-hand side array.
        self.nine0 = fine.sep is None and fine.nine
        if self.nine0:
            self.st = [sum((_split(np.ascontiguousarray(a, dtype=np.float64))
                            for a in (fine.C, fine.E, fine.N, fine.NE)), ())]
            if rhs is None:
                self._has_b = True
                self.b = [_parity_planes(np.zeros(x0.shape))]
        else:
            self.st = [_level_split(fine, lambda: (fine.E, fine.N))]   # Ee, Eo, Ne, No
        # Unit-stencil level 0 (E, N stride-0 views: E[i, j] = e[j], N[i, j] = nn[i]): its 1D factors.
        self.unit0 = None
        if not self.nine0 and fine.E.strides[0] == 0 and fine.N.strides[1] == 0 and x0.shape[0] > 2:
            e = np.ascontiguousarray(fine.E[0], dtype=np.float64)
            self.unit0 = (np.ascontiguousarray(e[0::2]), np.ascontiguousarray(e[1::2]),
                          np.ascontiguousarray(fine.N[:, 0], dtype=np.float64))
        self.sep = [False]
        #: per level, the row parity solved last if nothing it reads has changed since (see smooth)
        self._solved: list[int | None] = [None] * self.levels
        #: the iterate, its right-hand side and has_b while conjugate gradients bind others (bind)
        self._own: tuple | None = None
        #: (barriers, the kernel's arrays, their negative coverages) of a per-edge level 0 (band_steps)
        self._bands: tuple | None = None
        dt = np.float32
        # The line solves' scratch (Thomas factors of one block of rows per thread), allocated
        # once: a fresh 1-2 MB array per block and sweep cost page faults, up to half a sweep's time.
        # Every level has the finest level's columns.
        nthreads = numba.config.NUMBA_NUM_THREADS
        # Rows 0 .. nu-2 hold the factors g, row nu the current column's 1 / d.
        mb = max(self.mbs)
        # x0 and rhs have been read (level 0's planes above): from here on spare's memory is free.
        # Every operation writes a coarse level's iterate and right-hand side (boundary rows
        # included) before it reads them, and the line solves their scratch rows, so neither
        # needs a first value (a test runs a solve in a spare full of NaN).
        if scratch is not None and scratch._shape[:2] == x0.shape[:2] and max(scratch.mbs) >= mb:
            # another solve's on the same grid, never in use at the same time (residual_solve)
            self._scr, self._rows = scratch._scr, scratch._rows
        else:
            self._scr = {np.dtype(t): arena.empty((nthreads, x0.shape[0] + 1, mb), t)
                         for t in (np.float64, np.float32)}
            self._rows = arena.empty((nthreads, x0.shape[1] + 2), np.float64)   # restriction's residual rows
        #: where the coarse levels start in spare's memory: what residual_solve lends (the scratch shared)
        self._coarse_from = arena.position
        for lv in levels[1:]:
            nu, nv = lv.shape
            self.x.append(tuple(arena.empty((k, nu, n), dt) for n in ((nv + 1) // 2, nv // 2)))
            self.b.append(tuple(arena.empty((k, nu, n), dt) for n in ((nv + 1) // 2, nv // 2)))
            self.sep.append(lv.sep is not None)
            if lv.sep is not None:   # cu, kud, du over columns; md, mu, kd, ku split by row parity
                sp = lv.sep
                cu = np.r_[sp.cu, 0.0]
                cols = tuple(np.ascontiguousarray(a, dtype=dt) for a in (cu, np.r_[0.0, sp.cu] + cu, sp.du))
                rows = tuple(np.ascontiguousarray(a[par::2], dtype=dt) for a in (sp.md, sp.mu, sp.kd, sp.ku)
                             for par in (0, 1))
                self.st.append(cols + rows)   # cu, kud, du, mde, mdo, mue, muo, kde, kdo, kue, kuo
            else:
                self.st.append(_level_split(lv, lambda lv=lv: (lv.C, lv.E, lv.N, lv.NE)))

    def _kernel(self, name: str, level: int):
        """Kernel ``name`` for ``level``: parallel, or its serial twin on a small level of a small
        hierarchy (:data:`_PARALLEL_NODES`, :data:`_ALL_PARALLEL_NODES`)."""
        return _pick(name, self.nodes[level], self.nodes[0])

    def smooth(self, level: int, reverse: bool = False) -> None:
        """One zebra line sweep: even rows then odd rows (odd then even if ``reverse``).

        A half-sweep whose rows were the last ones solved on this level, with nothing they read
        changed since (the other rows, the right-hand side), is skipped: a line solve reads only
        those, so it would write the same bits again. That is level 0's even half-sweep at the
        start of each V-cycle after the first (the previous cycle ended with it) and after the
        full-multigrid start: two of a solve's level-0 sweeps' four halves fewer.
        """
        (xe, xo), (be, bo), st, nv = self.x[level], self.b[level], self.st[level], self.nv[level]
        scr, mb = self._scr[xe.dtype], self.mbs[level]
        for p in ((1, 0) if reverse else (0, 1)):
            if self._solved[level] == p:
                continue
            self._solved[level] = p
            own, other = (xe, xo) if p == 0 else (xo, xe)
            b = be if p == 0 else bo
            if level == 0 and self.unit0 is not None:
                ee, eo, nn = self.unit0
                self._kernel("_relax5u", level)(own, other, b, (ee, eo)[p], nn, p, nv, self._has_b, mb,
                                                     scr)
            elif level == 0 and not self.nine0:
                Ee, Eo, Ne, No = st
                self._kernel("_relax5", level)(own, other, b, (Ee, Eo)[p], (Ne, No)[p], (No, Ne)[p],
                                                    p, nv, self._has_b, mb, scr)
            elif self.sep[level]:
                cu, kud, du, mde, mdo, mue, muo, kde, kdo, kue, kuo = st
                q = 1 - p
                md, mu, kd, ku = (mde, mdo), (mue, muo), (kde, kdo), (kue, kuo)
                self._kernel("_relax9s", level)(own, other, b, cu, kud, du, md[p], mu[p], kd[p], ku[p],
                                                     mu[q], ku[q], p, nv, mb, scr)
            else:
                Ce, Co, Ee, Eo, Ne, No, NEe, NEo = st
                q = 1 - p
                self._kernel("_relax9", level)(own, other, b, (Ce, Co)[p], (Ee, Eo)[p], (Ne, No)[p],
                                                    (Ne, No)[q], (NEe, NEo)[p], (NEe, NEo)[q], p, nv, mb, scr)

    def restrict(self, level: int) -> None:
        """``b[l+1] = P^T (b[l] - A x[l])`` from the even rows (the odd rows' residual is zero
        after pre-smoothing); ``x[l+1] = 0``."""
        (xe, xo), (be, _), st = self.x[level], self.b[level], self.st[level]
        (bce, bco), (xce, xco) = self.b[level + 1], self.x[level + 1]
        self._solved[level + 1] = None
        if level == 0 and self.unit0 is not None:
            self._kernel("_restrict5u", level)(xe, xo, be, self.unit0[0], self.unit0[2], self._has_b,
                                                    bce, bco, xce, xco, self._rows)
        elif level == 0 and not self.nine0:
            Ee, _, Ne, No = st
            self._kernel("_restrict5", level)(xe, xo, be, Ee, Ne, No, self._has_b, bce, bco, xce, xco, self._rows)
        elif self.sep[level]:
            cu, kud, du, mde, _, mue, muo, kde, _, kue, kuo = st
            self._kernel("_restrict9s", level)(xe, xo, be, cu, kud, du, mde, mue, kde, kue, muo, kuo,
                                                    bce, bco, xce, xco, self._rows)
        else:
            Ce, _, Ee, _, Ne, No, NEe, NEo = st
            self._kernel("_restrict9", level)(xe, xo, be, Ce, Ee, Ne, No, NEe, NEo, bce, bco, xce, xco, self._rows)

    def prolong(self, level: int) -> None:
        """``x[l] += P x[l+1]`` on the even rows (the odd rows are re-solved next)."""
        xce, xco = self.x[level + 1]
        self._solved[level] = None
        self._kernel("_prolong", level)(self.x[level][0], xce, xco)

    def restrict_full(self, level: int) -> None:
        """Full-multigrid start: ``b[1] = P^T (b[0] - A x[0])`` with every row's residual
        (level 0), or ``b[l+1] = P^T b[l]`` (coarser levels); ``x[l+1] = 0``."""
        (bce, bco), (xce, xco) = self.b[level + 1], self.x[level + 1]
        self._solved[level + 1] = None
        if level == 0 and self.nine0:
            re, ro = _parity_planes(self._residual9())
            self._kernel("_restrict_rhs", 0)(re, ro, self.nv[0], bce, bco, xce, xco)
        elif level == 0 and self.unit0 is not None:
            (xe, xo), (be, bo) = self.x[0], self.b[0]
            ee, eo, nn = self.unit0
            self._kernel("_restrict5u_full", 0)(xe, xo, be, bo, ee, eo, nn, self._has_b, self.nv[0],
                                                     bce, bco, xce, xco, self._rows)
        elif level == 0:
            (xe, xo), (be, bo) = self.x[0], self.b[0]
            Ee, Eo, Ne, No = self.st[0]
            self._kernel("_restrict5_full", 0)(xe, xo, be, bo, Ee, Eo, Ne, No, self._has_b, self.nv[0],
                                                    bce, bco, xce, xco)
        else:
            be, bo = self.b[level]
            self._kernel("_restrict_rhs", level)(be, bo, self.nv[level], bce, bco, xce, xco)

    def prolong_full(self, level: int) -> None:
        """``x[l] += P x[l+1]`` on every row (full-multigrid start)."""
        xe, xo = self.x[level]
        self._solved[level] = None
        self._kernel("_prolong_full", level)(xe, xo, *self.x[level + 1], self.nv[level])

    def max_step(self) -> float:
        """``max |D^-1 (b - A x)|`` over level 0's interior nodes (Euclidean per node)."""
        if self.nine0:
            C = _merge_rows(*self.st[0][:2])[..., None]
            r = self._residual9()[1:-1, 1:-1]
            return float(np.max(np.linalg.norm(r, axis=-1) / C[1:-1, 1:-1, 0])) if r.size else 0.0
        (xe, xo), (be, bo) = self.x[0], self.b[0]
        if self.unit0 is not None:
            ee, eo, nn = self.unit0
            return float(self._kernel("_max_step5u", 0)(xe, xo, be, bo, ee, eo, nn, self.nv[0], self._has_b,
                                                             self._rows))
        return float(self._kernel("_max_step5", 0)(xe, xo, be, bo, *self.st[0], self.nv[0], self._has_b, 0.0,
                                                   self._no_planes, self._no_planes, False))

    def band_steps(self, barriers: Any) -> np.ndarray | None:
        """:func:`~clothgrid.solvers.bounds.band_steps` of level 0's iterate (its right-hand side
        included) for a :class:`~clothgrid.solvers.bounds.BandBarriers`, whose ``bound`` takes
        it; None for a 9-point level 0 (the heat solver's time steps)."""
        if self.nine0:
            return None
        (xe, xo), (be, bo) = self.x[0], self.b[0]
        if self.unit0 is None:
            Ee, Eo, Ne, No = self.st[0]
            if self._bands is None or self._bands[0] is not barriers:   # the kernel's arrays, once
                sv = barriers.slopes(1)
                self._bands = (barriers, (barriers.kv[0::2].copy(), barriers.kv[1::2].copy(), barriers.slopes(0),
                                          np.ascontiguousarray(sv[:, 0::2]), np.ascontiguousarray(sv[:, 1::2]),
                                          barriers.widths), None)
            _, (kve, kvo, su, sve, svo, widths), deficits = self._bands
            # the barriers' negative coverages depend on the weights alone: sought on the first call
            table = self._kernel("_band_steps5", 0)(
                xe, xo, be, bo, Ee, Eo, Ne, No, self.nv[0], self._has_b, self._rows.shape[0], barriers.ku,
                kve, kvo, su, sve, svo, widths, barriers.cost, float(barriers.zmax),
                float(barriers.reference) ** 2, barriers.buckets, deficits is None)
            if deficits is None:
                self._bands = self._bands[:2] + (table[barriers.deficits_at:].copy(),)
            else:
                table[barriers.deficits_at:] = deficits
            return table
        ee, eo, nn = self.unit0
        return self._kernel("_band_steps5u", 0)(xe, xo, be, bo, ee, eo, nn, self.nv[0], self._has_b,
                                                     self._rows, barriers.ku, barriers.kv[0::2].copy(),
                                                     barriers.kv[1::2].copy(), barriers.cost,
                                                     float(barriers.zmax), float(barriers.reference) ** 2,
                                                     barriers.buckets)

    def residual_solve(self, eps: float) -> tuple["CpuMultigrid", float] | None:
        """Operations for ``A y = q``, ``q = |b - A x| + eps D`` of this iterate (Euclidean over the
        coordinates), ``y`` zero, on the same hierarchy, and this iterate's :meth:`max_step`; None for a
        unit-stencil or 9-point level 0 (their bound is the band barriers'). They share this solve's
        line-solve scratch and live in the memory of its coarse levels (dead between cycles) as far as
        they fit; fresh memory beyond."""
        if self.nine0 or self.unit0 is not None or self._shape[0] < 3 or self._shape[1] < 3:
            return None
        nu, nv = self._shape[:2]
        ops = CpuMultigrid(self._hierarchy, np.zeros((nu, nv, 1)), None, self._arena.carved_since(self._coarse_from),
                           scratch=self)
        qe, qo = (ops._arena.empty(a.shape, np.float64) for a in ops.x[0])
        (xe, xo), (be, bo) = self.x[0], self.b[0]
        step = self._kernel("_max_step5", 0)(xe, xo, be, bo, *self.st[0], self.nv[0], self._has_b, float(eps),
                                             qe, qo, True)
        ops.b[0], ops._has_b = (qe, qo), True
        return ops, float(step)

    def relative_residual(self) -> float:
        """``max (b - A x) / b`` over level 0's interior nodes of a :meth:`residual_solve`'s operations."""
        (xe, xo), (be, bo) = self.x[0], self.b[0]
        return float(self._kernel("_relative_residual5", 0)(xe, xo, be, bo, *self.st[0], self.nv[0]))

    # ---- conjugate gradients around the V-cycle (clothgrid.solvers.multigrid.ConjugateGradients)

    def vector(self) -> tuple[np.ndarray, np.ndarray] | None:
        """A new level-0 vector for conjugate gradients: parity planes like the iterate's, zero (its
        boundary ring stays zero); None for a 9-point level 0 (the heat solver's time steps)."""
        if self.nine0:
            return None
        xe, xo = self.x[0]
        return np.zeros(xe.shape), np.zeros(xo.shape)

    def residual(self, r: tuple[np.ndarray, np.ndarray]) -> None:
        """``r = b - A x`` of the iterate on the interior nodes."""
        self._kernel("_apply5", 0)(*self.x[0], *self.b[0], *self.st[0][:4], self.nv[0], self._has_b, 1.0, *r)

    def apply(self, p: tuple[np.ndarray, np.ndarray], q: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """``q = A p`` (``p`` zero on the ring); returns ``p . q`` per coordinate."""
        return self._kernel("_apply5", 0)(*p, *p, *self.st[0][:4], self.nv[0], False, -1.0, *q)   # no b read

    def dot(self, a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """``a . b`` per coordinate."""
        return self._kernel("_dot", 0)(*a, *b)

    def axpy(self, r: tuple[np.ndarray, np.ndarray], p: tuple[np.ndarray, np.ndarray],
             q: tuple[np.ndarray, np.ndarray], alpha: np.ndarray) -> None:
        """``x += alpha p`` (the iterate), ``r -= alpha q``; ``alpha`` per coordinate."""
        self._solved[0] = None
        self._kernel("_axpy", 0)(*self.x[0], *r, *p, *q, np.ascontiguousarray(alpha, dtype=np.float64))

    def xpay(self, p: tuple[np.ndarray, np.ndarray], z: tuple[np.ndarray, np.ndarray], beta: np.ndarray) -> None:
        """``p = z + beta p``; ``beta`` per coordinate."""
        self._kernel("_xpay", 0)(*p, *z, np.ascontiguousarray(beta, dtype=np.float64))

    def bind(self, r: tuple[np.ndarray, np.ndarray] | None, z: tuple[np.ndarray, np.ndarray] | None) -> None:
        """Until ``bind(None, None)``, level 0's right-hand side is ``r`` and its iterate ``z``, set to
        zero: a V-cycle then makes ``z = M r``. ``bind(None, None)`` brings back the iterate and its
        right-hand side."""
        if r is None:
            if self._own:
                self.x[0], self.b[0], self._has_b = self._own
                self._own = None
        else:
            if not self._own:
                self._own = (self.x[0], self.b[0], self._has_b)
            z[0].fill(0.0)
            z[1].fill(0.0)
            self.x[0], self.b[0], self._has_b = z, r, True
        self._solved[0] = None

    def _residual9(self) -> np.ndarray:
        """``b - A x`` of a 9-point level 0 as an ``(nu, nv, k)`` float64 array (zero on the boundary)."""
        C, E, N, NE = (_merge_rows(*self.st[0][2 * q:2 * q + 2]) for q in range(4))
        NW = diagonal_partner(NE)
        x = self.solution()
        b = np.empty(self._shape)
        _merge_grid(*self.b[0], b)
        r = np.zeros(self._shape)
        c = x[1:-1, 1:-1]
        s = b[1:-1, 1:-1] - C[1:-1, 1:-1, None] * c
        s += E[:-2, 1:-1, None] * x[:-2, 1:-1] + E[1:-1, 1:-1, None] * x[2:, 1:-1]
        s += N[1:-1, :-2, None] * x[1:-1, :-2] + N[1:-1, 1:-1, None] * x[1:-1, 2:]
        s += NE[1:-1, 1:-1, None] * x[2:, 2:] + NE[:-2, :-2, None] * x[:-2, :-2]
        s += NW[1:-1, 1:-1, None] * x[:-2, 2:] + NW[2:, :-2, None] * x[2:, :-2]
        r[1:-1, 1:-1] = s
        return r

    def solution(self) -> np.ndarray:
        """Level 0's iterate as a float64 ``(nu, nv, k)`` array."""
        out = np.empty(self._shape)
        self.solution_into(out)
        return out

    def solution_max(self) -> float:
        """The largest interior value of level 0's iterate, first coordinate, from its parity planes
        (no merged copy: 13 ms of fresh pages at 1024^2 on this VM)."""
        xe, xo = self.x[0]
        nu, nv = self._shape[:2]
        if nu < 3 or nv < 3:
            return -np.inf
        parts = [(xe if p == 0 else xo)[0, 1:-1, slice(*_line_range(nv, p))] for p in (0, 1)]
        return float(max(a.max() for a in parts if a.size))

    def solution_into(self, out: np.ndarray) -> None:
        """Write level 0's iterate into ``out`` (``(nu, nv, k)``, any strides).

        First gives the pages of the coarse levels not kept in ``spare``'s memory back to the
        system when they are large (:data:`clothgrid.memory.DISCARD_MIN_BYTES`): between cycles
        their contents are dead (every cycle, and the full multigrid start, writes a coarse level's
        iterate and right-hand side before reading them), so the released pages, which read as
        zero, change nothing; and the solution's grid, often written here for the first time, does
        not add to them (268 MB at 4096^2 for two coordinates). ``out`` may view ``spare``.
        """
        coarse = [a for lv in (self.x[1:] + self.b[1:]) for a in lv if not self._arena.owns(a)]
        if sum(a.nbytes for a in coarse) >= DISCARD_MIN_BYTES:
            for a in coarse:
                discard(a)
        self._kernel("_merge_grid", 0)(*self.x[0], out)

    def synchronize(self) -> None:
        """Nothing to wait for: every kernel has returned when its call does."""

    def spare(self) -> np.ndarray | None:
        """The part of ``spare``'s memory holding the coarse levels and the line solves' scratch (dead
        until the next full-multigrid start or V-cycle: each writes them before reading them), or
        None if none of them is there."""
        return self._arena.carved_since(self._lend_from)

    def extra(self) -> dict[str, Any]:
        """No keys for the result's info: ``{}``."""
        return {}
