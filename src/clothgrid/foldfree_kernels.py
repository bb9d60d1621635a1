"""Numba kernels of the fold-free step: node-by-node minimisation of the corner energy.

The energy of :mod:`clothgrid.foldfree` (the regularised Winslow energy of the
four corner triangles of every cell),

    f = (|a|^2 + |b|^2) / (J + sqrt(J^2 + 4 delta^2)),   J = a x b,

is minimised one interior node at a time (nonlinear Gauss-Seidel, as Escobar
et al. do it): the node moves by a Newton step on the energy of its four cells
(analytic 2 x 2 gradient and Hessian, a gradient step where the Hessian is
not positive definite), shortened until the energy goes down. ``delta`` is
given relative to the local cell area (the mean squared length of the node's
four edges), so that small cells of a graded grid are untangled like large ones. ``J`` is linear in
the node's position and ``|a|^2 + |b|^2`` quadratic, so both derivatives are exact.

Only the nodes listed are moved (an *active set*: where cells are folded or
poorly shaped, and a margin around them), so the cost follows the size of the
bad region, not of the grid. Coordinates are planar ``(nu, nv, 2)``, oriented
counter-clockwise, scaled so that the mean cell area is about 1.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from .grid_kernels import row_counts_into
from .jit_variants import by_size, fork_safe

__all__ = ["sweep_nodes", "sweep_nodes_coloured", "sweep_nodes_parts", "node_components", "corner_min", "CornerCells",
           "cell_min_sine", "cells_below", "smallest_cell_sine", "axes_to_plane", "axes_from_plane", "dilate"]

# Node offsets of the four corners of cell (ci, cj) in quad order.
_DI = np.array([0, 1, 1, 0], dtype=np.int64)
_DJ = np.array([0, 0, 1, 1], dtype=np.int64)


@njit(cache=True, inline="always")
def _tri(x0, y0, x1, y1, x3, y3, d4, kind, want):
    """One corner triangle (apex (x0, y0), edges a, b to (x1, y1), (x3, y3)): its energy and, if
    ``want``, gradient and Hessian terms in the moving node (``kind``: 0 the apex, 1 the end of a,
    2 the end of b). Energy inf if inverted beyond the regularisation (D <= 0)."""
    ax = x1 - x0
    ay = y1 - y0
    bx = x3 - x0
    by = y3 - y0
    J = ax * by - ay * bx
    N = ax * ax + ay * ay + bx * bx + by * by
    s = np.sqrt(J * J + d4)
    D = J + s
    if D <= 0.0:
        return np.inf, 0.0, 0.0, 0.0, 0.0, 0.0
    f = N / D
    if not want:
        return f, 0.0, 0.0, 0.0, 0.0, 0.0
    if kind == 0:
        nx = -2.0 * (ax + bx)
        ny = -2.0 * (ay + by)
        h2 = 4.0
        jx = ay - by
        jy = bx - ax
    elif kind == 1:
        nx = 2.0 * ax
        ny = 2.0 * ay
        h2 = 2.0
        jx = by
        jy = -bx
    else:
        nx = 2.0 * bx
        ny = 2.0 * by
        h2 = 2.0
        jx = -ay
        jy = ax
    Dp = 1.0 + J / s
    Dpp = d4 / (s * s * s)
    gx = nx / D - N * Dp / (D * D) * jx
    gy = ny / D - N * Dp / (D * D) * jy
    cjj = 2.0 * N * Dp * Dp / (D * D * D) - N * Dpp / (D * D)
    cnj = Dp / (D * D)
    hxx = h2 / D - cnj * 2.0 * nx * jx + cjj * jx * jx
    hyy = h2 / D - cnj * 2.0 * ny * jy + cjj * jy * jy
    hxy = -cnj * (nx * jy + jx * ny) + cjj * jx * jy
    return f, gx, gy, hxx, hxy, hyy


#: The node energy's scratch (:func:`new_scratch`): 13 rows of 16 lanes, one lane a corner
#: triangle (lanes 0-11: triangle ``t`` of cell ``c`` in lane ``4 t + c``; lanes 12-15 a fixed unit
#: triangle, never read). Sixteen lanes, a compile-time count, are what LLVM's loop vectoriser
#: takes (it leaves loops of fewer than 16 iterations scalar): two 8-wide passes.
LANES = 16
_X0, _Y0, _X1, _Y1, _X3, _Y3, _F, _GX, _GY, _HXX, _HXY, _HYY, _D = (r * LANES for r in range(13))
SCRATCH = 13 * LANES


#: Each scratch row is followed by this many unused values (128 bytes): rows used by different
#: threads never share a cache line, whatever the array's alignment (sharing one made the parallel
#: sweeps about 1.8x slower in some processes: 0.28-0.29 against 0.15 s at 1024^2).
PAD = 16


@njit(cache=True)
def new_scratch(count):
    """``(count, SCRATCH + PAD)`` node-energy scratch, the unused lanes holding a unit triangle."""
    w = np.zeros((count, SCRATCH + PAD))
    for k in range(count):
        for K in range(12, LANES):
            w[k, _X1 + K] = 1.0
            w[k, _Y3 + K] = 1.0
    return w


@njit(cache=True, error_model="numpy", inline="always")
def _triangles(w, d4, want):
    """Every lane's corner triangle (:func:`_tri`'s arithmetic, lane by lane): energy into ``_F``,
    ``D`` into ``_D`` and, if ``want``, gradient and Hessian terms (the moving node's role by lane:
    lanes 0-3 end edge a, 4-7 are the apex, 8-11 end edge b). No branches: an inverted triangle's
    lane divides by zero or less (numpy's error model: no exception) and is found by its ``D``."""
    for K in range(LANES):
        ax = w[_X1 + K] - w[_X0 + K]
        ay = w[_Y1 + K] - w[_Y0 + K]
        bx = w[_X3 + K] - w[_X0 + K]
        by = w[_Y3 + K] - w[_Y0 + K]
        J = ax * by - ay * bx
        N = ax * ax + ay * ay + bx * bx + by * by
        s = np.sqrt(J * J + d4)
        D = J + s
        w[_D + K] = D
        w[_F + K] = N / D
        if want:                # loop-invariant: the compiler makes two loops, both vectorised
            apex = K >= 4 and K < 8
            a_end = K < 4
            nx = -2.0 * (ax + bx) if apex else (2.0 * ax if a_end else 2.0 * bx)
            ny = -2.0 * (ay + by) if apex else (2.0 * ay if a_end else 2.0 * by)
            h2 = 4.0 if apex else 2.0
            jx = (ay - by) if apex else (by if a_end else -ay)
            jy = (bx - ax) if apex else (-bx if a_end else ax)
            Dp = 1.0 + J / s
            Dpp = d4 / (s * s * s)
            w[_GX + K] = nx / D - N * Dp / (D * D) * jx
            w[_GY + K] = ny / D - N * Dp / (D * D) * jy
            cjj = 2.0 * N * Dp * Dp / (D * D * D) - N * Dpp / (D * D)
            cnj = Dp / (D * D)
            w[_HXX + K] = h2 / D - cnj * 2.0 * nx * jx + cjj * jx * jx
            w[_HYY + K] = h2 / D - cnj * 2.0 * ny * jy + cjj * jy * jy
            w[_HXY + K] = -cnj * (nx * jy + jx * ny) + cjj * jx * jy


@njit(cache=True, error_model="numpy", inline="always")
def _node_energy(X, i, j, px, py, d4, want, w):
    """Energy of the 4 cells around node (i, j) with the node at (px, py); gradient, Hessian if want.

    Cells (i-1, j-1), (i, j-1), (i-1, j), (i, j) in turn; in each (corners p, n, o, q counter-
    clockwise from the node p) the three corner triangles that hold p: apex q (p ends a), apex p,
    apex n (p ends b). The sums run in that order.

    The twelve triangles are computed side by side in the lanes of ``w`` (:func:`new_scratch`,
    :func:`_triangles`: vector instructions for the square roots and the up to nine divisions a
    triangle) and summed in the order above: the same bits as :func:`_tri`, one at a time. Energy
    inf if any triangle is inverted beyond the regularisation (D <= 0).
    """
    ex, ey = X[i + 1, j, 0], X[i + 1, j, 1]
    wx, wy = X[i - 1, j, 0], X[i - 1, j, 1]
    nx, ny = X[i, j + 1, 0], X[i, j + 1, 1]
    sx, sy = X[i, j - 1, 0], X[i, j - 1, 1]
    for c in range(4):
        if c == 0:
            n_x, n_y, q_x, q_y = wx, wy, sx, sy
            o_x, o_y = X[i - 1, j - 1, 0], X[i - 1, j - 1, 1]
        elif c == 1:
            n_x, n_y, q_x, q_y = sx, sy, ex, ey
            o_x, o_y = X[i + 1, j - 1, 0], X[i + 1, j - 1, 1]
        elif c == 2:
            n_x, n_y, q_x, q_y = nx, ny, wx, wy
            o_x, o_y = X[i - 1, j + 1, 0], X[i - 1, j + 1, 1]
        else:
            n_x, n_y, q_x, q_y = ex, ey, nx, ny
            o_x, o_y = X[i + 1, j + 1, 0], X[i + 1, j + 1, 1]
        # t = 0: apex q, p ends a; t = 1: apex p; t = 2: apex n, p ends b
        w[_X0 + c], w[_Y0 + c], w[_X1 + c], w[_Y1 + c], w[_X3 + c], w[_Y3 + c] = q_x, q_y, px, py, o_x, o_y
        k = 4 + c
        w[_X0 + k], w[_Y0 + k], w[_X1 + k], w[_Y1 + k], w[_X3 + k], w[_Y3 + k] = px, py, n_x, n_y, q_x, q_y
        k = 8 + c
        w[_X0 + k], w[_Y0 + k], w[_X1 + k], w[_Y1 + k], w[_X3 + k], w[_Y3 + k] = n_x, n_y, o_x, o_y, px, py
    return _lane_sums(w, d4, want)


@njit(cache=True, error_model="numpy", inline="always")
def _moved_energy(w, px, py, d4):
    """:func:`_node_energy` (no derivatives) with the node moved to (px, py), its neighbours already
    in ``w`` from the last call: only the node's own lanes are rewritten."""
    for c in range(4):
        w[_X1 + c], w[_Y1 + c] = px, py
        w[_X0 + 4 + c], w[_Y0 + 4 + c] = px, py
        w[_X3 + 8 + c], w[_Y3 + 8 + c] = px, py
    return _lane_sums(w, d4, False)[0]


@njit(cache=True, error_model="numpy", inline="always")
def _lane_sums(w, d4, want):
    """The lanes' triangles (:func:`_triangles`) summed in :func:`_node_energy`'s order; inf if any
    of the twelve is inverted beyond the regularisation."""
    _triangles(w, d4, want)
    for K in range(12):
        if w[_D + K] <= 0.0:
            return np.inf, 0.0, 0.0, 0.0, 0.0, 0.0
    E = gx = gy = hxx = hxy = hyy = 0.0
    for c in range(4):
        for t in range(3):
            K = 4 * t + c
            E += w[_F + K]
            if want:
                gx += w[_GX + K]
                gy += w[_GY + K]
                hxx += w[_HXX + K]
                hxy += w[_HXY + K]
                hyy += w[_HYY + K]
    return E, gx, gy, hxx, hxy, hyy


@njit(cache=True, error_model="numpy")
def _relax_node(X, i, j, delta2, w, omega):
    """One Newton step (line-searched, the first try ``omega`` times the step, then halved) of node
    (i, j) on the energy of its four cells; its move. ``w``: the node energy's scratch (a row of
    :func:`new_scratch`).

    The energy's functions are inlined here (Numba counts every array a call takes up and down,
    atomically: 135-141 -> 125-130 ns a visit over the survey); this step is not inlined into the
    sweeps (118-122 ns, but five times their compile time on a fresh cache)."""
    px = X[i, j, 0]
    py = X[i, j, 1]
    loc = 0.0                # local cell area: mean squared length of the 4 edges at the node
    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        ex = X[i + di, j + dj, 0] - px
        ey = X[i + di, j + dj, 1] - py
        loc += 0.25 * (ex * ex + ey * ey)
    d4 = 4.0 * delta2 * loc * loc
    E, gx, gy, hxx, hxy, hyy = _node_energy(X, i, j, px, py, d4, True, w)
    if not np.isfinite(E):
        return 0.0
    det = hxx * hyy - hxy * hxy
    if hxx > 0.0 and det > 1e-30 * (hxx * hyy + 1e-300):
        dx = -(hyy * gx - hxy * gy) / det
        dy = -(hxx * gy - hxy * gx) / det
    else:               # not positive definite: a gradient step scaled by the diagonal
        sc = max(abs(hxx), abs(hyy), 1e-12)
        dx = -gx / sc
        dy = -gy / sc
    # keep the step within the node's neighbourhood
    lim = 0.0
    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        ex = X[i + di, j + dj, 0] - px
        ey = X[i + di, j + dj, 1] - py
        lim = max(lim, np.sqrt(ex * ex + ey * ey))
    step = np.sqrt(dx * dx + dy * dy)
    if step > lim and step > 0.0:
        dx *= lim / step
        dy *= lim / step
    t = omega
    for _ls in range(12):
        E1 = _moved_energy(w, px + t * dx, py + t * dy, d4)
        if E1 < E:
            X[i, j, 0] = px + t * dx
            X[i, j, 1] = py + t * dy
            return t * np.sqrt(dx * dx + dy * dy)
        t *= 0.5
    return 0.0


@njit(cache=True)
def quiet_stamps(nodes, quiet):
    """The record of :func:`sweep_nodes`' skip rule (``quiet > 0``): ``(stamps, i0, j0)``, an int32
    array over the box of ``nodes`` and the nodes round it (node ``(i, j)`` at ``(i - i0, j - j0)``),
    zero; where ``quiet <= 0`` (no node is skipped) a ``(1, 1)`` array, unused."""
    if quiet <= 0.0 or nodes.shape[0] == 0:
        return np.zeros((1, 1), np.int32), 0, 0
    i0, j0, i1, j1 = nodes[0, 0], nodes[0, 1], nodes[0, 0], nodes[0, 1]
    for q in range(nodes.shape[0]):
        i0, i1 = min(i0, nodes[q, 0]), max(i1, nodes[q, 0])
        j0, j1 = min(j0, nodes[q, 1]), max(j1, nodes[q, 1])
    return np.zeros((i1 - i0 + 3, j1 - j0 + 3), np.int32), i0 - 1, j0 - 1


@njit(cache=True, inline="always")
def _stirred(stamps, a, b, since):
    """Whether the node at ``(a, b)`` of ``stamps`` or one of its 8 neighbours last moved more than
    the quiet move at sweep ``since`` or later."""
    for x in range(a - 1, a + 2):
        for y in range(b - 1, b + 2):
            if stamps[x, y] >= since:
                return True
    return False


@njit(cache=True, inline="always")
def _relax_span(X, nodes, q0, q1, delta2, w, omega, stamps, i0, j0, sweep, quiet):
    """Node steps of ``nodes[q0:q1]`` in order (:func:`_relax_node`) in sweep ``sweep`` (from 1);
    the largest move and the nodes stepped. With ``quiet > 0`` a node is passed over where neither
    it nor a neighbour moved more than ``quiet`` in this sweep or the last (``stamps``,
    :func:`quiet_stamps`)."""
    big = 0.0
    visits = 0
    for q in range(q0, q1):
        i, j = nodes[q, 0], nodes[q, 1]
        if quiet > 0.0 and not _stirred(stamps, i - i0, j - j0, sweep - 1):
            continue
        visits += 1
        mv = _relax_node(X, i, j, delta2, w, omega)
        if quiet > 0.0 and mv > quiet:
            stamps[i - i0, j - j0] = sweep
        if mv > big:
            big = mv
    return big, visits


@njit(cache=True, error_model="numpy")
def sweep_nodes(X, nodes, delta2, sweeps, tol, omega=1.0, quiet=0.0):
    """Gauss-Seidel sweeps of node-wise Newton steps over ``nodes`` ((K, 2) int64).

    Returns ``(sweeps done, largest move of the last sweep, node steps taken)``; moves are
    measured in the scaled coordinates (mean cell area 1). Stops early when
    no node moves more than ``tol``. With ``quiet > 0``, a node is passed over in a sweep where
    neither it nor any of its 8 neighbours moved more than ``quiet`` in that sweep or the one
    before (the first sweep visits every node).
    """
    w = new_scratch(1)[0]
    stamps, i0, j0 = quiet_stamps(nodes, quiet)
    done = 0
    last = 0.0
    visits = 0
    for s in range(1, sweeps + 1):
        done += 1
        last, n = _relax_span(X, nodes, 0, nodes.shape[0], delta2, w, omega, stamps, i0, j0, s, quiet)
        visits += n
        if last < tol:
            break
    return done, last, visits


#: Blocks a colour of :func:`sweep_nodes_coloured` is dealt in, per thread.
CHUNKS = 8


@fork_safe
@njit(cache=True, parallel=True, error_model="numpy")
def sweep_nodes_coloured(X, nodes, starts, delta2, sweeps, tol, omega=1.0, quiet=0.0):
    """:func:`sweep_nodes` in four colours, the nodes of each colour in parallel.

    ``nodes`` are sorted by colour ``2 (i mod 2) + (j mod 2)`` and colour ``c`` is
    ``nodes[starts[c]:starts[c + 1]]``: a node's step reads the 8 nodes around it and
    writes itself, so nodes of one colour (two lines apart) do not meet.
    """
    done = 0
    last = 0.0
    moves = np.zeros(nodes.shape[0])
    # a colour in CHUNKS blocks, each with its own scratch row, taken once a block (a row taken a
    # node costs Numba an atomic reference count up and down)
    chunks = CHUNKS * numba.config.NUMBA_NUM_THREADS
    scratch = new_scratch(chunks)
    stamps, i0, j0 = quiet_stamps(nodes, quiet)
    counts = np.zeros(chunks, np.int64)
    for s in range(1, sweeps + 1):
        done += 1
        for c in range(4):
            a, n = starts[c], starts[c + 1] - starts[c]
            for b in prange(chunks):
                w = scratch[b]
                for q in range(a + n * b // chunks, a + n * (b + 1) // chunks):
                    i, j = nodes[q, 0], nodes[q, 1]
                    if quiet > 0.0 and not _stirred(stamps, i - i0, j - j0, s - 1):
                        moves[q] = 0.0
                        continue
                    counts[b] += 1
                    moves[q] = _relax_node(X, i, j, delta2, w, omega)
                    if quiet > 0.0 and moves[q] > quiet:
                        stamps[i - i0, j - j0] = s
        big = moves.max() if nodes.shape[0] else 0.0
        last = big
        if big < tol:
            break
    return done, last, counts.sum()


@njit(cache=True, inline="always")
def _corner_vectors(X, ci, cj, k):
    """Edges ``a = R[k+1] - R[k]``, ``b = R[k-1] - R[k]`` at corner ``k`` of cell ``(ci, cj)``."""
    i0 = ci + _DI[k]
    j0 = cj + _DJ[k]
    k1 = (k + 1) % 4
    k3 = (k + 3) % 4
    ax = X[ci + _DI[k1], cj + _DJ[k1], 0] - X[i0, j0, 0]
    ay = X[ci + _DI[k1], cj + _DJ[k1], 1] - X[i0, j0, 1]
    bx = X[ci + _DI[k3], cj + _DJ[k3], 0] - X[i0, j0, 0]
    by = X[ci + _DI[k3], cj + _DJ[k3], 1] - X[i0, j0, 1]
    return ax, ay, bx, by


#: Grids of at least this many cells are measured by :func:`corner_min` and :func:`cell_min_sine`
#: with rows of cells in parallel (1024^2: 44 -> 22 ms a call on two threads); smaller ones, every
#: real piece at the default edge length, serially (waking the threads cost 5 % of the pattern
#: survey's time).
PARALLEL_CELLS = 1 << 18


@njit(cache=True, inline="always")
def _cell_corners(X, ci, cj, skip_grid_corners):
    """Cell ``(ci, cj)``: the smallest ``a x b / (|a|^2 + |b|^2)`` of its corners and how many are
    <= 0 (:func:`corner_min`'s terms, in its order; a grid corner's skipped if asked)."""
    nu = X.shape[0]
    nv = X.shape[1]
    best = np.inf
    bad = 0
    for k in range(4):
        i0 = ci + _DI[k]
        j0 = cj + _DJ[k]
        if skip_grid_corners and (i0 == 0 or i0 == nu - 1) and (j0 == 0 or j0 == nv - 1):
            continue
        ax, ay, bx, by = _corner_vectors(X, ci, cj, k)
        J = ax * by - ay * bx
        N = ax * ax + ay * ay + bx * bx + by * by
        v = J / N if N > 0.0 else -1.0
        if v <= 0.0:
            bad += 1
        if v < best:
            best = v
    return best, bad


@njit(cache=True, inline="always")
def _corner_row(X, ci, skip_grid_corners, apart, masked):
    """Row ``ci`` of cells (those not marked in ``apart`` where ``masked``): :func:`_cell_corners`'
    smallest and count."""
    best = np.inf
    bad = 0
    for cj in range(X.shape[1] - 1):
        if masked and apart[ci, cj]:
            continue
        v, n = _cell_corners(X, ci, cj, skip_grid_corners)
        bad += n
        if v < best:
            best = v
    return best, bad


@fork_safe
@njit(cache=True, parallel=True)
def _corner_min(X, skip_grid_corners, apart, masked):
    """:func:`corner_min` (with ``masked``, of the cells not marked in ``apart``), rows in parallel."""
    nu = X.shape[0]
    row_best = np.full(nu - 1, np.inf)
    row_bad = np.zeros(nu - 1, dtype=np.int64)
    for r in prange(nu - 1):
        ci = np.int64(r)
        row_best[ci], row_bad[ci] = _corner_row(X, ci, skip_grid_corners, apart, masked)
    return row_best.min(), row_bad.sum()


_corner_min_sized = by_size(_corner_min, PARALLEL_CELLS)


@fork_safe
@njit(cache=True, parallel=True)
def _listed_corner_min(X, skip_grid_corners, cells, blocks):
    """:func:`_cell_corners` of the ``(C, 2)`` cells listed, in ``blocks`` in parallel: the smallest
    and the count."""
    n = cells.shape[0]
    best = np.full(blocks, np.inf)
    bad = np.zeros(blocks, np.int64)
    for b in prange(blocks):
        lo, k = np.inf, 0
        for q in range(n * b // blocks, n * (b + 1) // blocks):
            v, d = _cell_corners(X, cells[q, 0], cells[q, 1], skip_grid_corners)
            k += d
            if v < lo:
                lo = v
        best[b], bad[b] = lo, k
    return best.min(), bad.sum()


_listed_corner_min_sized = by_size(_listed_corner_min, PARALLEL_CELLS)


@njit(cache=True)
def _cells_at(nodes, nu, nv):
    """``(nu-1, nv-1)`` bool: the cells with a corner at one of ``nodes`` (``(K, 2)``)."""
    out = np.zeros((nu - 1, nv - 1), np.bool_)
    for q in range(nodes.shape[0]):
        i, j = nodes[q, 0], nodes[q, 1]
        for ci in range(max(i - 1, 0), min(i, nu - 2) + 1):
            for cj in range(max(j - 1, 0), min(j, nv - 2) + 1):
                out[ci, cj] = True
    return out


class CornerCells:
    """:func:`corner_min` of a grid whose ``nodes`` (``(K, 2)``) alone move: the cells with no corner
    at one of them measured once, the others (listed) again after each move (:meth:`moved`); the
    same minimum and count as :func:`corner_min` of the whole grid, bit for bit (a minimum and a
    sum of the cells' own)."""

    def __init__(self, X: np.ndarray, skip_grid_corners: bool, nodes: np.ndarray) -> None:
        from .grid_kernels import mask_places

        nu, nv = X.shape[:2]
        self.skip = skip_grid_corners
        if nu < 2 or nv < 2:
            self.cells, self.apart, self.inside = np.zeros((0, 2), np.int64), (np.inf, 0), (np.inf, 0)
            return
        touched = _cells_at(np.ascontiguousarray(nodes, dtype=np.int64), nu, nv)
        self.cells = mask_places(touched)
        kernel = _corner_min_sized(touched.size)
        self.apart = kernel(X, skip_grid_corners, touched, True)
        self.inside = (np.inf, 0)
        self.moved(X)

    def moved(self, X: np.ndarray) -> tuple[float, int]:
        """After the nodes moved: the listed cells measured again; :meth:`figures`."""
        n = len(self.cells)
        if n:
            blocks = 8 * numba.config.NUMBA_NUM_THREADS
            kernel = _listed_corner_min_sized(n)
            self.inside = kernel(X, self.skip, self.cells, blocks if n >= PARALLEL_CELLS else 1)
        return self.figures()

    def figures(self) -> tuple[float, int]:
        """``(smallest, count <= 0)``: :func:`corner_min`'s."""
        return min(self.apart[0], self.inside[0]), int(self.apart[1] + self.inside[1])


def corner_min(X: np.ndarray, skip_grid_corners: bool) -> tuple[float, int]:
    """Smallest ``a x b / (|a|^2 + |b|^2)`` of all cell corners (1/2 for a square) and how many are <= 0.

    The 4 fixed grid-corner terms are skipped if asked. A minimum and a count, so the rows of a
    large grid (:data:`PARALLEL_CELLS`) are measured in parallel with the same result.
    """
    cells = (X.shape[0] - 1) * (X.shape[1] - 1)
    if cells <= 0:
        return np.inf, 0
    none = np.zeros((0, 0), np.bool_)
    return _corner_min_sized(cells)(X, skip_grid_corners, none, False)


@njit(cache=True, error_model="numpy", inline="always")
def _cell_sine(X, i, j):
    """Cell (i, j)'s smallest signed corner sine: its four edges (u-edges ``e_u(i, j) = X[i+1, j] -
    X[i, j]``, v-edges ``e_v``) and their lengths once, the corners' edge vectors as those or their
    negations (exactly :func:`_corner_vectors`' differences: ``x - y`` is ``-(y - x)`` in floating
    point), so the same sines bit for bit as one corner at a time, with half the square roots; -1
    for a corner with a zero-length edge."""
    u0x, u0y = X[i + 1, j, 0] - X[i, j, 0], X[i + 1, j, 1] - X[i, j, 1]
    u1x, u1y = X[i + 1, j + 1, 0] - X[i, j + 1, 0], X[i + 1, j + 1, 1] - X[i, j + 1, 1]
    v0x, v0y = X[i, j + 1, 0] - X[i, j, 0], X[i, j + 1, 1] - X[i, j, 1]
    v1x, v1y = X[i + 1, j + 1, 0] - X[i + 1, j, 0], X[i + 1, j + 1, 1] - X[i + 1, j, 1]
    lu0, lu1 = np.sqrt(u0x * u0x + u0y * u0y), np.sqrt(u1x * u1x + u1y * u1y)
    lv0, lv1 = np.sqrt(v0x * v0x + v0y * v0y), np.sqrt(v1x * v1x + v1y * v1y)
    # corner k of the cell, edges (a, b): 0 (e_u0, e_v0), 1 (e_v1, -e_u0), 2 (-e_u1, -e_v1), 3 (-e_v0, e_u1)
    s0 = (u0x * v0y - u0y * v0x) / (lu0 * lv0)
    s1 = (v1x * (-u0y) - v1y * (-u0x)) / (lv1 * lu0)
    s2 = ((-u1x) * (-v1y) - (-u1y) * (-v1x)) / (lu1 * lv1)
    s3 = ((-v0x) * u1y - (-v0y) * u1x) / (lv0 * lu1)
    best = np.inf
    for v in (-1.0 if lu0 == 0.0 or lv0 == 0.0 else s0, -1.0 if lv1 == 0.0 or lu0 == 0.0 else s1,
              -1.0 if lu1 == 0.0 or lv1 == 0.0 else s2, -1.0 if lv0 == 0.0 or lu1 == 0.0 else s3):
        if v < best:
            best = v
    return best


@fork_safe
@njit(cache=True, parallel=True, error_model="numpy")
def _cell_min_sine(X, out):
    """:func:`cell_min_sine`: :func:`_cell_sine` of every cell, rows of cells in parallel."""
    nv = X.shape[1]
    for r in prange(X.shape[0] - 1):
        i = np.int64(r)
        for j in range(nv - 1):
            out[i, j] = _cell_sine(X, i, j)


_cell_min_sine_sized = by_size(_cell_min_sine, PARALLEL_CELLS, error_model="numpy")


def cell_min_sine(X: np.ndarray) -> np.ndarray:
    """``(nu-1, nv-1)`` smallest signed corner sine ``a x b / (|a| |b|)`` of every cell (<= 0: folded);
    rows of cells in parallel on a large grid (:data:`PARALLEL_CELLS`)."""
    out = np.empty((X.shape[0] - 1, X.shape[1] - 1))
    _cell_min_sine_sized(out.size)(X, out)
    return out


#: :func:`surely_at_least`'s relative margin on the squared sine: far above the rounding of a sine's
#: square roots and division (a few 1e-16), so a corner it passes has its sine at the bound or
#: above, bit for bit as :func:`_cell_sine` (or the evening's sines) take it.
SINE_MARGIN = 1e-9


@njit(cache=True, inline="always")
def squared_bound(sine):
    """The bound :func:`surely_at_least` compares with: ``sine^2 (1 + SINE_MARGIN)``."""
    return sine * sine * (1.0 + SINE_MARGIN)


@njit(cache=True, inline="always")
def surely_at_least(c, p, bound2):
    """Whether a corner of cross product ``c`` and squared edge lengths' product ``p`` surely has a
    sine ``c / sqrt(p)`` of at least the bound (``bound2``: :func:`squared_bound`), without a square
    root or a division: ``c > 0`` and ``c^2 >= bound2 p``, ``p`` a normal number. False means only
    that the exact sine must tell; True is never wrong."""
    return c > 0.0 and 1e-280 < p < 1e280 and c * c >= bound2 * p


@njit(cache=True, inline="always")
def _cell_surely_at_least(X, i, j, bound2):
    """Whether each of cell ``(i, j)``'s four corners is :func:`surely_at_least` the bound
    (``bound2``: :func:`squared_bound`), with no square root or division (False: the exact sines
    must tell)."""
    ux, uy = X[i + 1, j, 0] - X[i, j, 0], X[i + 1, j, 1] - X[i, j, 1]
    tx, ty = X[i + 1, j + 1, 0] - X[i, j + 1, 0], X[i + 1, j + 1, 1] - X[i, j + 1, 1]
    vx, vy = X[i, j + 1, 0] - X[i, j, 0], X[i, j + 1, 1] - X[i, j, 1]
    wx, wy = X[i + 1, j + 1, 0] - X[i + 1, j, 0], X[i + 1, j + 1, 1] - X[i + 1, j, 1]
    lu, lt, lv, lw = ux * ux + uy * uy, tx * tx + ty * ty, vx * vx + vy * vy, wx * wx + wy * wy
    # the crosses of corners 0-3 (up to the sign conventions of _cell_sine, which only negate)
    c0, c1 = ux * vy - uy * vx, ux * wy - uy * wx
    c2, c3 = tx * wy - ty * wx, vy * tx - vx * ty
    return (surely_at_least(c0, lu * lv, bound2) and surely_at_least(c1, lw * lu, bound2)
            and surely_at_least(c2, lt * lw, bound2) and surely_at_least(c3, lv * lt, bound2))


@fork_safe
@njit(cache=True, parallel=True, error_model="numpy")
def _cells_below(X, sine, out):
    """:func:`cells_below`: a cell whose four corners are each :func:`surely_at_least` the bound is
    not below, with no square root or division (:func:`_cell_surely_at_least`); any other cell takes
    :func:`_cell_sine`. The grid-corner cells are compared as a sine of 1."""
    nu, nv = X.shape[0], X.shape[1]
    s2 = squared_bound(sine)
    for r in prange(nu - 1):
        i = np.int64(r)
        for j in range(nv - 1):
            if (i == 0 or i == nu - 2) and (j == 0 or j == nv - 2):
                out[i, j] = 1.0 < sine
            else:
                out[i, j] = False if _cell_surely_at_least(X, i, j, s2) else _cell_sine(X, i, j) < sine


@fork_safe
@njit(cache=True, parallel=True, error_model="numpy")
def _smallest_cell_sine(X, cap):
    nu, nv = X.shape[0], X.shape[1]
    corners = (nu - 1) * (nv - 1) > 4
    s2 = squared_bound(cap)
    rows = np.full(nu - 1, np.inf)
    for r in prange(nu - 1):
        i = np.int64(r)
        best = np.inf
        for j in range(nv - 1):
            if corners and (i == 0 or i == nu - 2) and (j == 0 or j == nv - 2):
                continue                # a grid-corner cell: a sine of 1
            if _cell_surely_at_least(X, i, j, s2):
                continue                # at the cap or above: no square root, no division
            v = _cell_sine(X, i, j)
            if v < best:                # (no cell's sine is NaN: _cell_sine skips NaN corners)
                best = v
        rows[i] = best
    return min(rows.min(), 1.0 if corners else np.inf, cap)


_smallest_cell_sine_sized = by_size(_smallest_cell_sine, PARALLEL_CELLS, error_model="numpy")


def smallest_cell_sine(X: np.ndarray, cap: float = np.inf) -> float:
    """The smallest of :func:`cell_min_sine` with the four grid-corner cells taken as a sine of 1
    (where the grid has more than four cells; their angle is the outline's), or ``cap`` where that
    is smaller: the same value as ``min(array.min(), cap)``, without the array, and without the
    square roots and divisions of the cells whose corners are :func:`surely_at_least` ``cap``."""
    cells = (X.shape[0] - 1) * (X.shape[1] - 1)
    if cells <= 0:
        raise ValueError("a grid of no cells has no smallest sine")
    kernel = _smallest_cell_sine_sized(cells)
    return float(kernel(X, float(cap)))


_cells_below_sized = by_size(_cells_below, PARALLEL_CELLS, error_model="numpy")


def cells_below(X: np.ndarray, sine: float) -> np.ndarray:
    """``(nu-1, nv-1)`` bool: cells whose :func:`cell_min_sine` is below ``sine``, the four grid-corner
    cells (whose angle is the outline's) taken as a right angle; the same cells as comparing
    :func:`cell_min_sine`, without most of its square roots and divisions."""
    out = np.empty((X.shape[0] - 1, X.shape[1] - 1), np.bool_)
    _cells_below_sized(out.size)(X, float(sine), out)
    return out


@fork_safe
@njit(cache=True, parallel=True)
def _axes_to_plane(R, k0, s0, k1, s1, shift0, shift1, scale, affine, X):
    """``X[..., 0] = R[..., k0] * s0`` and ``X[..., 1] = R[..., k1] * s1``: a grid in the xy-plane
    to planar coordinates whose frame only swaps and negates axes
    (:func:`clothgrid.foldfree.to_plane`); with ``affine`` then shifted and scaled in the same pass,
    ``(R[..., k0] * s0 - shift0) / scale``: the same IEEE operations, in the same order, as NumPy's
    multiply, subtract and divide one after the other."""
    for i in prange(R.shape[0]):
        for j in range(R.shape[1]):
            if affine:
                X[i, j, 0] = (R[i, j, k0] * s0 - shift0) / scale
                X[i, j, 1] = (R[i, j, k1] * s1 - shift1) / scale
            else:
                X[i, j, 0] = R[i, j, k0] * s0
                X[i, j, 1] = R[i, j, k1] * s1


@fork_safe
@njit(cache=True, parallel=True)
def _axes_from_plane(X, k0, s0, k1, s1, shift0, shift1, scale, affine, R):
    """The way back for the interior nodes: ``R[i, j, k0] = X[i, j, 0] * s0`` (and ``k1``), with
    ``affine`` ``(X[i, j, 0] * scale + shift0) * s0``; the boundary nodes of ``R`` kept as they are."""
    for i in prange(1, R.shape[0] - 1):
        for j in range(1, R.shape[1] - 1):
            if affine:
                R[i, j, k0] = (X[i, j, 0] * scale + shift0) * s0
                R[i, j, k1] = (X[i, j, 1] * scale + shift1) * s1
            else:
                R[i, j, k0] = X[i, j, 0] * s0
                R[i, j, k1] = X[i, j, 1] * s1


@fork_safe
@njit(cache=True, parallel=True)
def _grid_from_plane(R, X, k0, s0, k1, s1, out):
    """A new grid ``out`` in one pass: ``R``'s boundary nodes as they are, the interior's
    ``out[i, j, k0] = X[i, j, 0] * s0`` (and ``k1``) with the third coordinate 0 (a piece in the
    xy-plane): :func:`_axes_from_plane` into a copy of ``R``, without the copy."""
    nu, nv = R.shape[0], R.shape[1]
    k2 = 3 - k0 - k1
    for i in prange(nu):
        for j in range(nv):
            if i == 0 or i == nu - 1 or j == 0 or j == nv - 1:
                out[i, j, 0], out[i, j, 1], out[i, j, 2] = R[i, j, 0], R[i, j, 1], R[i, j, 2]
            else:
                out[i, j, k0] = X[i, j, 0] * s0
                out[i, j, k1] = X[i, j, 1] * s1
                out[i, j, k2] = 0.0


_axes_to_plane_sized = by_size(_axes_to_plane, PARALLEL_CELLS)


@fork_safe
@njit(cache=True, parallel=True)
def _unscale_in_plane(X, R, moved, k0, s0, k1, s1, shift0, shift1, scale):
    """The nodes of ``X`` that moved (``moved``, interior) ``X * scale + shift`` in place (NumPy's
    multiply, then add), every other node ``R``'s as :func:`_axes_to_plane` gives it (not through
    the scale and back: bit for bit), in one pass."""
    nu, nv = X.shape[0], X.shape[1]
    for i in prange(nu):
        for j in range(nv):
            if moved[i, j] and 0 < i < nu - 1 and 0 < j < nv - 1:
                X[i, j, 0] = X[i, j, 0] * scale + shift0
                X[i, j, 1] = X[i, j, 1] * scale + shift1
            else:
                X[i, j, 0] = R[i, j, k0] * s0
                X[i, j, 1] = R[i, j, k1] * s1


_unscale_in_plane_sized = by_size(_unscale_in_plane, PARALLEL_CELLS)


_axes_from_plane_sized = by_size(_axes_from_plane, PARALLEL_CELLS)


def _axes_args(axes: list[tuple[int, float]], shift, scale: float) -> tuple:
    """The plane kernels' arguments after the grid: each planar axis's coordinate and sign, the
    shift and scale, and whether they apply."""
    (k0, s0), (k1, s1) = axes
    sh = (0.0, 0.0) if shift is None else (float(shift[0]), float(shift[1]))
    return (k0, s0, k1, s1, *sh, float(scale), shift is not None)


def axes_to_plane(R: np.ndarray, axes: list[tuple[int, float]], shift, scale: float, X: np.ndarray) -> None:
    """:func:`_axes_to_plane` (``axes``: :func:`clothgrid.foldfree._axis_map`'s; ``shift`` None:
    no shift or scale), rows in parallel on a large grid (:data:`PARALLEL_CELLS`)."""
    kernel = _axes_to_plane_sized(R.shape[0] * R.shape[1])
    kernel(R, *_axes_args(axes, shift, scale), X)


def unscale_in_plane(X: np.ndarray, R: np.ndarray, moved: np.ndarray, axes: list[tuple[int, float]], shift,
                     scale: float) -> None:
    """:func:`_unscale_in_plane` (``moved``: ``(nu, nv)`` bool; ``axes``:
    :func:`clothgrid.foldfree._axis_map`'s), rows in parallel on a large grid (:data:`PARALLEL_CELLS`)."""
    (k0, s0), (k1, s1) = axes
    kernel = _unscale_in_plane_sized(X.shape[0] * X.shape[1])
    kernel(X, R, moved, k0, s0, k1, s1, float(shift[0]), float(shift[1]), float(scale))


def grid_from_plane(R: np.ndarray, X: np.ndarray, axes: list[tuple[int, float]]) -> np.ndarray:
    """:func:`_grid_from_plane` into a new array (``axes``: :func:`clothgrid.foldfree._axis_map`'s,
    a piece in the xy-plane), rows in parallel."""
    (k0, s0), (k1, s1) = axes
    out = np.empty_like(R)
    _grid_from_plane(R, X, k0, s0, k1, s1, out)
    return out


def axes_from_plane(X: np.ndarray, axes: list[tuple[int, float]], shift, scale: float, R: np.ndarray) -> None:
    """:func:`_axes_from_plane` (arguments as :func:`axes_to_plane`'s), rows in parallel on a large
    grid (:data:`PARALLEL_CELLS`)."""
    kernel = _axes_from_plane_sized(R.shape[0] * R.shape[1])
    kernel(X, *_axes_args(axes, shift, scale), R)


@fork_safe
@njit(cache=True, parallel=True)
def _dilate(mask, before, after, nu, nv):
    """The interior nodes of an ``(nu, nv)`` grid near a true entry of ``mask``, and their count.

    Node ``(i, j)`` (``0 < i < nu - 1``, ``0 < j < nv - 1``) is marked where ``mask[ci, cj]`` is
    true for some ``i - before <= ci <= i + after`` and ``j - before <= cj <= j + after``: for a
    mask of nodes and ``before = after = m``, the nodes within ``m`` grid lines in the max norm;
    for a mask of cells, ``before = m + 1`` and ``after = m``, the nodes within ``m`` lines of a
    corner of a marked cell. Two passes of running counts (along the rows, then down the columns),
    rows in parallel: the cost does not grow with ``m``.
    """
    mu, mv = mask.shape
    # along the rows: hits[ci, j] = any(mask[ci, j - before : j + after + 1])
    hits = np.zeros((mu, nv), np.bool_)
    for ci in prange(mu):
        run = np.zeros(mv + 1, np.int32)
        for cj in range(mv):
            run[cj + 1] = run[cj] + (1 if mask[ci, cj] else 0)
        for j in range(nv):
            hi = min(mv, j + after + 1)
            lo = max(0, j - before)
            hits[ci, j] = hi > lo and run[hi] > run[lo]
    # down the columns: running counts of hits over the rows
    down = np.zeros((mu + 1, nv), np.int32)
    for ci in range(mu):
        for j in range(nv):
            down[ci + 1, j] = down[ci, j] + (1 if hits[ci, j] else 0)
    out = np.zeros((nu, nv), np.bool_)
    counts = np.zeros(nu, np.int64)
    for i in prange(1, nu - 1):
        hi = min(mu, i + after + 1)
        lo = max(0, i - before)
        if hi <= lo:
            continue
        c = 0
        for j in range(1, nv - 1):
            if down[hi, j] > down[lo, j]:
                out[i, j] = True
                c += 1
        counts[i] = c
    return out, counts.sum()


_dilate_sized = by_size(_dilate, PARALLEL_CELLS)


@njit(cache=True, inline="always")
def _count_true(mask):
    """How many entries of a 2D bool ``mask`` are true (:func:`~clothgrid.grid_kernels.row_counts_into`'s
    rows, parallel where the kernel it is inlined into is)."""
    rows = np.zeros(mask.shape[0] + 1, np.int64)
    row_counts_into(mask, rows)
    return rows.sum()


@fork_safe
@njit(cache=True, parallel=True)
def _true_count(mask):
    """:func:`_count_true`, rows in parallel."""
    return _count_true(mask)


@fork_safe
@njit(cache=True, parallel=True)
def _dilate_boxes(mask, before, after, nu, nv):
    """:func:`_dilate` of a sparse ``mask``: each true entry ``(ci, cj)`` marks its box of interior
    nodes ``ci - after <= i <= ci + before``, ``cj - after <= j <= cj + before`` (rows of the mask in
    parallel: two threads may write True to the same node, the same value), then the marked nodes
    counted. One array of the grid's size, not three: the cost follows the boxes."""
    mu, mv = mask.shape
    out = np.zeros((nu, nv), np.bool_)
    for r in prange(mu):
        ci = np.int64(r)
        for cj in range(mv):
            if mask[ci, cj]:
                for i in range(max(1, ci - after), min(nu - 2, ci + before) + 1):
                    for j in range(max(1, cj - after), min(nv - 2, cj + before) + 1):
                        out[i, j] = True
    return out, _count_true(out)


_dilate_boxes_sized = by_size(_dilate_boxes, PARALLEL_CELLS)
_true_count_sized = by_size(_true_count, PARALLEL_CELLS)


def true_count(mask: np.ndarray) -> int:
    """How many entries of a 2D bool ``mask`` are true (rows in parallel on a large grid)."""
    mask = np.ascontiguousarray(mask)
    return int(_true_count_sized(mask.size)(mask))


def dilate(mask: np.ndarray, before: int, after: int, nu: int, nv: int) -> tuple[np.ndarray, int]:
    """:func:`_dilate`, rows in parallel on a large grid (:data:`PARALLEL_CELLS`); by boxes
    (:func:`_dilate_boxes`, the same nodes) where the true entries' boxes cover the grid at most
    four times over."""
    mask = np.ascontiguousarray(mask)
    count = true_count(mask)
    sized = _dilate_boxes_sized if count * (before + after + 1) ** 2 <= 4 * nu * nv else _dilate_sized
    out, count = sized(nu * nv)(mask, before, after, nu, nv)
    return out, int(count)


@njit(cache=True)
def node_components(nodes):
    """The components of a set of grid nodes (``(K, 2)``) joined as the 8 neighbours of a node:
    each node's component label (from 0, in order of first node) and their count. Nodes of two
    components are never neighbours, so a node-by-node sweep may visit them in any interleaving."""
    K = nodes.shape[0]
    label = np.full(K, -1, np.int64)
    if K == 0:
        return label, 0
    i0, i1 = nodes[:, 0].min(), nodes[:, 0].max()
    j0, j1 = nodes[:, 1].min(), nodes[:, 1].max()
    index = np.full((i1 - i0 + 3, j1 - j0 + 3), -1, np.int64)     # a ring of -1 around the box
    for q in range(K):
        index[nodes[q, 0] - i0 + 1, nodes[q, 1] - j0 + 1] = q
    stack = np.empty(K, np.int64)
    count = 0
    for q0 in range(K):
        if label[q0] >= 0:
            continue
        label[q0] = count
        stack[0] = q0
        top = 1
        while top:
            top -= 1
            q = stack[top]
            a0, b0 = nodes[q, 0] - i0 + 1, nodes[q, 1] - j0 + 1
            for a in range(a0 - 1, a0 + 2):
                for b in range(b0 - 1, b0 + 2):
                    r = index[a, b]
                    if r >= 0 and label[r] < 0:
                        label[r] = count
                        stack[top] = r
                        top += 1
        count += 1
    return label, count


@fork_safe
@njit(cache=True, parallel=True, error_model="numpy")
def sweep_nodes_parts(X, nodes, starts, delta2, sweeps, tol, omega=1.0, quiet=0.0):
    """:func:`sweep_nodes` with ``nodes`` in parts (part ``p`` is ``nodes[starts[p]:starts[p + 1]]``,
    whole components of :func:`node_components`, each in the order of :func:`sweep_nodes`' list),
    the parts of a sweep in parallel: no node of one part is a neighbour of a node of another, so
    every node's step reads what it read in order, and the grid is the same, bit for bit. The
    sweeps stop together, on the largest move of all parts, as :func:`sweep_nodes` does; the nodes
    passed over (``quiet``) are its own too (a node's neighbours are in its part)."""
    parts = starts.shape[0] - 1
    scratch = new_scratch(parts)
    stamps, i0, j0 = quiet_stamps(nodes, quiet)
    bigs = np.zeros(parts)
    counts = np.zeros(parts, np.int64)
    done = 0
    last = 0.0
    for s in range(1, sweeps + 1):
        done += 1
        for p in prange(parts):
            bigs[p], n = _relax_span(X, nodes, starts[p], starts[p + 1], delta2, scratch[p], omega, stamps, i0, j0,
                                     s, quiet)
            counts[p] += n
        last = bigs.max()
        if last < tol:
            break
    return done, last, counts.sum()
