"""Even out the edge lengths of a planar grid: a lower edge spread, angles kept above a floor.

A mass-spring simulator's stable time step is set by its shortest, stiffest
spring, so the *edge spread* of a grid (longest over shortest edge,
:func:`clothgrid.quality.sim_figures`) is what it costs. The length functional
puts a few very long edges where the outline turns sharply inside a side (a
grid line cuts across the turn) and a few very short ones in concave bays; most
edges are within a factor 1.5 of each other. :func:`even_edges` moves the
interior nodes near those few edges, node by node (Gauss-Seidel), to lower

    E = sum over edges of  max(0, |log(l / L)| - log(BAND))^2,

``L`` the geometric mean edge length: edges within a factor :data:`BAND` of
``L`` cost nothing, so the rest of the grid is left as the length functional
made it. A move is taken only when it lowers ``E`` and leaves the sine of
every corner angle of the four cells around the node at least that of
``floor_deg``, or at least what it was where it was smaller: no cell folds, no
angle falls below the floor (nor rises above 180 degrees less the floor), and
no angle already outside them gets worse. The grid's four corner angles (the
outline's) are fixed and not counted.

The energy is lowered in two stages: first with the wide band :data:`WIDE_BAND`,
which reaches only the few most outlying edges (the ones that set the spread),
then with ``BAND``. Run alone, the narrow band's sweeps move every node near a
mildly outlying edge and stall while the extreme edges are still far out: on the
T-shirt front the spread stayed at 7.9-10.9 from 128^2 to 1024^2 nodes, where
the two stages reach 3.9-6.2. Where the narrow band's nodes are too many for the
ordered sweeps (:data:`~clothgrid.foldfree.PARALLEL_NODES`) the second stage takes
the narrowest of :data:`FINAL_BANDS` whose nodes are not (docs/performance.md,
"Ninth pass").
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numba import njit, prange

from .blas_threads import one_blas_thread
from .foldfree_kernels import PARALLEL_CELLS, squared_bound, surely_at_least
from .jit_variants import by_size, fork_safe

__all__ = ["even_edges", "even_in_plane", "FLOOR_DEG", "FLOOR_MAX_DEG", "BAND", "WIDE_BAND", "FINAL_BANDS", "SPREAD_OK"]

#: No corner angle is made smaller than this (degrees), unless it was already ...
FLOOR_DEG = 25.0
#: ... nor smaller than the grid's smallest angle, up to this (degrees): a grid of
#: well-shaped cells keeps them well shaped.
FLOOR_MAX_DEG = 40.0
#: A grid whose edge spread is at most this is left as it is.
SPREAD_OK = 3.0
#: The evened grid is kept where its spread is at most the input's times ``1 +`` this. Both spreads
#: are measured in the plane's coordinates, and the evening's scale is a power of two, which comes
#: back exactly: an edge no sweep moved keeps its length bit for bit, and this is a margin only. (A
#: scale of the mean edge itself lost 33 of 1200 fresh test pieces' evening to such an edge coming
#: back longer in its last bits, 73.04184938339515 -> ...705.)
SPREAD_ROUNDING = 1e-9
#: Edges within this factor of the geometric mean length are left alone (the last stage's band).
BAND = 1.4
#: The first stage's band: only edges outside this factor of the mean move nodes. Over the 455
#: survey pieces (under the energy rule alone, 3 %), 2.5 then 1.4 left 79 pieces with a spread
#: above 5 where 1.4 alone left 119 (2.0 then 1.4: 84; 1.7 then 1.4: 102); now 81.
WIDE_BAND = 2.5
#: Bands the last stage widens to, narrowest first, where ``band``'s active set has
#: :data:`~clothgrid.foldfree.PARALLEL_NODES` nodes or more: the ordered, over-relaxed sweeps
#: on a few thousand nodes lower the spread further than the coloured ones on a hundred thousand
#: (1024^2 T-shirt front: 1.7's 7,180 nodes reach 6.2; 1.4's 101,736, budget-limited, 9.6).
FINAL_BANDS = (1.7, 2.0)
#: Most Gauss-Seidel sweeps.
MAX_SWEEPS = 100
#: Over-relaxation of a node's step in the ordered sweeps (an active set below
#: :data:`~clothgrid.foldfree.PARALLEL_NODES` nodes, every real piece at the default edge length):
#: the first step tried is this many times the inverse of the node's curvature estimate (still at
#: most a quarter of the mean edge, halved until it lowers the energy and keeps the angles).
#: Outlying lengths spread along a grid line about one node a sweep: with the plain step (1) the
#: 294 evened survey pieces still moved in their last 50 of 100 sweeps; with 3 they reach as low
#: a spread in about a third of the sweeps. On the 1024^2 T-shirt's large active set the
#: over-relaxed step (capped at a quarter edge everywhere) raised the spread: the coloured sweeps
#: take the plain step (docs/performance.md, "Eighth pass").
OVERRELAX = 3.0
#: The ordered sweeps measure the energy and the spread of the edges at their nodes every
#: :data:`SMALL_CHECK_SWEEPS` sweeps, and stop when since the last measurement the energy fell by
#: less than :data:`SMALL_MIN_PROGRESS` and that spread by less than
#: :data:`SMALL_MIN_SPREAD_PROGRESS` (fractions). The energy alone (3 % before the wide stage came)
#: stops either too early or too late: at 6 %, 51 of the survey's pieces at 5 mm edges ended with a
#: spread over 5 % larger (a GLX sleeve 4.52 -> 5.88, the extreme edges still moving), at 3 % the
#: evening took 1.75 s of the survey at 10 mm where it takes 1.4 s now (docs/performance.md,
#: "Ninth pass").
SMALL_CHECK_SWEEPS = 5
SMALL_MIN_PROGRESS = 0.06
SMALL_MIN_SPREAD_PROGRESS = 0.01
#: The coloured sweeps, once they have made :data:`WORK_BUDGET` node moves (about 0.3 s), measure
#: the energy every :data:`CHECK_SWEEPS` sweeps and stop when it fell by less than
#: :data:`MIN_PROGRESS` since the last measurement. On a large graded grid point Gauss-Seidel
#: lowers it by about 2 % per 10 sweeps (1024^2: 100 sweeps over 101,521 nodes, 2.6 s, spread
#: 16.8 -> 16.7), a polish not worth its time.
WORK_BUDGET = 1_000_000
CHECK_SWEEPS = 10
MIN_PROGRESS = 0.05


@njit(cache=True, inline="always")
def _outlying(d2, lo, hi, lo2, hi2):
    """An edge's term of the energy from its squared length ``d2`` (``1e-300`` added), and the
    term's derivative in ``t = log(d2) / 2``: ``(t - hi)^2`` and ``2 (t - hi)`` above the band,
    ``(lo - t)^2`` and ``-2 (lo - t)`` below it, ``(0, 0)`` inside it (no logarithm where
    ``lo2 < d2 < hi2``, :func:`_inside_band`). The derivative is nonzero exactly outside the band."""
    if lo2 < d2 < hi2:
        return 0.0, 0.0
    return _term(0.5 * math.log(d2), lo, hi)


@njit(cache=True, inline="always")
def _term(t, lo, hi):
    """:func:`_outlying`'s term and derivative from ``t = log(d2) / 2``."""
    if t > hi:
        return (t - hi) ** 2, 2.0 * (t - hi)
    if t < lo:
        return (lo - t) ** 2, -2.0 * (lo - t)
    return 0.0, 0.0


@fork_safe
@njit(cache=True, parallel=True)
def _energy(X, lo, hi):
    """``sum max(0, |log l| - log BAND)^2`` over every edge (lengths already over the mean): each
    row's u-edges (to the next row) and v-edges summed in parallel, then the rows in order. (Only
    the stop rules read it, as a ratio: its last bits, the order's, decide nothing.)"""
    nu, nv = X.shape[0], X.shape[1]
    lo2, hi2 = _inside_band(lo, hi)
    rows = np.zeros(nu)
    for r in prange(nu):
        i = np.int64(r)
        e = 0.0
        for j in range(nv):
            if i + 1 < nu:
                dx, dy = X[i, j, 0] - X[i + 1, j, 0], X[i, j, 1] - X[i + 1, j, 1]
                f, slope = _outlying(dx * dx + dy * dy + 1e-300, lo, hi, lo2, hi2)
                if slope != 0.0:
                    e += f
            if j + 1 < nv:
                dx, dy = X[i, j, 0] - X[i, j + 1, 0], X[i, j, 1] - X[i, j + 1, 1]
                f, slope = _outlying(dx * dx + dy * dy + 1e-300, lo, hi, lo2, hi2)
                if slope != 0.0:
                    e += f
        rows[i] = e
    total = 0.0
    for i in range(nu):
        total += rows[i]
    return total


_energy_sized = by_size(_energy, PARALLEL_CELLS)


def _grid_energy(X: np.ndarray, lo: float, hi: float) -> float:
    """:func:`_energy`, rows in parallel on a large grid (:data:`~clothgrid.foldfree_kernels.PARALLEL_CELLS`)."""
    return _energy_sized(X.shape[0] * X.shape[1])(X, lo, hi)


#: Relative margin of :func:`_inside_band`: far above the rounding of ``exp``, ``log`` and the
#: halving (a few 1e-16 relative), far below any band (``BAND`` is 1.4).
_BAND_MARGIN = 1e-9


@njit(cache=True)
def _inside_band(lo, hi):
    """``(lo2, hi2)``: a squared edge length ``d2`` with ``lo2 < d2 < hi2`` has ``lo < log(d2) / 2 < hi``
    for certain, so it adds nothing to a node's energy or gradient and its logarithm is not taken
    (the same sums: the skipped terms are exactly the ones that added nothing)."""
    lo2 = math.exp(2.0 * lo) * (1.0 + _BAND_MARGIN)
    hi2 = math.exp(2.0 * hi) * (1.0 - _BAND_MARGIN)
    return lo2, hi2


@njit(cache=True, inline="always")
def _node_energy_below(X, i, j, lo, hi, lo2, hi2, e0):
    """Whether the energy of the four edges at node (i, j) (:func:`_outlying`'s terms, in edge order)
    is below ``e0``, its terms summed no further than the sum reaching ``e0``: the terms are not
    negative, so a rounded sum never falls again, and the edges left need no logarithm. The same
    answer as summing them all, bit for bit."""
    e = 0.0
    for n in range(4):
        a = i + (1 if n == 0 else (-1 if n == 1 else 0))
        b = j + (1 if n == 2 else (-1 if n == 3 else 0))
        dx, dy = X[i, j, 0] - X[a, b, 0], X[i, j, 1] - X[a, b, 1]
        f, slope = _outlying(dx * dx + dy * dy + 1e-300, lo, hi, lo2, hi2)
        if slope != 0.0:
            e += f
            if not e < e0:
                return False
    return e < e0


@njit(cache=True, inline="always")
def _node_gradient(X, i, j, lo, hi, lo2, hi2):
    """The node's gradient, curvature and energy (:func:`_node_energy_below`'s terms in the same
    order), from one logarithm an edge (none for an edge inside the band, :func:`_inside_band`)."""
    gx, gy, curv, e = 0.0, 0.0, 0.0, 0.0
    for n in range(4):
        a = i + (1 if n == 0 else (-1 if n == 1 else 0))
        b = j + (1 if n == 2 else (-1 if n == 3 else 0))
        dx, dy = X[i, j, 0] - X[a, b, 0], X[i, j, 1] - X[a, b, 1]
        d2 = dx * dx + dy * dy + 1e-300
        term, f = _outlying(d2, lo, hi, lo2, hi2)
        if f != 0.0:
            e += term
            gx += f * dx / d2          # d/dx of (t - hi)^2 = 2 (t - hi) * dx / d^2
            gy += f * dy / d2
            curv += 2.0 / d2 + abs(f) / d2
    return gx, gy, curv, e


@njit(cache=True)
def _corner_sine(X, p, q, r):
    """Sine of the angle at q between q->r and q->p (positive: counter-clockwise cell)."""
    ax, ay = X[r[0], r[1], 0] - X[q[0], q[1], 0], X[r[0], r[1], 1] - X[q[0], q[1], 1]
    bx, by = X[p[0], p[1], 0] - X[q[0], q[1], 0], X[p[0], p[1], 1] - X[q[0], q[1], 1]
    na = math.sqrt(ax * ax + ay * ay)
    nb = math.sqrt(bx * bx + by * by)
    if na == 0.0 or nb == 0.0:
        return -1.0
    return (ax * by - ay * bx) / (na * nb)


#: A node step's scratch (:func:`_even_node`): rows of 16 lanes, one corner a lane (edges a, b, the
#: sine; the sines after the step, before it, and the least each may be). Sixteen lanes, the
#: compile-time count LLVM's loop vectoriser takes: two 8-wide passes of square roots and divisions.
#: One array, not one a row: each array a step takes is counted up and down at every visit (Numba's
#: atomic reference counts, which its pruning pass leaves in a step with a loop and several exits),
#: and with five arrays and the helpers' own calls that was a fifth of the sweeps' time. The helpers
#: are inlined into the step, the step is not inlined into the sweeps: that took another 5 % off the
#: survey's evening but six times the sweeps' compile time (5 -> 38 s on a fresh cache).
LANES = 16
_AX, _AY, _BX, _BY, _SINE, _AFTER, _BEFORE, _NEED = (r * LANES for r in range(8))
SINE_SCRATCH = 8 * LANES


#: The corners a move of an interior node changes (:func:`_moving_edges`): in each of its four cells
#: its own corner and the two beside it; the scratch's other 4 lanes hold a right angle.
_MOVING = 12


@njit(cache=True, error_model="numpy", inline="always")
def _lane_sines(w):
    """Every lane's corner sine, :func:`_corner_sine`'s arithmetic (-1 for a zero-length edge). A
    zero-length edge's lane divides by zero: the functions it is inlined into take NumPy's error
    model too (an inlined body takes its caller's)."""
    for m in range(LANES):
        ax, ay, bx, by = w[_AX + m], w[_AY + m], w[_BX + m], w[_BY + m]
        na = math.sqrt(ax * ax + ay * ay)
        nb = math.sqrt(bx * bx + by * by)
        v = (ax * by - ay * bx) / (na * nb)
        w[_SINE + m] = -1.0 if (na == 0.0 or nb == 0.0) else v


@njit(cache=True, inline="always")
def _edge_lane(X, i, j, w, m, qi, qj, ri, rj, pi, pj):
    """Lane ``m`` of ``w``: the edges q->r and q->p of the corner at q (offsets from node (i, j)),
    :func:`_corner_sine`'s differences."""
    qx, qy = X[i + qi, j + qj, 0], X[i + qi, j + qj, 1]
    w[_AX + m] = X[i + ri, j + rj, 0] - qx
    w[_AY + m] = X[i + ri, j + rj, 1] - qy
    w[_BX + m] = X[i + pi, j + pj, 0] - qx
    w[_BY + m] = X[i + pi, j + pj, 1] - qy


@njit(cache=True, inline="always")
def _moving_edges(X, i, j, w):
    """The edges a, b of the corners interior node (i, j) moves into the lanes of ``w``; a right angle
    in the lanes left over. Lane by lane ``(q, r, p)`` offsets from the node, the sine at q between
    q->r and q->p: of the cells ``(i-1, j-1)``, ``(i-1, j)``, ``(i, j-1)``, ``(i, j)`` in turn, the
    corners counter-clockwise that are the node's own or beside it (the one opposite keeps its
    angle; an interior node's cells are all inside the grid, and none of these is a grid corner).
    Written out, so the offsets are constants (a table read at run time took 82 ns a node against
    31); ``tests/test_evening.py`` derives them afresh."""
    _edge_lane(X, i, j, w, 0, 0, -1, 0, 0, -1, -1)
    _edge_lane(X, i, j, w, 1, 0, 0, -1, 0, 0, -1)
    _edge_lane(X, i, j, w, 2, -1, 0, -1, -1, 0, 0)
    _edge_lane(X, i, j, w, 3, -1, 0, 0, 0, -1, 1)
    _edge_lane(X, i, j, w, 4, 0, 0, 0, 1, -1, 0)
    _edge_lane(X, i, j, w, 5, 0, 1, -1, 1, 0, 0)
    _edge_lane(X, i, j, w, 6, 0, -1, 1, -1, 0, 0)
    _edge_lane(X, i, j, w, 7, 1, 0, 0, 0, 1, -1)
    _edge_lane(X, i, j, w, 8, 0, 0, 0, -1, 1, 0)
    _edge_lane(X, i, j, w, 9, 0, 0, 1, 0, 0, 1)
    _edge_lane(X, i, j, w, 10, 1, 0, 1, 1, 0, 0)
    _edge_lane(X, i, j, w, 11, 0, 1, 0, 0, 1, 1)
    for m in range(_MOVING, LANES):
        w[_AX + m], w[_AY + m], w[_BX + m], w[_BY + m] = 1.0, 0.0, 0.0, 1.0


@njit(cache=True, error_model="numpy", inline="always")
def _surely_above(w, floor2):
    """Whether every lane's corner is surely at the floor or above
    (:func:`~clothgrid.foldfree_kernels.surely_at_least`, ``floor2`` its squared bound), without a
    square root or a division. False sends the node to the exact sines (:func:`_lane_sines`); True
    is never wrong."""
    low = 0
    for m in range(LANES):
        ax, ay, bx, by = w[_AX + m], w[_AY + m], w[_BX + m], w[_BY + m]
        low += not surely_at_least(ax * by - ay * bx, (ax * ax + ay * ay) * (bx * bx + by * by), floor2)
    return low == 0


@njit(cache=True, error_model="numpy", inline="always")
def _moving_sines(X, i, j, w, row):
    """The sines of the corners interior node (i, j) moves into ``w[row:row + LANES]`` (in
    :func:`_moving_edges`' order; 1.0, a right angle, in the 4 lanes left over), side by side
    (:func:`_lane_sines`: :func:`_corner_sine`'s bits)."""
    _moving_edges(X, i, j, w)
    _lane_sines(w)
    for m in range(LANES):
        w[row + m] = w[_SINE + m]


@njit(cache=True, error_model="numpy")
def _even_node(X, i, j, lo, hi, lo2, hi2, floor, floor2, w, omega):
    """One line-searched gradient step of interior node (i, j) (the first ``omega`` times the inverse
    curvature, :data:`OVERRELAX`) that lowers its energy and keeps every corner of its cells at the
    floor or no worse; the move, or -1.0 where it did not move. A step whose corners are all surely
    above the floor (:func:`_surely_above`, ``floor2``) takes no sine."""
    gx, gy, curv, e0 = _node_gradient(X, i, j, lo, hi, lo2, hi2)
    g = math.sqrt(gx * gx + gy * gy)
    if g < 1e-9:
        return -1.0
    x0, y0 = X[i, j, 0], X[i, j, 1]
    have_before = False      # the sines before the move: needed only where a corner ends below the floor
    step = min(omega / curv, 0.25 / g) if curv > 0 else 0.25 / g
    for _ in range(8):
        xt, yt = x0 - step * gx, y0 - step * gy
        X[i, j, 0] = xt
        X[i, j, 1] = yt
        ok = _node_energy_below(X, i, j, lo, hi, lo2, hi2, e0)
        if ok:
            _moving_edges(X, i, j, w)
            if not _surely_above(w, floor2):
                _lane_sines(w)
                for k in range(LANES):
                    w[_AFTER + k] = w[_SINE + k]
                for k in range(LANES):
                    if w[_AFTER + k] < floor:    # else at the floor or above: never below min(before, floor)
                        if not have_before:
                            X[i, j, 0], X[i, j, 1] = x0, y0
                            _moving_sines(X, i, j, w, _BEFORE)
                            for q in range(LANES):
                                w[_NEED + q] = min(w[_BEFORE + q], floor)
                            X[i, j, 0], X[i, j, 1] = xt, yt
                            have_before = True
                        if w[_AFTER + k] < w[_NEED + k]:
                            ok = False
                            break
        if ok:
            return step * g
        step *= 0.5
    X[i, j, 0], X[i, j, 1] = x0, y0
    return -1.0


@njit(cache=True, inline="always")
def _settled(i, j, moved_at, failed_at):
    """Whether node (i, j) last failed to move (at ``failed_at``, a visit count) and neither it nor
    any of its 8 neighbours has moved since (``moved_at``, the visit counts of their last moves):
    :func:`_even_node` reads nothing else of the grid, so it would fail again, and is not called."""
    if failed_at < 0:
        return False
    for a in range(i - 1, i + 2):
        for b in range(j - 1, j + 2):
            if moved_at[a, b] > failed_at:
                return False
    return True


@njit(cache=True, inline="always")
def _sweep_span(X, lo, hi, lo2, hi2, floor, nodes, index, q0, q1, omega, sweep, moved_at, failed_at):
    """The steps of ``nodes[q0:q1]`` in order (``index``: each node's place in the whole list,
    which numbers its visits and its ``failed_at``; None: its own place); the largest move and the
    nodes moved. A node that failed and whose neighbourhood has not moved since is skipped
    (:func:`_settled`)."""
    w = np.empty(SINE_SCRATCH)
    floor2 = squared_bound(floor)
    K = nodes.shape[0]
    biggest, moved = 0.0, 0
    for q in range(q0, q1):
        i, j = nodes[q, 0], nodes[q, 1]
        k = q if index is None else index[q]
        if _settled(i, j, moved_at, failed_at[k]):
            continue
        clock = sweep * K + k
        d = _even_node(X, i, j, lo, hi, lo2, hi2, floor, floor2, w, omega)
        if d >= 0.0:
            biggest = max(biggest, d)
            moved += 1
            moved_at[i, j] = clock
            failed_at[k] = -1
        else:
            failed_at[k] = clock
    return biggest, moved


@njit(cache=True, error_model="numpy")
def _sweep(X, lo, hi, floor, nodes, omega, sweep, moved_at, failed_at):
    """One Gauss-Seidel sweep over ``nodes`` (``(K, 2)``, row by row: the active nodes in the order
    a scan of the grid meets them, without the scan); the largest move, the nodes moved.

    ``sweep`` counts the stage's sweeps; ``moved_at`` (the grid's shape) and ``failed_at`` (``K``)
    hold the visit counts (``sweep * K + q``, -1 for none) of each node's last move and, per listed
    node, of its last failed step since: a node that failed and whose neighbourhood has not moved
    since is skipped (:func:`_settled`; the same grid, a quarter of the survey's visits fewer)."""
    lo2, hi2 = _inside_band(lo, hi)
    return _sweep_span(X, lo, hi, lo2, hi2, floor, nodes, None, 0, nodes.shape[0], omega, sweep, moved_at,
                       failed_at)


@fork_safe
@njit(cache=True, parallel=True, error_model="numpy")
def _sweep_parts(X, lo, hi, floor, nodes, index, starts, omega, sweep, moved_at, failed_at):
    """:func:`_sweep` with the nodes in parts (``nodes[starts[p]:starts[p + 1]]``, whole components
    of :func:`clothgrid.foldfree.node_parts`; ``index``: each node's place in :func:`_sweep`'s list,
    which numbers its visits and its ``failed_at``), the parts in parallel. No node of one part is a
    neighbour of a node of another, so each step and skip is the one :func:`_sweep` makes: the same
    grid, bit for bit, the same largest move and count."""
    lo2, hi2 = _inside_band(lo, hi)
    parts = starts.shape[0] - 1
    bigs = np.zeros(parts)
    counts = np.zeros(parts, np.int64)
    for p in prange(parts):
        bigs[p], counts[p] = _sweep_span(X, lo, hi, lo2, hi2, floor, nodes, index, starts[p], starts[p + 1],
                                         omega, sweep, moved_at, failed_at)
    return bigs.max(), counts.sum()


@fork_safe
@njit(cache=True, parallel=True, error_model="numpy")
def _sweep_coloured(X, lo, hi, floor, active, omega, sweep, moved_at, failed_at):
    """:func:`_sweep` in four colours ``(i mod 2, j mod 2)``, the rows of each colour in parallel
    (a node's step reads its 8 neighbours and writes itself: nodes of one colour do not meet).
    ``failed_at`` has the grid's shape here, and a visit's count is ``4 sweep + colour``."""
    nu, nv = X.shape[0], X.shape[1]
    lo2, hi2 = _inside_band(lo, hi)
    row_big = np.zeros(nu)
    row_moved = np.zeros(nu, np.int64)
    floor2 = squared_bound(floor)
    for c in range(4):
        ci, cj = c // 2, c % 2
        rows = (nu - 2 - ci + 1) // 2
        clock = 4 * sweep + c
        for r in prange(rows):
            i = 1 + ci + 2 * r
            # one block a row, 128 bytes unused at its end: blocks of two threads never share a cache line
            w = np.empty(SINE_SCRATCH + 16)
            for j in range(1 + cj, nv - 1, 2):
                if not active[i, j] or _settled(i, j, moved_at, failed_at[i, j]):
                    continue
                d = _even_node(X, i, j, lo, hi, lo2, hi2, floor, floor2, w, omega)
                if d >= 0.0:
                    row_big[i] = max(row_big[i], d)
                    row_moved[i] += 1
                    moved_at[i, j] = clock
                    failed_at[i, j] = -1
                else:
                    failed_at[i, j] = clock
    return row_big.max(), row_moved.sum()


@njit(cache=True, inline="always")
def _edge_bands(d2, los, his, lo2s, hi2s, bit, flags, energy):
    """One edge of squared length ``d2`` (``1e-300`` added) against each band ``k`` (limits ``los[k],
    his[k]``, inside-range ``lo2s[k], hi2s[k]``, bands nested, the narrowest first): where it is
    outside, bit ``bit`` of band ``k`` set in ``flags`` (two bits a band) and its term added to
    ``energy[k]`` (:func:`_outlying`'s, its logarithm taken once); the flags."""
    if lo2s[0] < d2 < hi2s[0]:
        return flags                # inside the narrowest band: inside every band
    t = 0.5 * math.log(d2)
    for k in range(los.shape[0]):
        if lo2s[k] < d2 < hi2s[k]:
            continue
        f, slope = _term(t, los[k], his[k])
        if slope != 0.0:
            flags |= bit << (2 * k)
            energy[k] += f
    return flags


@fork_safe
@njit(cache=True, parallel=True)
def _outside_edges(X, los, his):
    """Which edges lie outside each band ``k`` (limits ``los[k] <= his[k]``, nested, the narrowest
    first; at most 4), rows in parallel: per node, whether its u-edge to ``(i + 1, j)`` (bit ``2k``)
    and its v-edge to ``(i, j + 1)`` (bit ``2k + 1``) are (each edge looked at once, its logarithm
    once); and each band's energy (:func:`_energy`'s, bit for bit: the same terms summed in the same
    order). :func:`_hot_nodes` makes one band's nodes of them."""
    nu, nv = X.shape[0], X.shape[1]
    K = los.shape[0]
    lo2s, hi2s = np.empty(K), np.empty(K)
    for k in range(K):
        lo2s[k], hi2s[k] = _inside_band(los[k], his[k])
    edges = np.zeros((nu, nv), np.uint8)
    rows = np.zeros((nu, K))
    for r in prange(nu):
        i = np.int64(r)
        e = np.zeros(K)
        for j in range(nv):
            flags = 0
            if i + 1 < nu:
                dx, dy = X[i, j, 0] - X[i + 1, j, 0], X[i, j, 1] - X[i + 1, j, 1]
                flags = _edge_bands(dx * dx + dy * dy + 1e-300, los, his, lo2s, hi2s, 1, flags, e)
            if j + 1 < nv:
                dx, dy = X[i, j, 0] - X[i, j + 1, 0], X[i, j, 1] - X[i, j + 1, 1]
                flags = _edge_bands(dx * dx + dy * dy + 1e-300, los, his, lo2s, hi2s, 2, flags, e)
            edges[i, j] = flags
        rows[i] = e
    total = np.zeros(K)
    for i in range(nu):
        for k in range(K):
            total[k] += rows[i, k]
    return edges, total


@fork_safe
@njit(cache=True, parallel=True)
def _hot_nodes(edges, k):
    """Band ``k``'s nodes at an outlying edge (:func:`_outside_edges`' flags): its own u- or v-edge,
    or the one from ``(i - 1, j)`` or ``(i, j - 1)``; and how many of them are interior nodes."""
    nu, nv = edges.shape[0], edges.shape[1]
    u, v = np.uint8(1 << (2 * k)), np.uint8(2 << (2 * k))
    hot = np.zeros((nu, nv), np.bool_)
    inner = np.zeros(nu, np.int64)
    for i in prange(nu):
        n = 0
        for j in range(nv):
            h = edges[i, j] & (u | v) != 0 or (i > 0 and edges[i - 1, j] & u != 0) \
                or (j > 0 and edges[i, j - 1] & v != 0)
            hot[i, j] = h
            if h and 0 < i < nu - 1 and 0 < j < nv - 1:
                n += 1
        inner[i] = n
    return hot, inner.sum()


_outside_edges_sized = by_size(_outside_edges, PARALLEL_CELLS)
_hot_nodes_sized = by_size(_hot_nodes, PARALLEL_CELLS)
#: :func:`_last_band` finds its bands' outlying edges in one pass on grids of at most this many
#: nodes, a band at a time on larger ones (a byte of flags a node less at the step's peak: 16 MB at
#: 4096^2)
ONE_PASS_MAX_NODES = 1 << 22


def _outside(X: np.ndarray, lo: float, hi: float, margin: int, at_most: int | None = None
             ) -> tuple[np.ndarray | None, int, float]:
    """Interior nodes within ``margin`` grid lines of an edge outside the band; their count; the
    grid's energy in the band (:func:`_grid_energy`'s, from the same pass). With ``at_most``: where
    the interior nodes at such an edge (all of them near one) are already more, ``(None, their
    count, energy)``, without the margin's nodes."""
    return _outside_bands(X, [(lo, hi)], margin, [at_most])[0]


def _outside_bands(X: np.ndarray, limits: list[tuple[float, float]], margin: int,
                   at_most: list[int | None], stop: int | None = None) -> list[tuple[np.ndarray | None, int, float]]:
    """:func:`_outside` of each band of ``limits`` (nested, the narrowest first, at most 4) with its
    ``at_most``, the outlying edges of every band found in one pass over the grid (one byte of flags
    a node; a band's nodes made when it is looked at); the bands after the first whose count is
    below ``stop`` are not looked at (their answers left out)."""
    from .foldfree_kernels import dilate

    nu, nv = X.shape[:2]
    if len(limits) > 4:
        raise ValueError("at most 4 bands in one pass")
    edges, energies = _outside_edges_sized(nu * nv)(X, np.array([lo for lo, _ in limits]),
                                                    np.array([hi for _, hi in limits]))
    hot_nodes = _hot_nodes_sized(nu * nv)
    out = []
    for k, (energy, most) in enumerate(zip(energies, at_most)):
        energy = float(energy)
        hot, inner = hot_nodes(edges, k)
        if k == len(limits) - 1:
            edges = None                # (its pages free before the dilation: the peak at 4096^2)
        if most is not None and inner > most:
            out.append((None, int(inner), energy))
            continue
        out.append((*dilate(hot, margin, margin, nu, nv), energy))
        if stop is not None and out[-1][1] < stop:
            break
    return out


def _band_limits(band: float, mean_log: float) -> tuple[float, float]:
    """The logarithms of the shortest and longest edge inside ``band`` of a geometric mean length
    whose logarithm is ``mean_log`` (in the evening's scaled units)."""
    return mean_log - math.log(band), mean_log + math.log(band)


def _even_band(X: np.ndarray, band: float, floor: float, max_sweeps: int, active: np.ndarray,
               count: int, moved_at: np.ndarray, mean_log: float = 0.0, energy: float | None = None
               ) -> dict[str, Any]:
    """One stage of :func:`even_edges`: sweeps over the ``count`` ``active`` nodes with the energy
    of ``band``, in order (over-relaxed) or, for :data:`~clothgrid.foldfree.PARALLEL_NODES` nodes
    or more, in colours, until a stop rule holds; ``{band, active, sweeps, moved}``. ``moved_at``:
    the grid's shape, int32 or int64, the stage's record of each node's last move (filled here: one
    array serves every stage). ``energy``: the grid's in the band where the caller has it
    (:func:`_outside`'s), else measured here."""
    from .foldfree import PARALLEL_NODES, node_parts
    from .grid_kernels import mask_places

    lo, hi = _band_limits(band, mean_log)
    mean_length = math.exp(mean_log)       # the geometric mean edge in X's units
    out = {"band": band, "active": int(count), "sweeps": 0, "moved": 0}
    if energy is None:
        energy = _grid_energy(X, lo, hi)
    ordered = count < PARALLEL_NODES
    if ordered:
        # the list of the active nodes: a sweep of a few thousand no longer scans the grid, and the
        # energy is re-measured on their edges only (the rest of the grid's is a constant)
        mask, active = active, mask_places(active)
        part, spread = _stage_energy(X, lo, hi, active, mask)
        rest = energy - part
        sweep_once, omega = _sweep, OVERRELAX
        failed_at = np.full(len(active), -1, np.int64)
        parts = node_parts(active)
        if parts is not None:      # separate components on the host's threads: the same grid
            order, starts = parts
            split = np.ascontiguousarray(active[order])

            def sweep_once(X, lo, hi, floor, _active, omega, sweep, moved_at, failed_at):
                return _sweep_parts(X, lo, hi, floor, split, order, starts, omega, sweep, moved_at, failed_at)
    else:
        sweep_once, omega = _sweep_coloured, 1.0
        failed_at = np.full(X.shape[:2], -1, moved_at.dtype)
    moved_at.fill(-1)
    check, progress = (SMALL_CHECK_SWEEPS, SMALL_MIN_PROGRESS) if ordered else (CHECK_SWEEPS, MIN_PROGRESS)
    for sweep in range(max_sweeps):
        biggest, moved = sweep_once(X, lo, hi, floor, active, omega, sweep, moved_at, failed_at)
        out["sweeps"] = sweep + 1
        out["moved"] += int(moved)
        if moved == 0 or biggest < 1e-4 * mean_length:     # a ten-thousandth of the mean edge
            break
        if (sweep + 1) % check == 0:
            if ordered:
                was = spread
                part, spread = _stage_energy(X, lo, hi, active, mask)
                now = rest + part
                # (a spread that stays infinite, a zero-length edge no move could lengthen, is slow)
                if now > (1.0 - progress) * energy and not spread < (1.0 - SMALL_MIN_SPREAD_PROGRESS) * was:
                    break
            else:
                now = _grid_energy(X, lo, hi)
                if (sweep + 1) * count >= WORK_BUDGET and now > (1.0 - progress) * energy:
                    break
            energy = now
    return out


@njit(cache=True)
def _stage_energy(X, lo, hi, nodes, active):
    """The energy of the edges at ``nodes`` (``(K, 2)`` interior nodes, ``active`` their mask; an
    edge between two of them counted once), and the longest over the shortest of those edges."""
    lo2, hi2 = _inside_band(lo, hi)
    e, short, long = 0.0, np.inf, 0.0
    for q in range(nodes.shape[0]):
        i, j = nodes[q, 0], nodes[q, 1]
        for n in range(4):
            a = i + (1 if n == 0 else (-1 if n == 1 else 0))
            b = j + (1 if n == 2 else (-1 if n == 3 else 0))
            dx, dy = X[i, j, 0] - X[a, b, 0], X[i, j, 1] - X[a, b, 1]
            d2 = dx * dx + dy * dy
            short = min(short, d2)
            long = max(long, d2)
            if n % 2 == 1 and active[a, b]:
                continue                    # the edge back to an active node: counted there
            f, slope = _outlying(d2 + 1e-300, lo, hi, lo2, hi2)
            if slope != 0.0:
                e += f
    return e, (math.sqrt(long / short) if short > 0.0 else np.inf)


def _last_band(X: np.ndarray, band: float, wider: tuple[float, ...], margin: int, wide_ran: bool,
               mean_log: float = 0.0) -> tuple[float, np.ndarray, int, float] | None:
    """The last stage's band, active set, its count and the grid's energy in that band: ``band``, or
    the narrowest of ``wider`` whose active set is below :data:`~clothgrid.foldfree.PARALLEL_NODES`;
    where all are that large, the widest of them, or none after a wide stage (whose result then
    stands). None also for no active node."""
    from .foldfree import PARALLEL_NODES

    bands = (band, *wider)
    # every band's outlying edges in one pass (a band at a time on a grid of more than
    # ONE_PASS_MAX_NODES: its flags would be held beside a band's nodes and their dilation); a band
    # whose nodes at outlying edges alone are too many is passed over without its margin
    limits = [_band_limits(b, mean_log) for b in bands]
    most = [PARALLEL_NODES] * (len(bands) - 1) + [None]
    if X.shape[0] * X.shape[1] <= ONE_PASS_MAX_NODES:
        found = _outside_bands(X, limits, margin, most, stop=PARALLEL_NODES)
    else:
        found = []
        for lim, m in zip(limits, most):
            found += _outside_bands(X, [lim], margin, [m])
            if found[-1][1] < PARALLEL_NODES:
                break
    for b, (active, count, energy) in zip(bands, found):
        if count < PARALLEL_NODES:
            break
    else:
        if wide_ran:
            return None
    return (b, active, int(count), energy) if count else None


@one_blas_thread()     # Numba's threads do the work (clothgrid.blas_threads)
def even_edges(points: np.ndarray, *, dim: int = 3, floor_deg: float = FLOOR_DEG, band: float = BAND,
               spread_ok: float = SPREAD_OK, max_sweeps: int = MAX_SWEEPS, margin: int = 3,
               copy: bool = True, wide_band: float | None = WIDE_BAND) -> tuple[np.ndarray, dict[str, Any]]:
    """Lower the edge spread of a planar grid by moving interior nodes near its outlying edges.

    Parameters
    ----------
    points : array_like
        ``(nu, nv, 3)`` planar grid; the boundary nodes are kept exactly.
    dim : int
        2 for a grid in the xy-plane, else 3 (then the grid must be planar).
    floor_deg : float
        No corner angle of a cell is made smaller than this (degrees), nor
        smaller than it was where it already was, nor smaller than the grid's
        smallest angle up to :data:`FLOOR_MAX_DEG` (grid corners aside; the
        floor used is ``info["floor_deg"]``).
    band : float
        Edges within this factor of the geometric mean edge length are left
        alone in the last stage (a wider one of :data:`FINAL_BANDS` where this
        band's nodes are too many for ordered sweeps).
    spread_ok : float
        A grid whose edge spread is at most this is returned as it is.
    max_sweeps : int
        Most Gauss-Seidel sweeps a stage; fewer where the energy falls slowly
        (:data:`SMALL_MIN_PROGRESS` and :data:`SMALL_MIN_SPREAD_PROGRESS` over
        :data:`SMALL_CHECK_SWEEPS` sweeps for an active set below
        ``PARALLEL_NODES``, else, past :data:`WORK_BUDGET`
        node moves, :data:`MIN_PROGRESS` over :data:`CHECK_SWEEPS`).
    margin : int
        Nodes within this many grid lines of an outlying edge are moved.
    copy : bool
        False: ``points`` (a C-contiguous float64 array) is the caller's to give away, and the
        result is written into it (a grid-size copy less); it is still returned as it was where
        nothing is evened.
    wide_band : float or None
        The first stage's band (:data:`WIDE_BAND`); None, or a band no wider
        than ``band``: the last stage only.

    Raises
    ------
    InputError
        Not an ``(nu, nv, 3)`` grid of finite nodes, not planar, or a band
        that is not a finite number greater than 1.

    Returns
    -------
    points : numpy.ndarray
        ``(nu, nv, 3)`` nodes.
    info : dict
        ``spread_before``, ``spread_after`` (longest / shortest edge),
        ``active`` (the most nodes a stage could move), ``moved`` (node moves),
        ``sweeps`` (all stages), ``stages`` (per stage run: ``band``, ``active``,
        ``sweeps``, ``moved``), ``seconds``, and ``floor_deg`` (the floor used)
        when it evened. The spread never grows (beyond :data:`SPREAD_ROUNDING`):
        where the sweeps left it larger, the input grid is returned, ``moved`` is 0 and ``rejected_spread`` holds
        the spread they reached.
    """
    from .foldfree import _grid_copy, _with_interior, plane_frame, to_plane

    t0 = time.perf_counter()
    _check_bands(band, wide_band)
    R = _grid_copy(points, "even_edges", copy=copy)
    centre, basis = plane_frame(R, dim)
    X = np.ascontiguousarray(to_plane(R, centre, basis))
    info = even_in_plane(X, floor_deg=floor_deg, band=band, spread_ok=spread_ok, max_sweeps=max_sweeps,
                         margin=margin, wide_band=wide_band)
    info["seconds"] = time.perf_counter() - t0
    if info["moved"] == 0:                 # as it was, bit for bit
        return R, info
    return _with_interior(R, X, centre, basis, dim, copy=False), info   # R: this call's own copy


@fork_safe
@njit(cache=True, parallel=True)
def _scale_rows(X, factor):
    for i in prange(X.shape[0]):
        for j in range(X.shape[1]):
            X[i, j, 0] *= factor
            X[i, j, 1] *= factor


_scale_rows_sized = by_size(_scale_rows, PARALLEL_CELLS)


def _scale_by(X: np.ndarray, factor: float) -> None:
    """``X *= factor`` in place, rows in parallel on a large grid (NumPy's products, bit for bit)."""
    _scale_rows_sized(X.shape[0] * X.shape[1])(X, float(factor))


def _check_bands(band: Any, wide_band: Any) -> None:
    """InputError unless ``band`` (and ``wide_band``, where not None) is a finite number above 1."""
    from .errors import InputError

    for name, value in (("band", band), ("wide_band", wide_band)):
        if value is None and name == "wide_band":
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                or not (1.0 < float(value) < math.inf):
            raise InputError(f"{name} must be a finite number greater than 1, not {value!r}")


def even_in_plane(X: np.ndarray, *, floor_deg: float = FLOOR_DEG, band: float = BAND,
                  spread_ok: float = SPREAD_OK, max_sweeps: int = MAX_SWEEPS, margin: int = 3,
                  wide_band: float | None = WIDE_BAND, touched: list | None = None) -> dict[str, Any]:
    """:func:`even_edges`' work on the plane's coordinates ``X`` (C-contiguous float64 ``(nu, nv, 2)``,
    finite; the boundary nodes kept), in place: for a caller that has them already
    (:func:`clothgrid.foldfree.relax_in_plane`'s result) and makes the 3D grid once. Where nothing
    moved, or the evening was rejected (``rejected_spread``), ``X`` is as it came, bit for bit; any
    other node than those of its stages (each a ``(K, 2)`` array appended to ``touched``, where
    given) is as it came in any case. Returns :func:`even_edges`' info (``seconds`` this call's)."""
    from .foldfree import PARALLEL_NODES
    from .grid_kernels import mask_places

    t0 = time.perf_counter()
    _check_bands(band, wide_band)
    record = edge_blocks(X)
    shortest2, longest2, log_sum = edge_stats(X, record)
    shortest = math.sqrt(shortest2)
    spread = math.sqrt(longest2) / shortest if shortest > 0 else float("inf")
    info: dict[str, Any] = {"spread_before": spread, "spread_after": spread, "moved": 0, "sweeps": 0,
                            "active": 0, "stages": []}
    if not (shortest > 0 and spread > spread_ok):
        info["seconds"] = time.perf_counter() - t0
        return info
    from .foldfree_kernels import smallest_cell_sine

    # The interior is scaled by the power of two nearest the geometric mean edge length: then
    # X / scale * scale is X bit for bit, and a node no sweep moves comes back as it was; the
    # bands are taken about the mean, whose logarithm in those units is mean_log (|.| < 0.35).
    edges = (X.shape[0] - 1) * X.shape[1] + X.shape[0] * (X.shape[1] - 1)
    log_mean = log_sum / (2 * edges)              # the geometric mean edge length's logarithm
    power = round(log_mean / math.log(2.0))
    scale, mean_log = math.ldexp(1.0, power), log_mean - power * math.log(2.0)
    _scale_by(X, 1.0 / scale)       # (exact: a power of two)
    # only a smallest angle below FLOOR_MAX_DEG counts: a cap a little above its sine spares the
    # square roots of the cells above it, and a sine at the cap is an angle above FLOOR_MAX_DEG
    cap = math.sin(math.radians(FLOOR_MAX_DEG)) * (1.0 + 1e-12)
    smallest = math.degrees(math.asin(min(1.0, max(0.0, smallest_cell_sine(X, cap)))))
    info["floor_deg"] = max(floor_deg, min(smallest, FLOOR_MAX_DEG))
    floor = math.sin(math.radians(info["floor_deg"]))
    wide = wide_band is not None and wide_band > band
    stages: list[dict[str, Any]] = []
    saved = []      # each stage's nodes as they were: X is put back where the evening is rejected
    # a node's visit counts fit 32 bits (a grid-size array of half the pages to fault in) unless
    # the sweeps asked for are very many
    moved_at = np.empty(X.shape[:2], np.int32 if max_sweeps * PARALLEL_NODES < 2**31 else np.int64)

    def stage(b: float, active: np.ndarray, count: int, energy: float) -> None:
        nodes = mask_places(active)
        saved.append((nodes, X[nodes[:, 0], nodes[:, 1]]))       # a copy (fancy indexing)
        if touched is not None:
            touched.append(nodes)
        stages.append(_even_band(X, b, floor, max_sweeps, active, count, moved_at, mean_log, energy))

    if wide:
        active, count, energy = _outside(X, *_band_limits(wide_band, mean_log), margin)
        if count:
            stage(wide_band, active, int(count), energy)
    wider = tuple(f for f in FINAL_BANDS if f > band and not (wide and f >= wide_band))
    last = _last_band(X, band, wider, margin, bool(stages), mean_log)
    if last is not None:
        stage(*last)
    info["stages"] = stages
    for done in stages:
        info["active"] = max(info["active"], done["active"])
        info["sweeps"] += done["sweeps"]
        info["moved"] += done["moved"]
    _scale_by(X, scale)
    if info["moved"] == 0:                 # as it was, bit for bit
        info["seconds"] = time.perf_counter() - t0
        return info
    shortest2, longest2 = edge_extremes(X, record, [nodes for nodes, _ in saved])  # where the stages moved
    # the lengths' max / min (sqrt is monotone); a zero-length edge (no move makes one: its corners'
    # sines are -1, below any floor) would be an infinite spread
    after = math.sqrt(longest2) / math.sqrt(shortest2) if shortest2 > 0.0 else math.inf
    if not after <= info["spread_before"] * (1.0 + SPREAD_ROUNDING):
        # The sweeps lower an energy of every outlying edge, not the spread itself: on about 1 in
        # 250 fresh test pieces the longest or shortest edge got a little worse (24.7 -> 25.3).
        # Then the grid is put back as it was, bit for bit (the scale is a power of two).
        for nodes, was in reversed(saved):
            X[nodes[:, 0], nodes[:, 1]] = was * scale
        info.update(rejected_spread=after, moved=0)
    else:
        info["spread_after"] = after
    info["seconds"] = time.perf_counter() - t0
    return info


#: :func:`_edge_stats` keeps its running product of squared lengths within 2^-400 .. 2^400, and
#: takes the logarithm of a squared length outside that range on its own
_PRODUCT_RANGE = 2.0 ** 400


@njit(cache=True, inline="always")
def _edge_stat(d2, lo, hi, p, e, s):
    """One squared length into :func:`_edge_stats`' row figures: extremes, running product ``p``
    (kept in range by moving its binary exponent into ``e``), lone logarithms ``s``."""
    lo, hi = min(lo, d2), max(hi, d2)
    if 1.0 / _PRODUCT_RANGE <= d2 <= _PRODUCT_RANGE:
        p *= d2
        if not 1.0 / _PRODUCT_RANGE <= p <= _PRODUCT_RANGE:
            m, k = math.frexp(p)
            p, e = m, e + k
    else:
        s += math.log(d2) if d2 > 0.0 else -np.inf
    return lo, hi, p, e, s


#: Nodes of a row in a block of :func:`_edge_stats`' record of the edges' extremes (a node holds its
#: edges to ``(i + 1, j)`` and ``(i, j + 1)``): the evening measures again only the blocks at the
#: nodes it moved (:func:`edge_extremes`).
EDGE_BLOCK = 64


@fork_safe
@njit(cache=True, parallel=True)
def _edge_stats(X, blocks):
    """The smallest and largest squared edge length ``d0 * d0 + d1 * d1`` of a ``(nu, nv, 2)`` grid
    (their square roots are the lengths' minimum and maximum, bit for bit) and the sum of every
    edge's ``log(d2)`` (twice the log of the geometric mean length times the edge count: a running
    product a row, one logarithm each, within a few 1e-13 of the sum of the logarithms a row),
    without an array of lengths, rows in parallel. A zero-length edge makes the sum -inf. Each
    block's extremes go into ``blocks`` (``(nu, blocks, 2)``, :data:`EDGE_BLOCK` nodes of a row a
    block; a ``(0, 0, 2)`` array: none)."""
    nu, nv = X.shape[0], X.shape[1]
    rows = np.empty((nu, 3))
    nb = -(-nv // EDGE_BLOCK)
    keep = blocks.shape[0] > 0
    for r in prange(nu):
        i = np.int64(r)
        lo, hi, p, e, s = np.inf, 0.0, 1.0, 0, 0.0
        for b in range(nb):
            b_lo, b_hi = lo, hi
            lo, hi = np.inf, 0.0
            for j in range(b * EDGE_BLOCK, min((b + 1) * EDGE_BLOCK, nv)):
                if i + 1 < nu:
                    d0, d1 = X[i + 1, j, 0] - X[i, j, 0], X[i + 1, j, 1] - X[i, j, 1]
                    lo, hi, p, e, s = _edge_stat(d0 * d0 + d1 * d1, lo, hi, p, e, s)
                if j + 1 < nv:
                    d0, d1 = X[i, j + 1, 0] - X[i, j, 0], X[i, j + 1, 1] - X[i, j, 1]
                    lo, hi, p, e, s = _edge_stat(d0 * d0 + d1 * d1, lo, hi, p, e, s)
            if keep:
                blocks[i, b, 0], blocks[i, b, 1] = lo, hi
            lo, hi = min(lo, b_lo), max(hi, b_hi)
        rows[i, 0], rows[i, 1] = lo, hi
        rows[i, 2] = s + (math.log(p) + e * math.log(2.0) if p > 0.0 else -np.inf)
    return rows[:, 0].min(), rows[:, 1].max(), rows[:, 2].sum()


@fork_safe
@njit(cache=True, parallel=True)
def _edge_extremes(X, blocks, todo):
    """:func:`_edge_stats`' blocks marked in ``todo`` (``(nu, blocks)``) measured again; the smallest
    and largest squared edge length of all blocks."""
    nu, nv = X.shape[0], X.shape[1]
    nb = blocks.shape[1]
    for r in prange(nu):
        i = np.int64(r)
        for b in range(nb):
            if not todo[i, b]:
                continue
            lo, hi = np.inf, 0.0
            for j in range(b * EDGE_BLOCK, min((b + 1) * EDGE_BLOCK, nv)):
                if i + 1 < nu:
                    d0, d1 = X[i + 1, j, 0] - X[i, j, 0], X[i + 1, j, 1] - X[i, j, 1]
                    d2 = d0 * d0 + d1 * d1
                    lo, hi = min(lo, d2), max(hi, d2)
                if j + 1 < nv:
                    d0, d1 = X[i, j + 1, 0] - X[i, j, 0], X[i, j + 1, 1] - X[i, j, 1]
                    d2 = d0 * d0 + d1 * d1
                    lo, hi = min(lo, d2), max(hi, d2)
            blocks[i, b, 0], blocks[i, b, 1] = lo, hi
    lo, hi = np.inf, 0.0
    for i in range(nu):
        for b in range(nb):
            lo, hi = min(lo, blocks[i, b, 0]), max(hi, blocks[i, b, 1])
    return lo, hi


_edge_stats_sized = by_size(_edge_stats, PARALLEL_CELLS)


_edge_extremes_sized = by_size(_edge_extremes, PARALLEL_CELLS)


def edge_stats(X: np.ndarray, blocks: np.ndarray | None = None) -> tuple[float, float, float]:
    """:func:`_edge_stats`, rows in parallel on a large grid (:data:`PARALLEL_CELLS`); each block's
    extremes into ``blocks`` where given (:func:`edge_blocks`)."""
    return _edge_stats_sized(X.shape[0] * X.shape[1])(X, _NO_BLOCKS if blocks is None else blocks)


_NO_BLOCKS = np.zeros((0, 0, 2))


def edge_blocks(X: np.ndarray) -> np.ndarray:
    """An empty record of :func:`edge_stats`' blocks for the grid ``X``."""
    return np.empty((X.shape[0], -(-X.shape[1] // EDGE_BLOCK), 2))


def edge_extremes(X: np.ndarray, blocks: np.ndarray, moved: list[np.ndarray]) -> tuple[float, float]:
    """The smallest and largest squared edge length of ``X``, whose :func:`edge_stats` filled
    ``blocks`` when only the ``(K, 2)`` nodes of ``moved`` were elsewhere: the blocks of the edges at
    those nodes measured again (the same extremes as :func:`edge_stats`, bit for bit)."""
    todo = np.zeros(blocks.shape[:2], bool)
    for nodes in moved:
        i, j = nodes[:, 0], nodes[:, 1]
        todo[i, j // EDGE_BLOCK] = True                        # its own edges
        todo[i, np.maximum(j - 1, 0) // EDGE_BLOCK] = True     # the edge from (i, j - 1)
        todo[np.maximum(i - 1, 0), j // EDGE_BLOCK] = True     # the edge from (i - 1, j)
    return _edge_extremes_sized(X.shape[0] * X.shape[1])(X, blocks, todo)
