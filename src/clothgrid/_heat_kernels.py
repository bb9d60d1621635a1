"""Numba kernels of the heat solver's black-box multigrid and conjugate gradients.

Low level on purpose: plain arrays in, plain arrays out; imports only Numba
and NumPy. :mod:`clothgrid.heat_multigrid` builds the hierarchy and drives
them. Every grid array is padded with a ring: shape ``(nu + 2, nv + 2)``,
unknowns at ``1..nu`` x ``1..nv``, the ring zero (homogeneous Dirichlet for
corrections; the boundary data of :mod:`clothgrid.heat` is in the right-hand
side). Loops run over the interior only; parallel over the first index.

Stencils:

- level 0, 5 points: ``we[i, j]`` the conductance ``(i, j)-(i+1, j)``,
  ``wn[i, j]`` ``(i, j)-(i, j+1)`` (positive, zero where either end is the
  ring), ``d[i, j]`` the diagonal (all four conductances, those to the ring
  included, plus any mass term) and ``c0[i, j]`` the diagonal less the
  conductances between unknowns (those to the ring and the mass term);
- coarse levels, 9 points: ``S[i, j, k]`` the matrix entry of row ``(i, j)``
  for the neighbour ``(i + di, j + dj)``, ``k = 3 (di + 1) + (dj + 1)``
  (``k = 4``: the diagonal), zero for neighbours on the ring.

Interpolation (Dendy's black-box multigrid): ``P[i, j, a + 2 b]`` is the
weight of fine point ``(i, j)``'s parent ``(i // 2 + a, j // 2 + b)``
(``a = 1`` or ``b = 1`` only along an odd coordinate), zero for parents on
the coarse ring. Coarse point ``I`` is fine point ``2 I``.

Compiled once and cached on disk (``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np

from .jit_variants import fork_safe

_OPTS = dict(cache=True, nogil=True, error_model="numpy", fastmath=False)

# --------------------------------------------------------------------------- level 0: 5 points


@numba.njit(inline="always")
def _flux5(we, wn, c0, x, i, j):
    """Row ``(i, j)`` of ``A x`` in flux form, ``c0 x + sum w (x - x_nb)``: the differences first, so that
    its rounding error is that of the fluxes, not of ``d x`` (10^4 times larger in a conductor)."""
    xc = x[i, j]
    return (c0[i, j] * xc + we[i - 1, j] * (xc - x[i - 1, j]) + we[i, j] * (xc - x[i + 1, j])
            + wn[i, j - 1] * (xc - x[i, j - 1]) + wn[i, j] * (xc - x[i, j + 1]))


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def apply5_dot(we, wn, c0, x, out):
    """``out = A x`` on the interior (``c0``: the diagonal less the couplings between unknowns); returns
    ``x . out``."""
    nu = x.shape[0] - 2
    nv = x.shape[1] - 2
    s = 0.0
    for i in numba.prange(1, nu + 1):
        t = 0.0
        for j in range(1, nv + 1):
            v = _flux5(we, wn, c0, x, i, j)
            out[i, j] = v
            t += v * x[i, j]
        s += t
    return s


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def residual5(we, wn, c0, b, x, r, i0=1, step=1):
    """``r = b - A x`` on the interior rows ``i0, i0 + step, ...`` (flux form, as :func:`apply5_dot`)."""
    nu = x.shape[0] - 2
    nv = x.shape[1] - 2
    for t in numba.prange((nu - i0) // step + 1):
        i = i0 + step * t
        for j in range(1, nv + 1):
            r[i, j] = b[i, j] - _flux5(we, wn, c0, x, i, j)


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def five_to_nine(we, wn, d, S):
    """The 9-point form of a 5-point level (corners zero)."""
    nu = d.shape[0] - 2
    nv = d.shape[1] - 2
    for i in numba.prange(nu + 2):
        for j in range(nv + 2):
            for k in range(9):
                S[i, j, k] = 0.0
            if 1 <= i <= nu and 1 <= j <= nv:
                S[i, j, 4] = d[i, j]
                S[i, j, 1] = -we[i - 1, j]     # (i-1, j); we, wn are zero towards the ring
                S[i, j, 7] = -we[i, j]         # (i+1, j)
                S[i, j, 3] = -wn[i, j - 1]     # (i, j-1)
                S[i, j, 5] = -wn[i, j]         # (i, j+1)


# --------------------------------------------------------------------------- coarse levels: 9 points


@numba.njit(inline="always")
def _row9(S, x, i, j):
    """Row ``(i, j)`` of ``S`` times ``x`` without the diagonal."""
    return (S[i, j, 0] * x[i - 1, j - 1] + S[i, j, 1] * x[i - 1, j] + S[i, j, 2] * x[i - 1, j + 1]
            + S[i, j, 3] * x[i, j - 1] + S[i, j, 5] * x[i, j + 1]
            + S[i, j, 6] * x[i + 1, j - 1] + S[i, j, 7] * x[i + 1, j] + S[i, j, 8] * x[i + 1, j + 1])


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def residual9(S, b, x, r, i0=1, step=1):
    """``r = b - A x`` on the interior rows ``i0, i0 + step, ...``."""
    nu = x.shape[0] - 2
    nv = x.shape[1] - 2
    for t in numba.prange((nu - i0) // step + 1):
        i = i0 + step * t
        for j in range(1, nv + 1):
            r[i, j] = b[i, j] - S[i, j, 4] * x[i, j] - _row9(S, x, i, j)


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def line_factors(S, we, wn, d, five, cp, im):
    """The Thomas factors of every line along ``j``, once per level: ``cp`` the eliminated
    super-diagonal, ``im`` the inverse pivots (of ``S``, or of ``we``, ``wn``, ``d`` when ``five``)."""
    nu = cp.shape[0] - 2
    nv = cp.shape[1] - 2
    for i in numba.prange(1, nu + 1):
        prev_c = 0.0
        for j in range(1, nv + 1):
            if five:
                a, c, m0 = -wn[i, j - 1], -wn[i, j], d[i, j]
            else:
                a, c, m0 = S[i, j, 3], S[i, j, 5], S[i, j, 4]
            inv = 1.0 / (m0 - a * prev_c)
            prev_c = c * inv
            cp[i, j] = prev_c
            im[i, j] = inv


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def lines5(we, wn, b, x, colour, cp, im, dp, first=False):
    """Zebra line Gauss-Seidel: solve every line ``i`` with ``i % 2 == colour`` exactly along ``j``
    (tridiagonal, factors from :func:`line_factors`), its neighbour lines ``i - 1``, ``i + 1`` held
    (``first``: taken as zero, whatever ``x`` holds there: the first half sweep from zero)."""
    nu = x.shape[0] - 2
    nv = x.shape[1] - 2
    i0 = 2 - colour
    rows = (nu - i0) // 2 + 1
    for t in numba.prange(rows):
        i = i0 + 2 * t
        prev = 0.0
        for j in range(1, nv + 1):
            rhs = b[i, j]
            if not first:
                rhs += we[i - 1, j] * x[i - 1, j] + we[i, j] * x[i + 1, j]
            prev = (rhs + wn[i, j - 1] * prev) * im[i, j]
            dp[i, j] = prev
        v = 0.0
        for j in range(nv, 0, -1):
            v = dp[i, j] - cp[i, j] * v
            x[i, j] = v


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def lines9(S, b, x, colour, cp, im, dp, first=False):
    """Zebra line Gauss-Seidel on a 9-point level (as :func:`lines5`)."""
    nu = x.shape[0] - 2
    nv = x.shape[1] - 2
    i0 = 2 - colour
    rows = (nu - i0) // 2 + 1
    for t in numba.prange(rows):
        i = i0 + 2 * t
        prev = 0.0
        for j in range(1, nv + 1):
            rhs = b[i, j]
            if not first:
                rhs -= (S[i, j, 0] * x[i - 1, j - 1] + S[i, j, 1] * x[i - 1, j] + S[i, j, 2] * x[i - 1, j + 1]
                        + S[i, j, 6] * x[i + 1, j - 1] + S[i, j, 7] * x[i + 1, j] + S[i, j, 8] * x[i + 1, j + 1])
            prev = (rhs - S[i, j, 3] * prev) * im[i, j]
            dp[i, j] = prev
        v = 0.0
        for j in range(nv, 0, -1):
            v = dp[i, j] - cp[i, j] * v
            x[i, j] = v


# --------------------------------------------------------------------------- transfers


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def restrict_even(P, r, bc):
    """``bc = P^T r`` for a residual that is zero on the odd rows ``i`` (after a zebra sweep that ends
    with the odd lines: their equations hold exactly), reading the even rows only."""
    nv = r.shape[1] - 2
    ncu = bc.shape[0] - 2
    ncv = bc.shape[1] - 2
    for I in numba.prange(1, ncu + 1):
        i = 2 * I
        for J in range(1, ncv + 1):
            j = 2 * J
            s = r[i, j] + P[i, j - 1, 2] * r[i, j - 1]
            if j + 1 <= nv:
                s += P[i, j + 1, 0] * r[i, j + 1]
            bc[I, J] = s


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def prolong_add_even(P, xc, x):
    """``x += P xc`` on the even rows ``i`` only: before a zebra sweep that starts with the odd lines,
    which overwrite their own values, only the even rows' correction is ever read."""
    nu = x.shape[0] - 2
    nv = x.shape[1] - 2
    for t in numba.prange(nu // 2):
        i = 2 * (t + 1)
        I = i // 2
        for j in range(1, nv + 1):
            J = j // 2
            x[i, j] += P[i, j, 0] * xc[I, J] + P[i, j, 2] * xc[I, J + 1]


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def interpolation(S, ncu, ncv, P, work):
    """Operator-dependent interpolation weights ``P`` from a 9-point level ``S`` (``work``: scratch
    ``(3, nu + 2, nv + 2)``).

    - a fine point between two coarse points along ``v`` (even ``i``, odd ``j``) takes the weights of its
      row collapsed across ``u`` (Dendy: ``-a_S / a_C``, ``-a_N / a_C``);
    - the points of an odd row ``i`` between two coarse points along ``u`` (odd ``i``, even ``j``) take
      their weights from the row's **line** operator ``T_i`` (its couplings along ``v`` and the
      diagonal): ``w_W = T_i^-1 c_W``, ``w_E = T_i^-1 c_E`` with ``c_W``, ``c_E`` the couplings to rows
      ``i -/+ 1`` collapsed along ``v`` (Schaffer's semicoarsening collapse: the line's response to a
      coarse correction constant along it). Where the coupling along ``v`` is weak this is Dendy's
      pointwise ``c_W / (c_W + c_E)``; where it is strong the weights are averaged along the line, so that
      a correction smooth along the strong lines stays smooth (the pointwise weights vary along the line
      with the conductivities, which gave the Galerkin coarse operators of strongly stretched cells with
      random ``k`` a poor near-null space: 44-70 CG iterations instead of 6-8);
    - a point between four coarse points takes ``-(a_SW + a_W P_W + a_S P_S) / a_0`` and so on, from its
      neighbours' weights (Dendy).

    Weights to parents on the coarse ring are zero.
    """
    nu = S.shape[0] - 2
    nv = S.shape[1] - 2
    for i in numba.prange(nu + 2):
        for j in range(nv + 2):
            for k in range(4):
                P[i, j, k] = 0.0
    for i in numba.prange(1, nu + 1):
        if i % 2 == 1:
            continue
        for j in range(1, nv + 1):
            if j % 2 == 0:
                P[i, j, 0] = 1.0
            else:
                c = S[i, j, 1] + S[i, j, 4] + S[i, j, 7]
                P[i, j, 0] = -(S[i, j, 0] + S[i, j, 3] + S[i, j, 6]) / c
                P[i, j, 2] = -(S[i, j, 2] + S[i, j, 5] + S[i, j, 8]) / c
    rows = (nu + 1) // 2
    for t in numba.prange(rows):               # odd rows: T_i w = c_W, T_i w = c_E (Thomas along j)
        i = 2 * t + 1
        cp = work[0, i]
        dw = work[1, i]
        de = work[2, i]
        prev_c = 0.0
        pw = 0.0
        pe = 0.0
        for j in range(1, nv + 1):
            a = S[i, j, 3]
            inv = 1.0 / (S[i, j, 4] - a * prev_c)
            prev_c = S[i, j, 5] * inv
            cp[j] = prev_c
            pw = (-(S[i, j, 0] + S[i, j, 1] + S[i, j, 2]) - a * pw) * inv
            pe = (-(S[i, j, 6] + S[i, j, 7] + S[i, j, 8]) - a * pe) * inv
            dw[j] = pw
            de[j] = pe
        vw = 0.0
        ve = 0.0
        for j in range(nv, 0, -1):
            vw = dw[j] - cp[j] * vw
            ve = de[j] - cp[j] * ve
            if j % 2 == 0:
                P[i, j, 0] = vw
                P[i, j, 1] = ve
    for t in numba.prange(rows):
        i = 2 * t + 1
        for j in range(1, nv + 1, 2):
            c = S[i, j, 4]
            w = S[i, j, 1]       # (i-1, j): an (even, odd) point, parents slots 0 (below), 2 (above)
            e = S[i, j, 7]
            s = S[i, j, 3]       # (i, j-1): an (odd, even) point, parents slots 0 (left), 1 (right)
            n = S[i, j, 5]
            P[i, j, 0] = -(S[i, j, 0] + w * P[i - 1, j, 0] + s * P[i, j - 1, 0]) / c
            P[i, j, 1] = -(S[i, j, 6] + e * P[i + 1, j, 0] + s * P[i, j - 1, 1]) / c
            P[i, j, 2] = -(S[i, j, 2] + w * P[i - 1, j, 2] + n * P[i, j + 1, 0]) / c
            P[i, j, 3] = -(S[i, j, 8] + e * P[i + 1, j, 2] + n * P[i, j + 1, 1]) / c
    for i in numba.prange(1, nu + 1):
        for j in range(1, nv + 1):
            for a in range(2):
                for b in range(2):
                    I = i // 2 + a
                    J = j // 2 + b
                    if I < 1 or I > ncu or J < 1 or J > ncv:
                        P[i, j, a + 2 * b] = 0.0


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def galerkin(S, P, Sc):
    """The coarse 9-point operator ``Sc = P^T A P`` of a 9-point level ``S`` and its interpolation ``P``."""
    nu = S.shape[0] - 2
    nv = S.shape[1] - 2
    ncu = Sc.shape[0] - 2
    ncv = Sc.shape[1] - 2
    for I in numba.prange(ncu + 2):
        acc = np.zeros(9)
        for J in range(ncv + 2):
            for k in range(9):
                acc[k] = 0.0
            if 1 <= I <= ncu and 1 <= J <= ncv:
                for di in range(-1, 2):
                    pi = 2 * I + di
                    if pi > nu:
                        continue
                    a = 1 if di == -1 else 0
                    for dj in range(-1, 2):
                        pj = 2 * J + dj
                        if pj > nv:
                            continue
                        b = 1 if dj == -1 else 0
                        wp = P[pi, pj, a + 2 * b]
                        if wp == 0.0:
                            continue
                        for si in range(-1, 2):
                            qi = pi + si
                            for sj in range(-1, 2):
                                apq = S[pi, pj, 3 * (si + 1) + sj + 1]
                                if apq == 0.0:
                                    continue
                                qj = pj + sj
                                f = wp * apq
                                for a2 in range(2):
                                    Di = qi // 2 + a2 - I
                                    for b2 in range(2):
                                        wq = P[qi, qj, a2 + 2 * b2]
                                        if wq != 0.0:
                                            Dj = qj // 2 + b2 - J
                                            acc[3 * (Di + 1) + Dj + 1] += f * wq
            for k in range(9):
                Sc[I, J, k] = acc[k]


# --------------------------------------------------------------------------- conjugate-gradient vectors


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def dot(a, b):
    """``sum(a * b)`` over the interior."""
    nu = a.shape[0] - 2
    nv = a.shape[1] - 2
    s = 0.0
    for i in numba.prange(1, nu + 1):
        t = 0.0
        for j in range(1, nv + 1):
            t += a[i, j] * b[i, j]
        s += t
    return s


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def update_xr(x, r, p, q, alpha):
    """``x += alpha p``, ``r -= alpha q``; returns ``r . r``."""
    nu = x.shape[0] - 2
    nv = x.shape[1] - 2
    s = 0.0
    for i in numba.prange(1, nu + 1):
        t = 0.0
        for j in range(1, nv + 1):
            x[i, j] += alpha * p[i, j]
            v = r[i, j] - alpha * q[i, j]
            r[i, j] = v
            t += v * v
        s += t
    return s


@fork_safe
@numba.njit(parallel=True, **_OPTS)
def update_p(p, z, beta):
    """``p = z + beta p`` on the interior."""
    nu = p.shape[0] - 2
    nv = p.shape[1] - 2
    for i in numba.prange(1, nu + 1):
        for j in range(1, nv + 1):
            p[i, j] = z[i, j] + beta * p[i, j]
