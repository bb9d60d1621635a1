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

__all__ = ["angle_and_edge_extremes", "planar_measures"]


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


#: rows of :func:`planar_measures`' scratch a thread: the two node rows' x, y (0-3), the u-edges'
#: unit x, y and lengths (4-6), the lower and upper v-edges' (7-9, 10-12), cells' sine, aspect,
#: cosine, shortest edge (13-16)
_SCRATCH_ROWS = 17


@njit(cache=True, parallel=True, error_model="numpy")
def planar_measures(R, basis, straight):
    """:func:`clothgrid.quality.quality`'s measures of a planar grid in one pass.

    A row of cells at a time: its two node rows in the plane's coordinates, its edges' unit vectors
    and lengths (each edge once), then each cell's figures into rows of scratch, each loop free of
    dependences from one cell to the next (vector registers; the extremes taken after).

    Parameters
    ----------
    R : numpy.ndarray
        ``(nu, nv, 3)`` float64 nodes.
    basis : numpy.ndarray
        ``(2, 3)`` orthonormal axes of the piece's plane (``e1 x e2`` its oriented normal).
    straight : float
        :data:`clothgrid.quality.STRAIGHT_CORNER_SINE`.

    Returns
    -------
    folded : numpy.ndarray
        ``(nu-1, nv-1)`` bool: a corner's sine not positive (a grid corner's below ``-straight``)
        or a zero-length edge.
    min_sj, max_aspect, max_deviation_deg, max_u, min_u, max_v, min_v : float
    """
    nu, nv = R.shape[0], R.shape[1]
    mu, mv = nu - 1, nv - 1
    b00, b01, b02, b10, b11, b12 = basis[0, 0], basis[0, 1], basis[0, 2], basis[1, 0], basis[1, 1], basis[1, 2]
    folded = np.zeros((mu, mv), dtype=np.bool_)
    row_sj = np.full(mu, np.inf)
    row_aspect = np.zeros(mu)
    row_cos = np.zeros(mu)
    row_deg = np.zeros(mu, dtype=np.bool_)     # a degenerate cell in the row: deviation 90
    row_u = np.zeros((nu, 4))       # max, min of the u-edges at each row (the last has none); max, min of the v-edges
    scratch = np.empty((numba.config.NUMBA_NUM_THREADS, _SCRATCH_ROWS, nv + 8))   # 8 spare: threads' rows apart
    for r in prange(mu):
        i = np.int64(r)
        e = scratch[numba.get_thread_id()]
        xa, ya, xb, yb = e[0], e[1], e[2], e[3]
        ux, uy, lu, vx, vy, lv, wx, wy, lw = e[4], e[5], e[6], e[7], e[8], e[9], e[10], e[11], e[12]
        csj, casp, ccos, cshort = e[13], e[14], e[15], e[16]
        for j in range(nv):     # the nodes in the plane: the same products and sums as ever
            xa[j] = b00 * R[i, j, 0] + b01 * R[i, j, 1] + b02 * R[i, j, 2]
            ya[j] = b10 * R[i, j, 0] + b11 * R[i, j, 1] + b12 * R[i, j, 2]
            xb[j] = b00 * R[i + 1, j, 0] + b01 * R[i + 1, j, 1] + b02 * R[i + 1, j, 2]
            yb[j] = b10 * R[i + 1, j, 0] + b11 * R[i + 1, j, 1] + b12 * R[i + 1, j, 2]
        _unit_edges(xa, ya, xb, yb, nv, ux, uy, lu)                        # u-edges, row i to i + 1
        _unit_edges(xa, ya, xa[1:], ya[1:], mv, vx, vy, lv)                # v-edges of row i
        _unit_edges(xb, yb, xb[1:], yb[1:], mv, wx, wy, lw)                # v-edges of row i + 1
        fo = folded[i]
        for j in range(mv):
            bx, by, lb = ux[j], uy[j], lu[j]                  # bottom (u-edge at j)
            tx, ty, lt = ux[j + 1], uy[j + 1], lu[j + 1]      # top (u-edge at j + 1)
            lx, ly, ll = vx[j], vy[j], lv[j]                  # left (v-edge at i)
            rx, ry, lr = wx[j], wy[j], lw[j]                  # right (v-edge at i + 1)
            s0, s1 = bx * ly - by * lx, bx * ry - by * rx     # corners b x l, b x r, t x r, t x l
            s2, s3 = tx * ry - ty * rx, tx * ly - ty * lx
            shortest = min(min(lb, lt), min(ll, lr))
            longest = max(max(lb, lt), max(ll, lr))
            csj[j] = min(min(s0, s1), min(s2, s3))
            ccos[j] = max(max(abs(bx * lx + by * ly), abs(bx * rx + by * ry)),
                          max(abs(tx * rx + ty * ry), abs(tx * lx + ty * ly)))
            casp[j] = longest / shortest if shortest > 0 else np.inf
            cshort[j] = shortest
            fo[j] = not (s0 > 0 and s1 > 0 and s2 > 0 and s3 > 0 and shortest > 0)
        if i == 0 or i == mu - 1:           # the grid-corner cells (only their folding differs)
            for j in (0, mv - 1):
                fo[j] = _grid_corner_cell(i, j, mu, mv, ux[j], uy[j], ux[j + 1], uy[j + 1], vx[j], vy[j],
                                          wx[j], wy[j], straight) or not cshort[j] > 0
        sj_lo, asp_hi, cos_hi, deg = np.inf, 0.0, 0.0, False
        for j in range(mv):
            sj_lo = min(sj_lo, csj[j])
            asp_hi = max(asp_hi, casp[j])
            cos_hi = max(cos_hi, ccos[j])
            deg = deg or not cshort[j] > 0
        row_sj[i], row_aspect[i], row_cos[i], row_deg[i] = sj_lo, asp_hi, cos_hi, deg
        # the edge lengths' extremes: row i's u-edges and v-edges (and the last row's v-edges)
        uh, ul, vh, vl = 0.0, np.inf, 0.0, np.inf
        for j in range(nv):
            uh, ul = max(uh, lu[j]), min(ul, lu[j])
        for j in range(mv):
            vh, vl = max(vh, lv[j]), min(vl, lv[j])
        row_u[i, 0], row_u[i, 1], row_u[i, 2], row_u[i, 3] = uh, ul, vh, vl
        if i == mu - 1:
            vh, vl = 0.0, np.inf
            for j in range(mv):
                vh, vl = max(vh, lw[j]), min(vl, lw[j])
            row_u[nu - 1, 2], row_u[nu - 1, 3] = vh, vl
    deviation = 90.0 if row_deg.any() else math.degrees(math.asin(min(row_cos.max(), 1.0)))
    return (folded, row_sj.min(), row_aspect.max(), deviation,
            row_u[:mu, 0].max(), row_u[:mu, 1].min(), row_u[:, 2].max(), row_u[:, 3].min())
