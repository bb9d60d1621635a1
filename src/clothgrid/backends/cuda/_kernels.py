"""numba.cuda kernels of the cuda multigrid: the CPU multigrid's (``backends/_cpu_multigrid.py``) on a GPU.

Layout, stencils and arithmetic are the CPU kernels'. A level's iterate and
right-hand side are parity planes ``xe[c, i, m] = x[i, 2m, c]`` and
``xo[c, i, m] = x[i, 2m+1, c]``; level 0 is float64 with the 5-point stencil of
the edge weights ``E`` (``wu``) and ``N`` (``wv``), split by row parity like the
iterate; coarse levels are float32 with the 9-point stencil ``C, E, N, NE,
NW``. For a row of parity ``p`` ("own"), the rows below and above are the other
parity's ``m + ob`` and ``m + ob + 1`` (``ob = 0`` for odd rows, ``-1`` for even
rows). Every expression keeps the CPU kernel's order of operations.

Level 0's ``E`` may not depend on ``i`` (the paper's and uniform weights) and
``N`` not on ``j``: the kernels read ``E[i * ei, m]`` and ``N[i, m * nm]``, so
``ei = 0`` with an ``E`` of one row and ``nm = 0`` with an ``N`` of one column
read the 1D factors without forming the ``(nu, nv)`` arrays.

Threads. Node kernels run one thread per node (or coarse node) of a 2D grid
``(m or J, i)``: neighbouring threads take neighbouring ``m``, which are
neighbours in memory. Line solves (zebra relaxation) run one thread per line
``m`` and per *block* of ``L`` consecutive columns ``i`` (the partition method):

1. :func:`line_blocks` solves each block's tridiagonal system (Thomas) with its
   end neighbours taken as zero, and its two *spikes*, the responses ``yl``,
   ``yr`` to a unit value of the separator node left and right of the block;
   the first and last blocks read the boundary nodes as the CPU does. It also
   writes each separator's diagonal and right-hand side;
2. :func:`line_separators` solves, one thread per line, the tridiagonal system
   of the separators (nodes ``i = L+1, 2(L+1), ...``) that the spikes give;
3. :func:`line_spread` adds the separators' spikes to every other node.

:func:`line_solve` does the three in one launch (the default where a line's
blocks fit one thread block), with a barrier between them: a thread block
holds whole lines, so no line waits for the others' blocks, and a colour
costs one launch instead of three; the arithmetic, and so the bits, are the
same.

A line of ``nu`` nodes then takes about ``2 L + 2 nu / L`` dependent steps
instead of the Thomas algorithm's ``2 nu``, which on a GPU (memory latency
per step, and as few as one line per coarse level) is the difference between
milliseconds and microseconds per sweep at ``nu = 16384``. With a single block
(``nsep = 0``) :func:`line_blocks` is exactly the CPU's Thomas solve. Thomas
scratch (``g``, ``yl``, ``yr``) is ``(nu, lines)``: neighbouring threads, at the
same ``i``, touch neighbouring addresses.

Numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``) runs these kernels on the
CPU, one Python thread per GPU thread: the tests check them there.
"""

from __future__ import annotations

from ._compat import patch_numpy

patch_numpy()   # numba-cuda <= 0.30.4 with NumPy >= 2.5 (see _compat)

from numba import cuda  # noqa: E402

#: Coordinates per node the kernels handle (per-thread carried values live in local arrays).
MAX_COORDS = 3


# --- device functions ---------------------------------------------------------------------------------

@cuda.jit(device=True)
def _get(ae, ao, c, i, J):
    """Coarse row ``J`` of parity planes ``ae``, ``ao``."""
    if J % 2 == 0:
        return ae[c, i, J // 2]
    return ao[c, i, J // 2]


@cuda.jit(device=True)
def _put(ae, ao, c, i, J, v):
    """Set coarse row ``J`` of parity planes ``ae``, ``ao`` to ``v``."""
    if J % 2 == 0:
        ae[c, i, J // 2] = v
    else:
        ao[c, i, J // 2] = v


@cuda.jit(device=True)
def _coef(Co, Eo, No, Nt, i, m, ob, ei, nm, nine):
    """``(E to i-1, E to i+1, diagonal)`` of own-parity node ``(i, m)`` in its line's system."""
    elo = Eo[(i - 1) * ei, m]
    ehi = Eo[i * ei, m]
    if nine:
        return elo, ehi, Co[i, m]
    return elo, ehi, elo + ehi + Nt[i, (m + ob) * nm] + No[i, m * nm]


@cuda.jit(device=True)
def _rhs(xt, bo, No, Nt, NEo, NEt, NWo, NWt, c, i, m, ob, nm, has_b, nine):
    """The right-hand side of node ``(i, m)`` in its line's system: ``b`` plus the other rows' pull."""
    if has_b:
        r = bo[c, i, m] + Nt[i, (m + ob) * nm] * xt[c, i, m + ob]
    else:
        r = Nt[i, (m + ob) * nm] * xt[c, i, m + ob]
    r += No[i, m * nm] * xt[c, i, m + ob + 1]
    if nine:
        r += NEo[i, m] * xt[c, i + 1, m + ob + 1]
        r += NEt[i - 1, m + ob] * xt[c, i - 1, m + ob]
        r += NWo[i, m] * xt[c, i - 1, m + ob + 1]
        r += NWt[i + 1, m + ob] * xt[c, i + 1, m + ob]
    return r


@cuda.jit(device=True)
def _res5(x, t, b, E, No, Nt, c, i, m, ob, ei, nm, has_b):
    """Residual ``b - A x`` of level 0 at own-parity node ``(i, m)`` (the CPU's ``_res5``)."""
    xc = x[c, i, m]
    r = (E[(i - 1) * ei, m] * (x[c, i - 1, m] - xc) + E[i * ei, m] * (x[c, i + 1, m] - xc)
         + Nt[i, (m + ob) * nm] * (t[c, i, m + ob] - xc) + No[i, m * nm] * (t[c, i, m + ob + 1] - xc))
    if has_b:
        r += b[c, i, m]
    return r


@cuda.jit(device=True)
def _residual_c(x, t, b, elo, ehi, nlo, nhi, c, i, m, ob, has_b):
    """Coordinate ``c`` of ``b - A x`` at own-parity node ``(i, m)`` of level 0, in the CPU's order
    (``_residual_line5``): ``b``, then the couplings below and above along ``i``, then along ``j``."""
    x0 = x[c, i, m]
    r = elo * (x[c, i - 1, m] - x0)
    if has_b:
        r = b[c, i, m] + r
    return r + ehi * (x[c, i + 1, m] - x0) + nlo * (t[c, i, m + ob] - x0) + nhi * (t[c, i, m + ob + 1] - x0)


@cuda.jit(device=True)
def _scaled_step2(x, t, b, E, No, Nt, i, m, ob, ei, nm, has_b):
    """``|D^-1 (b - A x)|^2`` at own-parity node ``(i, m)`` of level 0 (the CPU's ``_max_step5`` order)."""
    elo, ehi, nlo, nhi = E[(i - 1) * ei, m], E[i * ei, m], Nt[i, (m + ob) * nm], No[i, m * nm]
    s2 = 0.0
    for c in range(x.shape[0]):
        r = _residual_c(x, t, b, elo, ehi, nlo, nhi, c, i, m, ob, has_b)
        s2 += r * r
    d = elo + ehi + nlo + nhi
    return s2 / (d * d)


# --- zebra line relaxation ------------------------------------------------------------------------------

@cuda.jit(device=True)
def _block_span(kb, L, nsep, nu):
    """Columns ``a .. z`` of block ``kb`` of a line of ``nu`` nodes: ``L`` after separator ``kb (L+1)``,
    the last block up to the last interior column."""
    a = kb * (L + 1) + 1
    return a, (nu - 2 if kb == nsep else a + L - 1)


@cuda.jit(device=True)
def _solve_block(xo, xt, bo, Co, Eo, No, Nt, NEo, NEt, NWo, NWt, g, yl, yr, q, m, kb, L, nsep, ob, ei, nm,
                 has_b, nine):
    """Thomas solve of block ``kb`` of own-parity line ``m`` (scratch column ``q``): see :func:`line_blocks`."""
    k, nu = xo.shape[0], xo.shape[1]
    a, z = _block_span(kb, L, nsep, nu)
    xc = cuda.local.array(MAX_COORDS, xo.dtype)   # x[i-1] going forward, x[i+1] going back
    sc = cuda.local.array(3, g.dtype)             # g[i-1], the inverse pivot, yl[i-1] (level precision)
    for c in range(k):
        xc[c] = xo[c, 0, m] if kb == 0 else 0     # the boundary node, or the left separator taken as 0
    sc[0] = 0
    sc[2] = 0 if kb == 0 else 1                   # yl: a unit value of the left separator
    for i in range(a, z + 1):
        elo, ehi, d0 = _coef(Co, Eo, No, Nt, i, m, ob, ei, nm, nine)
        sc[1] = 1.0 / (d0 - elo * sc[0])
        sc[0] = ehi * sc[1]
        g[i, q] = sc[0]
        for c in range(k):
            v = (_rhs(xt, bo, No, Nt, NEo, NEt, NWo, NWt, c, i, m, ob, nm, has_b, nine) + elo * xc[c]) * sc[1]
            xo[c, i, m] = v
            xc[c] = v
        if nsep > 0:
            sc[2] = elo * sc[2] * sc[1]
            yl[i, q] = sc[2]
    if kb < nsep:                                 # the separator to the right: its own equation's terms
        s = z + 1
        _, _, d0 = _coef(Co, Eo, No, Nt, s, m, ob, ei, nm, nine)
        g[s, q] = d0
        for c in range(k):
            xo[c, s, m] = _rhs(xt, bo, No, Nt, NEo, NEt, NWo, NWt, c, s, m, ob, nm, has_b, nine)
    for c in range(k):
        xc[c] = xo[c, nu - 1, m] if kb == nsep else 0
    sc[0] = 0                                     # yl[i+1]
    sc[2] = 1 if kb < nsep else 0                 # yr[i+1]: a unit value of the right separator
    for i in range(z, a - 1, -1):
        gi = g[i, q]
        for c in range(k):
            v = xo[c, i, m] + gi * xc[c]
            xo[c, i, m] = v
            xc[c] = v
        if nsep > 0:
            sc[0] = yl[i, q] + gi * sc[0]
            yl[i, q] = sc[0]
            sc[2] = gi * sc[2]
            yr[i, q] = sc[2]


@cuda.jit(device=True)
def _solve_separators(xo, Eo, g, yl, yr, q, m, L, nsep, ei):
    """The separators of line ``m`` (scratch column ``q``): see :func:`line_separators`."""
    k = xo.shape[0]
    xc = cuda.local.array(MAX_COORDS, xo.dtype)
    sc = cuda.local.array(2, g.dtype)             # the previous separator's factor, the inverse pivot
    for c in range(k):
        xc[c] = 0
    sc[0] = 0
    for kk in range(1, nsep + 1):
        s = kk * (L + 1)
        a_s = Eo[(s - 1) * ei, m]
        c_s = Eo[s * ei, m]
        lo = a_s * yl[s - 1, q]                   # coupling to the previous separator
        sc[1] = 1.0 / (g[s, q] - a_s * yr[s - 1, q] - c_s * yl[s + 1, q] - lo * sc[0])
        sc[0] = c_s * yr[s + 1, q] * sc[1]
        g[s, q] = sc[0]
        for c in range(k):
            v = (xo[c, s, m] + a_s * xo[c, s - 1, m] + c_s * xo[c, s + 1, m] + lo * xc[c]) * sc[1]
            xo[c, s, m] = v
            xc[c] = v
    for c in range(k):
        xc[c] = 0
    for kk in range(nsep, 0, -1):
        s = kk * (L + 1)
        gs = g[s, q]
        for c in range(k):
            v = xo[c, s, m] + gs * xc[c]
            xo[c, s, m] = v
            xc[c] = v


@cuda.jit(device=True)
def _spread(xo, yl, yr, q, m, i, kb, L, nsep):
    """Node ``i`` of block ``kb`` of line ``m`` plus its separators' values times its spikes."""
    for c in range(xo.shape[0]):
        v = xo[c, i, m]
        if kb > 0:
            v += yl[i, q] * xo[c, kb * (L + 1), m]
        if kb < nsep:
            v += yr[i, q] * xo[c, (kb + 1) * (L + 1), m]
        xo[c, i, m] = v


@cuda.jit(cache=True)
def line_blocks(xo, xt, bo, Co, Eo, No, Nt, NEo, NEt, NWo, NWt, g, yl, yr,
                m_lo, lines, L, nsep, ob, ei, nm, has_b, nine):
    """Thomas solve of each block of ``L`` columns of the own-parity lines ``m_lo .. m_lo+lines-1``.

    Thread ``(q, kb)``: line ``m = m_lo + q``, block ``kb`` (columns
    ``kb (L+1) + 1 ..``, up to the next separator or the last interior column).
    Writes the block's solution with zero separators into ``xo``, and with
    ``nsep > 0`` the spikes ``yl``, ``yr`` and, for the separator to its right,
    its diagonal into ``g`` and its right-hand side into ``xo``. ``Co``, ``NE*``,
    ``NW*`` are read only for a 9-point level (``nine``).
    """
    q, kb = cuda.grid(2)
    if q >= lines or kb > nsep:
        return
    _solve_block(xo, xt, bo, Co, Eo, No, Nt, NEo, NEt, NWo, NWt, g, yl, yr, q, m_lo + q, kb, L, nsep, ob, ei, nm,
                 has_b, nine)


@cuda.jit(cache=True)
def line_separators(xo, Eo, g, yl, yr, m_lo, lines, L, nsep, ei):
    """Solve each line's separators ``s = L+1, 2(L+1), ..`` from the blocks' spikes (one thread per line).

    Separator ``s`` couples to its neighbours ``s - 1`` and ``s + 1``, which
    :func:`line_blocks` expressed through the separators around them; the
    result is a tridiagonal system over the separators, solved here by the
    Thomas algorithm. ``g[s]`` holds the separator's diagonal on entry and its
    Thomas factor after; ``xo[:, s]`` its right-hand side on entry and its value after.
    """
    q = cuda.grid(1)
    if q >= lines:
        return
    _solve_separators(xo, Eo, g, yl, yr, q, m_lo + q, L, nsep, ei)


@cuda.jit(cache=True)
def line_spread(xo, yl, yr, m_lo, lines, L, nsep):
    """Add the separators' values times the spikes to every block node (thread per node ``(q, i)``)."""
    q, i = cuda.grid(2)
    nu = xo.shape[1]
    kb = i // (L + 1)
    if kb > nsep:                             # the last block may end on a multiple of L+1
        kb = nsep
    if q >= lines or i < 1 or i > nu - 2 or i == kb * (L + 1):
        return
    _spread(xo, yl, yr, q, m_lo + q, i, kb, L, nsep)


@cuda.jit(cache=True)
def line_solve(xo, xt, bo, Co, Eo, No, Nt, NEo, NEt, NWo, NWt, g, yl, yr,
               m_lo, lines, L, nsep, ob, ei, nm, has_b, nine):
    """:func:`line_blocks`, :func:`line_separators` and :func:`line_spread` in one launch, the same bits.

    A thread block holds every line block of ``blockDim.x`` whole lines: thread
    ``(x, y)`` is line ``q = blockIdx.x * blockDim.x + x`` (neighbouring threads,
    neighbouring lines: neighbouring addresses) and its block ``kb = y``
    (``blockDim.y = nsep + 1``). After a barrier one thread a line solves its
    separators, and after another each thread adds them to its own block's nodes.
    One launch a colour instead of three, and no wait for the other lines' blocks.
    """
    q = cuda.blockIdx.x * cuda.blockDim.x + cuda.threadIdx.x
    kb = cuda.threadIdx.y
    live = q < lines and kb <= nsep
    m = m_lo + q
    if live:
        _solve_block(xo, xt, bo, Co, Eo, No, Nt, NEo, NEt, NWo, NWt, g, yl, yr, q, m, kb, L, nsep, ob, ei, nm,
                     has_b, nine)
    cuda.syncthreads()                        # every block's spikes and separator terms are written
    if live and kb == 0:
        _solve_separators(xo, Eo, g, yl, yr, q, m, L, nsep, ei)
    cuda.syncthreads()                        # the separators' values are written
    if live:
        a, z = _block_span(kb, L, nsep, xo.shape[1])
        for i in range(a, z + 1):
            _spread(xo, yl, yr, q, m, i, kb, L, nsep)


# --- transfers between levels ----------------------------------------------------------------------------

@cuda.jit(cache=True)
def restrict5(xe, xo, be, Ee, Ne, No, ei, nm, has_b, bce, bco, xce, xco):
    """Coarse right-hand side from level 0's even rows (the odd rows' residual is zero after
    pre-smoothing), ``x_c = 0``; thread per coarse node ``(J, i)``, boundary included."""
    J, i = cuda.grid(2)
    nu = xe.shape[1]
    nc = bce.shape[2] + bco.shape[2]
    if J >= nc or i >= nu:
        return
    interior = 0 < i < nu - 1 and 0 < J < nc - 1
    for c in range(xe.shape[0]):
        _put(xce, xco, c, i, J, 0)
        if interior:
            _put(bce, bco, c, i, J, _res5(xe, xo, be, Ee, Ne, No, c, i, J, -1, ei, nm, has_b))
        else:
            _put(bce, bco, c, i, J, 0)


@cuda.jit(cache=True)
def restrict9(xe, xo, be, Ce, Ee, Ne, No, NEe, NEo, NWe, NWo, bce, bco, xce, xco):
    """:func:`restrict5` for a 9-point level (the CPU's ``_restrict9``)."""
    J, i = cuda.grid(2)
    nu = xe.shape[1]
    nc = bce.shape[2] + bco.shape[2]
    if J >= nc or i >= nu:
        return
    interior = 0 < i < nu - 1 and 0 < J < nc - 1
    m = J
    mb = m - 1
    for c in range(xe.shape[0]):
        _put(xce, xco, c, i, J, 0)
        if interior:
            r = (be[c, i, m] - Ce[i, m] * xe[c, i, m] + Ee[i - 1, m] * xe[c, i - 1, m] + Ee[i, m] * xe[c, i + 1, m]
                 + No[i, mb] * xo[c, i, mb] + Ne[i, m] * xo[c, i, mb + 1]
                 + NEe[i, m] * xo[c, i + 1, mb + 1] + NEo[i - 1, mb] * xo[c, i - 1, mb]
                 + NWe[i, m] * xo[c, i - 1, mb + 1] + NWo[i + 1, mb] * xo[c, i + 1, mb])
            _put(bce, bco, c, i, J, r)
        else:
            _put(bce, bco, c, i, J, 0)


@cuda.jit(cache=True)
def prolong(xe, xce, xco):
    """Add the coarse correction to the even rows (the odd rows are re-solved next)."""
    J, i = cuda.grid(2)
    nu = xe.shape[1]
    nc = xce.shape[2] + xco.shape[2]
    if 0 < J < nc - 1 and 0 < i < nu - 1:
        for c in range(xe.shape[0]):
            xe[c, i, J] += _get(xce, xco, c, i, J)


@cuda.jit(cache=True)
def restrict5_full(xe, xo, be, bo, Ee, Eo, Ne, No, ei, nm, has_b, nv, bce, bco, xce, xco):
    """``P^T (b - A x)`` from level 0 with every row's residual (the full multigrid start)."""
    J, i = cuda.grid(2)
    nu = xe.shape[1]
    nc = bce.shape[2] + bco.shape[2]
    if J >= nc or i >= nu:
        return
    interior = 0 < i < nu - 1 and 0 < J < nc - 1
    n_odd = (nv - 3) // 2 + 1          # interior odd rows m = 0 .. n_odd-1
    for c in range(xe.shape[0]):
        _put(xce, xco, c, i, J, 0)
        if interior:
            re = _res5(xe, xo, be, Ee, Ne, No, c, i, J, -1, ei, nm, has_b)
            lo = _res5(xo, xe, bo, Eo, No, Ne, c, i, J - 1, 0, ei, nm, has_b) if J - 1 < n_odd else 0.0
            hi = _res5(xo, xe, bo, Eo, No, Ne, c, i, J, 0, ei, nm, has_b) if J < n_odd else 0.0
            _put(bce, bco, c, i, J, re + 0.5 * (lo + hi))
        else:
            _put(bce, bco, c, i, J, 0)


@cuda.jit(cache=True)
def restrict_rhs(be, bo, nv, bce, bco, xce, xco):
    """``b_c = P^T b`` and ``x_c = 0`` (the full multigrid start's coarse right-hand sides)."""
    J, i = cuda.grid(2)
    nu = be.shape[1]
    nc = bce.shape[2] + bco.shape[2]
    if J >= nc or i >= nu:
        return
    interior = 0 < i < nu - 1 and 0 < J < nc - 1
    for c in range(be.shape[0]):
        _put(xce, xco, c, i, J, 0)
        if interior:
            r = be[c, i, J] + 0.5 * bo[c, i, J - 1]
            if 2 * J + 1 <= nv - 2:
                r += 0.5 * bo[c, i, J]
            _put(bce, bco, c, i, J, r)
        else:
            _put(bce, bco, c, i, J, 0)


@cuda.jit(cache=True)
def prolong_full(xe, xo, xce, xco, nv):
    """``x += P x_c`` on every interior row (odd rows take the mean of their neighbours); thread ``(m, i)``."""
    m, i = cuda.grid(2)
    nu = xe.shape[1]
    nc = xce.shape[2] + xco.shape[2]
    if not 0 < i < nu - 1:
        return
    for c in range(xe.shape[0]):
        if 0 < m < nc - 1:
            xe[c, i, m] += _get(xce, xco, c, i, m)
        if m <= (nv - 3) // 2:             # odd row 2m+1 between coarse rows m and m+1
            xo[c, i, m] += 0.5 * (_get(xce, xco, c, i, m) + _get(xce, xco, c, i, m + 1))


# --- level 0: the bound's factor, layout -----------------------------------------------------------------

@cuda.jit(cache=True)
def max_step5(xe, xo, be, bo, Ee, Eo, Ne, No, ei, nm, nv, has_b, rows, out):
    """``out[ci, m]``: the largest ``|D^-1 (b - A x)|^2`` at rows ``2m``, ``2m+1`` and columns
    ``1 + ci rows .. `` (``rows`` of them) of level 0; the caller takes the max and its root."""
    m, ci = cuda.grid(2)
    nu = xe.shape[1]
    if m >= xe.shape[2] or ci >= out.shape[0]:
        return
    end = 1 + (ci + 1) * rows
    if end > nu - 1:
        end = nu - 1
    best = 0.0
    for i in range(1 + ci * rows, end):
        if 1 <= 2 * m <= nv - 2:
            v = _scaled_step2(xe, xo, be, Ee, Ne, No, i, m, -1, ei, nm, has_b)
            if v > best:
                best = v
        if 2 * m + 1 <= nv - 2:
            v = _scaled_step2(xo, xe, bo, Eo, No, Ne, i, m, 0, ei, nm, has_b)
            if v > best:
                best = v
    out[ci, m] = best


@cuda.jit(device=True)
def _residual_at(x, t, b, E, No, Nt, i, m, ob, ei, nm, has_b, sign, out):
    """``out[c, i, m] = sign (b - A x)`` at own-parity node ``(i, m)`` of level 0 (the CPU's order)."""
    elo, ehi, nlo, nhi = E[(i - 1) * ei, m], E[i * ei, m], Nt[i, (m + ob) * nm], No[i, m * nm]
    for c in range(x.shape[0]):
        out[c, i, m] = sign * _residual_c(x, t, b, elo, ehi, nlo, nhi, c, i, m, ob, has_b)


@cuda.jit(cache=True)
def residual5(xe, xo, be, bo, Ee, Eo, Ne, No, ei, nm, nv, has_b, sign, oute, outo):
    """``out = sign (b - A x)`` on level 0's interior nodes, both parities (the ring is not written):
    conjugate gradients' residual (``sign`` 1) and ``A p`` (``sign`` -1, no ``b``)."""
    m, i = cuda.grid(2)
    if i < 1 or i >= xe.shape[1] - 1:
        return
    if m < xe.shape[2] and 1 <= 2 * m <= nv - 2:
        _residual_at(xe, xo, be, Ee, Ne, No, i, m, -1, ei, nm, has_b, sign, oute)
    if m < xo.shape[2] and 2 * m + 1 <= nv - 2:
        _residual_at(xo, xe, bo, Eo, No, Ne, i, m, 0, ei, nm, has_b, sign, outo)


@cuda.jit(cache=True)
def split_grid(x, xe, xo):
    """``(nu, nv, k)`` grid into parity planes ``xe[c, i, m] = x[i, 2m, c]``, ``xo[c, i, m] = x[i, 2m+1, c]``."""
    j, i = cuda.grid(2)
    nu, nv, k = x.shape
    if i < nu and j < nv:
        for c in range(k):
            _put(xe, xo, c, i, j, x[i, j, c])


@cuda.jit(cache=True)
def merge_grid(xe, xo, x):
    """The inverse of :func:`split_grid`."""
    j, i = cuda.grid(2)
    nu, nv, k = x.shape
    if i < nu and j < nv:
        for c in range(k):
            x[i, j, c] = _get(xe, xo, c, i, j)
