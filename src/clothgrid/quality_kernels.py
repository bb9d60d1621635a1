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
def _planar(R, basis, i, j):
    """Node ``(i, j)`` of ``R`` in the plane's coordinates (``basis`` ``(2, 3)``)."""
    x = basis[0, 0] * R[i, j, 0] + basis[0, 1] * R[i, j, 1] + basis[0, 2] * R[i, j, 2]
    y = basis[1, 0] * R[i, j, 0] + basis[1, 1] * R[i, j, 1] + basis[1, 2] * R[i, j, 2]
    return x, y


@njit(cache=True, inline="always")
def _edge_xy(x0, y0, x1, y1):
    """The in-plane edge from ``(x0, y0)`` to ``(x1, y1)``: unit vector (zero if degenerate), length."""
    dx, dy = x1 - x0, y1 - y0
    length = math.sqrt(dx * dx + dy * dy)
    if length > 0:
        return dx / length, dy / length, length
    return 0.0, 0.0, length


@njit(cache=True)
def _row_edges(R, basis, i, e):
    """The edges of the cells of row ``i`` into ``e`` (rows of ``nv`` values): 0-2 the u-edges from
    row ``i`` to ``i + 1`` (unit x, y, length), 3-5 the v-edges of row ``i``, 6-8 those of row ``i + 1``:
    each edge once (:func:`_planar`, then :func:`_edge_xy`), not once for each cell and measure."""
    nv = R.shape[1]
    x0, y0 = _planar(R, basis, i, 0)
    x1, y1 = _planar(R, basis, i + 1, 0)
    for j in range(nv):
        e[0, j], e[1, j], e[2, j] = _edge_xy(x0, y0, x1, y1)
        if j + 1 < nv:
            xa, ya = _planar(R, basis, i, j + 1)
            xb, yb = _planar(R, basis, i + 1, j + 1)
            e[3, j], e[4, j], e[5, j] = _edge_xy(x0, y0, xa, ya)
            e[6, j], e[7, j], e[8, j] = _edge_xy(x1, y1, xb, yb)
            x0, y0, x1, y1 = xa, ya, xb, yb


@njit(cache=True, parallel=True)
def planar_measures(R, basis, straight):
    """:func:`clothgrid.quality.quality`'s measures of a planar grid in one pass.

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
    folded = np.zeros((mu, mv), dtype=np.bool_)
    row_sj = np.full(mu, np.inf)
    row_aspect = np.zeros(mu)
    row_cos = np.zeros(mu)
    row_deg = np.zeros(mu, dtype=np.bool_)     # a degenerate cell in the row: deviation 90
    row_u = np.zeros((nu, 4))       # max, min of the u-edges at each row (the last has none); max, min of the v-edges
    scratch = np.empty((numba.config.NUMBA_NUM_THREADS, 9, nv + 8))   # 8 spare: threads' rows apart
    for r in prange(mu):
        i = np.int64(r)
        e = scratch[numba.get_thread_id()]
        _row_edges(R, basis, i, e)
        sj_lo, asp_hi, cos_hi, deg = np.inf, 0.0, 0.0, False
        for j in range(mv):
            bx, by, lb = e[0, j], e[1, j], e[2, j]                  # bottom (u-edge at j)
            tx, ty, lt = e[0, j + 1], e[1, j + 1], e[2, j + 1]      # top (u-edge at j + 1)
            lx, ly, ll = e[3, j], e[4, j], e[5, j]                  # left (v-edge at i)
            rx, ry, lr = e[6, j], e[7, j], e[8, j]                  # right (v-edge at i + 1)
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
                sj_lo = min(sj_lo, sj)
                cos_hi = max(cos_hi, abs(ax * cx + ay * cy))
            shortest = min(min(lb, lt), min(ll, lr))
            longest = max(max(lb, lt), max(ll, lr))
            if not shortest > 0:
                bad = True
                deg = True
                asp_hi = np.inf
            else:
                asp_hi = max(asp_hi, longest / shortest)
            folded[i, j] = bad
        row_sj[i], row_aspect[i], row_cos[i], row_deg[i] = sj_lo, asp_hi, cos_hi, deg
        # the edge lengths' extremes: row i's u-edges and v-edges (and the last row's v-edges)
        uh, ul, vh, vl = 0.0, np.inf, 0.0, np.inf
        for j in range(nv):
            length = e[2, j]
            uh, ul = max(uh, length), min(ul, length)
            if j + 1 < nv:
                length = e[5, j]
                vh, vl = max(vh, length), min(vl, length)
        row_u[i, 0], row_u[i, 1], row_u[i, 2], row_u[i, 3] = uh, ul, vh, vl
        if i == mu - 1:
            vh, vl = 0.0, np.inf
            for j in range(nv - 1):
                length = e[8, j]
                vh, vl = max(vh, length), min(vl, length)
            row_u[nu - 1, 2], row_u[nu - 1, 3] = vh, vl
    deviation = 90.0 if row_deg.any() else math.degrees(math.asin(min(row_cos.max(), 1.0)))
    return (folded, row_sj.min(), row_aspect.max(), deviation,
            row_u[:mu, 0].max(), row_u[:mu, 1].min(), row_u[:, 2].max(), row_u[:, 3].min())
