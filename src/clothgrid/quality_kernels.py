"""Numba kernels of :mod:`clothgrid.quality` for large grids: :func:`~clothgrid.quality.sim_figures`'
cell corner angles and edge lengths, and :func:`~clothgrid.quality.quality`'s measures of a planar
grid, each in one pass.

The NumPy form builds a dozen full-size temporaries (cross products, normals, angles per corner)
and took about a second at 1024^2 nodes, more than the solve; this kernel reads each node a few
times and keeps only per-row extremes. The arithmetic is the NumPy form's, term by term.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from .jit_variants import fork_safe

__all__ = ["angle_and_edge_extremes", "planar_blocks", "new_blocks", "block_figures"]


@njit(cache=True, inline="always")
def _corner_cross(P, ia, ja, ib, jb, ic, jc):
    """Edges a = b - a_node, b = c - a_node at node (ia, ja) of a cell: their cross product and dot."""
    ax = P[ib, jb, 0] - P[ia, ja, 0]
    ay = P[ib, jb, 1] - P[ia, ja, 1]
    az = P[ib, jb, 2] - P[ia, ja, 2]
    bx = P[ic, jc, 0] - P[ia, ja, 0]
    by = P[ic, jc, 1] - P[ia, ja, 1]
    bz = P[ic, jc, 2] - P[ia, ja, 2]
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx, ax * bx + ay * by + az * bz


@njit(cache=True, inline="always")
def _angle(s, dot):
    """The corner angle (degrees) from a corner's sine and cosine terms (:func:`_cell_terms`); 0 if folded."""
    ang = math.degrees(math.atan2(s, dot))
    return 0.0 if ang < 0 else ang


# node offsets of the four corners of a cell in quad order: (i, j), (i+1, j), (i+1, j+1), (i, j+1)
_DI = np.array([0, 1, 1, 0], dtype=np.int64)
_DJ = np.array([0, 0, 1, 1], dtype=np.int64)


@njit(cache=True)
def _cell_terms(P, i, j, sines, cosines, cross):
    """The four corners' sine and cosine terms of cell (i, j) (corners 0..3 in quad order).

    At corner a, between a->b and a->c: the sine term is the cross product's length, signed by
    the cell normal (the sum of the four corners' cross products), and the cosine term the dot
    product. Each corner's cross product is computed once (``cross``: ``(4, 3)`` scratch).
    """
    nx = ny = nz = 0.0
    for k in range(4):
        kn = (k + 1) % 4
        kp = (k + 3) % 4
        cx, cy, cz, dot = _corner_cross(P, i + _DI[k], j + _DJ[k], i + _DI[kn], j + _DJ[kn],
                                        i + _DI[kp], j + _DJ[kp])
        cross[k, 0], cross[k, 1], cross[k, 2] = cx, cy, cz
        cosines[k] = dot
        nx += cx
        ny += cy
        nz += cz
    for k in range(4):
        cx, cy, cz = cross[k, 0], cross[k, 1], cross[k, 2]
        cr = cx * nx + cy * ny + cz * nz
        s = math.sqrt(cx * cx + cy * cy + cz * cz)
        if cr < 0:
            s = -s
        elif cr == 0:
            s = 0.0
        sines[k] = s


@njit(cache=True)
def _cell_angles(P, i, j, out):
    """The four corner angles of cell (i, j) (corners 0..3 in quad order) into ``out``."""
    sines, cosines, cross = np.empty(4), np.empty(4), np.empty((4, 3))
    _cell_terms(P, i, j, sines, cosines, cross)
    for k in range(4):
        out[k] = _angle(sines[k], cosines[k])


#: A corner whose cosine is this far inside the (cosines of the) row's extreme angles so far
#: cannot be a new extreme, and its arctangent is not taken. The cosine's rounding (a few 1e-16)
#: is far below it, and a cosine difference d means an angle difference of at least d radians,
#: so the extremes are those of every corner's angle, bit for bit.
_COS_MARGIN = 1e-9


@fork_safe
@njit(cache=True, parallel=True)
def angle_and_edge_extremes(P):
    """Smallest and largest corner angle over the cells (the four grid-corner cells aside when
    there are more than four cells), each grid corner's angle, and the shortest and longest edge.

    Parameters
    ----------
    P : numpy.ndarray
        ``(nu, nv, 3)`` float64 nodes, C-contiguous.

    Returns
    -------
    amin, amax : float
    corners : numpy.ndarray
        ``(4,)`` angles at nodes ``[0, 0]``, ``[-1, 0]``, ``[-1, -1]``, ``[0, -1]``.
    emin, emax : float
    """
    nu, nv = P.shape[0], P.shape[1]
    mu, mv = nu - 1, nv - 1
    skip = mu * mv > 4
    row_amin = np.full(mu, 180.0)
    row_amax = np.zeros(mu)
    for r in prange(mu):
        i = np.int64(r)
        sines, cosines, cross = np.empty(4), np.empty(4), np.empty((4, 3))
        lo, hi = 180.0, 0.0
        cos_lo, cos_hi = -1.0, 1.0
        for j in range(mv):
            if skip and (i == 0 or i == mu - 1) and (j == 0 or j == mv - 1):
                continue
            _cell_terms(P, i, j, sines, cosines, cross)
            for k in range(4):
                s, dot = sines[k], cosines[k]
                if s > 0:
                    h = math.sqrt(s * s + dot * dot)
                    if 1e-150 < h < 1e150:        # s * s and dot * dot neither underflow nor overflow
                        c = dot / h
                        if c <= cos_lo - _COS_MARGIN and c >= cos_hi + _COS_MARGIN:
                            continue
                ang = _angle(s, dot)
                if ang < lo:
                    lo = ang
                    cos_lo = math.cos(math.radians(lo))
                if ang > hi:
                    hi = ang
                    cos_hi = math.cos(math.radians(hi))
        row_amin[i] = lo
        row_amax[i] = hi
    corners = np.empty(4)
    ang = np.empty(4)
    _cell_angles(P, 0, 0, ang)
    corners[0] = ang[0]
    _cell_angles(P, mu - 1, 0, ang)
    corners[1] = ang[1]
    _cell_angles(P, mu - 1, mv - 1, ang)
    corners[2] = ang[2]
    _cell_angles(P, 0, mv - 1, ang)
    corners[3] = ang[3]
    row_emin = np.full(nu, np.inf)
    row_emax = np.zeros(nu)
    for r in prange(nu):
        i = np.int64(r)
        lo, hi = np.inf, 0.0
        for j in range(nv):
            if i + 1 < nu:
                dx = P[i + 1, j, 0] - P[i, j, 0]
                dy = P[i + 1, j, 1] - P[i, j, 1]
                dz = P[i + 1, j, 2] - P[i, j, 2]
                e = math.sqrt(dx * dx + dy * dy + dz * dz)
                lo = min(lo, e)
                hi = max(hi, e)
            if j + 1 < nv:
                dx = P[i, j + 1, 0] - P[i, j, 0]
                dy = P[i, j + 1, 1] - P[i, j, 1]
                dz = P[i, j + 1, 2] - P[i, j, 2]
                e = math.sqrt(dx * dx + dy * dy + dz * dz)
                lo = min(lo, e)
                hi = max(hi, e)
        row_emin[i] = lo
        row_emax[i] = hi
    return row_amin.min(), row_amax.max(), corners, row_emin.min(), row_emax.max()


@njit(cache=True, inline="always")
def _unit_edges(x0, y0, x1, y1, n, ex, ey, el):
    """Edges ``k < n`` from ``(x0[k], y0[k])`` to ``(x1[k], y1[k])`` into ``ex, ey`` (unit vector, zero
    if degenerate) and ``el`` (length): no dependence from one edge to the next, so the compiler
    takes several at once in vector registers (square roots and divisions, a quarter of the time)."""
    for k in range(n):
        dx, dy = x1[k] - x0[k], y1[k] - y0[k]
        length = math.sqrt(dx * dx + dy * dy)
        ok = length > 0
        ex[k] = dx / length if ok else 0.0
        ey[k] = dy / length if ok else 0.0
        el[k] = length


@njit(cache=True, inline="always")
def _grid_corner_cell(i, j, mu, mv, bx, by, tx, ty, lx, ly, rx, ry, straight):
    """Whether a grid-corner cell is folded: its own grid corner's sine may be down to ``-straight``
    (the outline's angle), its other corners' must be positive (:func:`planar_measures`)."""
    bad = False
    for k in range(4):      # corners b x l, b x r, t x r, t x l
        ax, ay = (bx, by) if k < 2 else (tx, ty)
        cx, cy = (lx, ly) if k == 0 or k == 3 else (rx, ry)
        sj = ax * cy - ay * cx
        grid_corner = ((k == 0 and i == 0 and j == 0) or (k == 1 and i == mu - 1 and j == 0)
                       or (k == 2 and i == mu - 1 and j == mv - 1) or (k == 3 and i == 0 and j == mv - 1))
        if grid_corner:
            if not sj > -straight:
                bad = True
        elif not sj > 0:
            bad = True
    return bad


#: rows of :func:`planar_blocks`' scratch a thread: the two node rows' x, y (0-3), the u-edges'
#: unit x, y and lengths (4-6), the lower and upper v-edges' (7-9, 10-12), cells' sine, aspect,
#: cosine, shortest edge (13-16)
_SCRATCH_ROWS = 17
#: Cells of a row in a block of :func:`planar_blocks`' figures (a grid whose nodes mostly stay put
#: is measured again block by block: :class:`clothgrid.quality.CellRecord`).
BLOCK = 128
#: :func:`planar_blocks`' figures of a block: smallest sine, largest aspect, largest |cosine|, a
#: degenerate cell (1.0), longest and shortest u-edge, longest and shortest v-edge
_FIGURES = 8


def new_blocks(nu, nv):
    """``(nu-1, blocks, 8)`` figures for :func:`planar_blocks`."""
    mu, mv = nu - 1, nv - 1
    return np.empty((mu, -(-mv // BLOCK), _FIGURES))


@njit(cache=True)
def block_figures(blocks):
    """:func:`clothgrid.quality.quality`'s figures from :func:`planar_blocks`' blocks: smallest sine, largest
    aspect, largest angle deviation in degrees, longest and shortest u-edge, longest and shortest
    v-edge (extremes: the same whatever the blocks)."""
    sj, asp, cos, deg = np.inf, 0.0, 0.0, False
    uh, ul, vh, vl = 0.0, np.inf, 0.0, np.inf
    for i in range(blocks.shape[0]):
        for b in range(blocks.shape[1]):
            f = blocks[i, b]
            sj, asp, cos, deg = min(sj, f[0]), max(asp, f[1]), max(cos, f[2]), deg or f[3] > 0.0
            uh, ul, vh, vl = max(uh, f[4]), min(ul, f[5]), max(vh, f[6]), min(vl, f[7])
    deviation = 90.0 if deg else math.degrees(math.asin(min(cos, 1.0)))
    return sj, asp, deviation, uh, ul, vh, vl


@fork_safe
@njit(cache=True, parallel=True, error_model="numpy")
def planar_blocks(R, basis, straight, folded, blocks, todo):
    """:func:`clothgrid.quality.quality`'s measures of a planar grid ``R`` (``(nu, nv, 3)`` float64,
    ``basis`` the ``(2, 3)`` orthonormal axes of its plane, ``straight``
    :data:`~clothgrid.quality.STRAIGHT_CORNER_SINE`) on the blocks of cells marked in ``todo`` (``(nu-1, blocks)``
    bool; a block is :data:`BLOCK` cells of a row): their cells' folding into ``folded`` and their
    figures into ``blocks`` (:func:`new_blocks`). A cell is folded where a corner's sine is not
    positive (a grid corner's below ``-straight``) or an edge has zero length.

    A run of marked blocks of a row at a time: its nodes of the two node rows in the plane's
    coordinates, its edges' unit vectors and lengths (each edge once), then each cell's figures
    into rows of scratch, each loop free of dependences from one cell to the next (vector
    registers; the extremes taken after). A cell's figures do not depend on the run it is measured
    in. A block holds the u-edges at its cells' first nodes (the last block also the row's last)
    and the v-edges of its cells' lower node row (the last row of cells also the upper row's)."""
    nu, nv = R.shape[0], R.shape[1]
    mu, mv = nu - 1, nv - 1
    nb = blocks.shape[1]
    b00, b01, b02, b10, b11, b12 = basis[0, 0], basis[0, 1], basis[0, 2], basis[1, 0], basis[1, 1], basis[1, 2]
    scratch = np.empty((numba.config.NUMBA_NUM_THREADS, _SCRATCH_ROWS, nv + 8))   # 8 spare: threads' rows apart
    for r in prange(mu):
        i = np.int64(r)
        e = scratch[numba.get_thread_id()]
        xa, ya, xb, yb = e[0], e[1], e[2], e[3]
        ux, uy, lu, vx, vy, lv, wx, wy, lw = e[4], e[5], e[6], e[7], e[8], e[9], e[10], e[11], e[12]
        csj, casp, ccos, cshort = e[13], e[14], e[15], e[16]
        fo = folded[i]
        b0 = 0
        while b0 < nb:
            if not todo[i, b0]:
                b0 += 1
                continue
            b1 = b0 + 1
            while b1 < nb and todo[i, b1]:
                b1 += 1
            c0, c1 = b0 * BLOCK, min(b1 * BLOCK, mv)        # cells c0 .. c1-1, nodes c0 .. c1
            n = c1 - c0
            for k in range(n + 1):     # the nodes in the plane: the same products and sums as ever
                j = c0 + k
                xa[k] = b00 * R[i, j, 0] + b01 * R[i, j, 1] + b02 * R[i, j, 2]
                ya[k] = b10 * R[i, j, 0] + b11 * R[i, j, 1] + b12 * R[i, j, 2]
                xb[k] = b00 * R[i + 1, j, 0] + b01 * R[i + 1, j, 1] + b02 * R[i + 1, j, 2]
                yb[k] = b10 * R[i + 1, j, 0] + b11 * R[i + 1, j, 1] + b12 * R[i + 1, j, 2]
            _unit_edges(xa, ya, xb, yb, n + 1, ux, uy, lu)                    # u-edges, row i to i + 1
            _unit_edges(xa, ya, xa[1:], ya[1:], n, vx, vy, lv)                # v-edges of row i
            _unit_edges(xb, yb, xb[1:], yb[1:], n, wx, wy, lw)                # v-edges of row i + 1
            for k in range(n):
                bx, by, lb = ux[k], uy[k], lu[k]                  # bottom (u-edge at j)
                tx, ty, lt = ux[k + 1], uy[k + 1], lu[k + 1]      # top (u-edge at j + 1)
                lx, ly, ll = vx[k], vy[k], lv[k]                  # left (v-edge at i)
                rx, ry, lr = wx[k], wy[k], lw[k]                  # right (v-edge at i + 1)
                s0, s1 = bx * ly - by * lx, bx * ry - by * rx     # corners b x l, b x r, t x r, t x l
                s2, s3 = tx * ry - ty * rx, tx * ly - ty * lx
                shortest = min(min(lb, lt), min(ll, lr))
                longest = max(max(lb, lt), max(ll, lr))
                csj[k] = min(min(s0, s1), min(s2, s3))
                ccos[k] = max(max(abs(bx * lx + by * ly), abs(bx * rx + by * ry)),
                              max(abs(tx * rx + ty * ry), abs(tx * lx + ty * ly)))
                casp[k] = longest / shortest if shortest > 0 else np.inf
                cshort[k] = shortest
                fo[c0 + k] = not (s0 > 0 and s1 > 0 and s2 > 0 and s3 > 0 and shortest > 0)
            if i == 0 or i == mu - 1:           # the grid-corner cells (only their folding differs)
                for j in (0, mv - 1):
                    if c0 <= j < c1:
                        k = j - c0
                        fo[j] = _grid_corner_cell(i, j, mu, mv, ux[k], uy[k], ux[k + 1], uy[k + 1], vx[k],
                                                  vy[k], wx[k], wy[k], straight) or not cshort[k] > 0
            for b in range(b0, b1):
                k0, k1 = b * BLOCK - c0, min((b + 1) * BLOCK, mv) - c0
                sj_lo, asp_hi, cos_hi, deg = np.inf, 0.0, 0.0, False
                for k in range(k0, k1):
                    sj_lo = min(sj_lo, csj[k])
                    asp_hi = max(asp_hi, casp[k])
                    cos_hi = max(cos_hi, ccos[k])
                    deg = deg or not cshort[k] > 0
                # the edge lengths' extremes: the block's u-edges and v-edges (and the last row's v-edges)
                uh, ul, vh, vl = 0.0, np.inf, 0.0, np.inf
                for k in range(k0, k1 + 1 if b == nb - 1 else k1):
                    uh, ul = max(uh, lu[k]), min(ul, lu[k])
                for k in range(k0, k1):
                    vh, vl = max(vh, lv[k]), min(vl, lv[k])
                if i == mu - 1:
                    for k in range(k0, k1):
                        vh, vl = max(vh, lw[k]), min(vl, lw[k])
                f = blocks[i, b]
                f[0], f[1], f[2], f[3] = sj_lo, asp_hi, cos_hi, 1.0 if deg else 0.0
                f[4], f[5], f[6], f[7] = uh, ul, vh, vl
            b0 = b1
