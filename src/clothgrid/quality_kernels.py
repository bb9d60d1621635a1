"""Numba kernel of :func:`clothgrid.quality.sim_figures`: cell corner angles and edge lengths in one pass.

The NumPy form builds a dozen full-size temporaries (cross products, normals, angles per corner)
and took about a second at 1024^2 nodes, more than the solve; this kernel reads each node a few
times and keeps only per-row extremes. The arithmetic is the NumPy form's, term by term.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

__all__ = ["angle_and_edge_extremes"]


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
def _corner(P, ia, ja, ib, jb, ic, jc, nx, ny, nz):
    """Angle (degrees) at node a of the cell between a->b and a->c, signed by the cell normal; 0 if folded."""
    cx, cy, cz, dot = _corner_cross(P, ia, ja, ib, jb, ic, jc)
    cr = cx * nx + cy * ny + cz * nz
    s = math.sqrt(cx * cx + cy * cy + cz * cz)
    if cr < 0:
        s = -s
    elif cr == 0:
        s = 0.0
    ang = math.degrees(math.atan2(s, dot))
    return 0.0 if ang < 0 else ang


@njit(cache=True, inline="always")
def _cross_add(P, ia, ja, ib, jb, ic, jc, out):
    cx, cy, cz, _ = _corner_cross(P, ia, ja, ib, jb, ic, jc)
    out[0] += cx
    out[1] += cy
    out[2] += cz


# node offsets of the four corners of a cell in quad order: (i, j), (i+1, j), (i+1, j+1), (i, j+1)
_DI = np.array([0, 1, 1, 0], dtype=np.int64)
_DJ = np.array([0, 0, 1, 1], dtype=np.int64)


@njit(cache=True)
def _cell_angles(P, i, j, out):
    """The four corner angles of cell (i, j) (corners 0..3 in quad order) into ``out``."""
    n = np.zeros(3)
    for k in range(4):
        kn = (k + 1) % 4
        kp = (k + 3) % 4
        _cross_add(P, i + _DI[k], j + _DJ[k], i + _DI[kn], j + _DJ[kn], i + _DI[kp], j + _DJ[kp], n)
    for k in range(4):
        kn = (k + 1) % 4
        kp = (k + 3) % 4
        out[k] = _corner(P, i + _DI[k], j + _DJ[k], i + _DI[kn], j + _DJ[kn], i + _DI[kp], j + _DJ[kp],
                         n[0], n[1], n[2])


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
        ang = np.empty(4)
        lo, hi = 180.0, 0.0
        for j in range(mv):
            if skip and (i == 0 or i == mu - 1) and (j == 0 or j == mv - 1):
                continue
            _cell_angles(P, i, j, ang)
            for k in range(4):
                lo = min(lo, ang[k])
                hi = max(hi, ang[k])
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
