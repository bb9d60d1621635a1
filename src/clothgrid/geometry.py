"""Plane geometry shared by the boundary, quality, plotting and fold-free code."""

from __future__ import annotations

import numpy as np

from . import limits
from .errors import BoundaryError

__all__ = ["PLANAR_TOL", "cross", "points_in_polygon", "box_holds", "reflect", "boundary_loop", "signed_area", "vector_area", "best_fit_plane", "plane_axes", "plane_frame",
           "spike_points", "SPIKE_TURN_DEG", "untie_loops", "roll"]

#: A point set is planar when no point is farther than this (relative to its size) from its plane.
PLANAR_TOL = 1e-9


def roll(p: np.ndarray, shift: int) -> np.ndarray:
    """``np.roll(p, shift, axis=0)`` without its overhead (several times faster on the small
    outlines of a pattern file, where it is called for every piece)."""
    n = len(p)
    s = shift % n if n else 0
    if s == 0:
        return np.array(p, copy=True)
    return np.concatenate((p[n - s:], p[:n - s]))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of ``(..., 3)`` arrays, the same arithmetic (``a1 b2 - a2 b1``, ...) without its
    dispatch: several times faster on the single vectors and small outlines that every piece's
    plane frame, quality and corner scoring take, the same bits."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    np.subtract(a[..., 1] * b[..., 2], a[..., 2] * b[..., 1], out=out[..., 0])
    np.subtract(a[..., 2] * b[..., 0], a[..., 0] * b[..., 2], out=out[..., 1])
    np.subtract(a[..., 0] * b[..., 1], a[..., 1] * b[..., 0], out=out[..., 2])
    return out


def boundary_loop(points: np.ndarray) -> np.ndarray:
    """The boundary nodes of an ``(nu, nv, d)`` grid as one closed loop, each once.

    Bottom (``i`` increasing, ``j = 0``), right (``j`` increasing at ``i = nu-1``),
    top reversed, left reversed: counter-clockwise for a counter-clockwise piece.
    """
    return np.concatenate([points[:-1, 0], points[-1, :-1], points[:0:-1, -1], points[0, :0:-1]])


def turn_angles(outline: np.ndarray) -> np.ndarray:
    """Signed turn at every point of a closed outline (radians, + left / convex for CCW)."""
    p = np.asarray(outline, dtype=np.float64)
    d_in = p - roll(p, 1)
    d_out = roll(p, -1) - p
    cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
    dot = (d_in * d_out).sum(axis=1)
    return np.arctan2(cross, dot)


def signed_area(loop: np.ndarray) -> float:
    """Signed area of a closed polygon from its first two coordinates (positive: counter-clockwise)."""
    p = np.asarray(loop)
    q = roll(p, -1)
    return 0.5 * float((p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]).sum())


def vector_area(loop: np.ndarray) -> np.ndarray:
    """Vector area ``1/2 sum p_k x p_{k+1}`` of a closed 3D polygon ``(n, 3)``."""
    p = loop - loop.mean(axis=0)
    return 0.5 * cross(p, roll(p, -1)).sum(axis=0)


def best_fit_plane(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares plane through ``(n, 3)`` points.

    Returns
    -------
    centre, normal, distance : numpy.ndarray, numpy.ndarray, float
        A point of the plane, its unit normal (sign arbitrary) and the largest
        distance of a point from it.
    """
    centre = pts.mean(axis=0)
    d = pts - centre
    _, vecs = np.linalg.eigh(d.T @ d)
    normal = vecs[:, 0]
    return centre, normal, float(np.abs(d @ normal).max(initial=0.0))


def plane_axes(normal: np.ndarray) -> np.ndarray:
    """``(2, 3)`` orthonormal in-plane axes ``e1, e2`` with ``e1 x e2 = normal`` (a unit vector)."""
    e1 = cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, cross(normal, e1)])


def plane_frame(points: np.ndarray, fit: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """The oriented best-fit plane of a grid: centre, in-plane axes and the farthest distance from it.

    Parameters
    ----------
    points : numpy.ndarray
        ``(nu, nv, 3)`` nodes.
    fit : numpy.ndarray, optional
        ``(n, 3)`` points the plane is fitted to (default: the boundary loop).

    Returns
    -------
    centre : (3,) array
    basis : (2, 3) array
        Orthonormal in-plane axes, chosen so that the boundary loop (bottom,
        right, top reversed, left reversed) turns counter-clockwise in the
        coordinates ``(p - centre) @ basis.T``.
    distance : float
        The largest distance of a fitted point from the plane.
    """
    loop = boundary_loop(points)
    centre, normal, dist = best_fit_plane(loop if fit is None else fit)
    if vector_area(loop) @ normal < 0:
        normal = -normal
    return centre, plane_axes(normal), dist


#: A vertex where a closed outline turns back by this much (degrees) starts a spike.
SPIKE_TURN_DEG = 170.0


def spike_points(loop: np.ndarray, width: float) -> np.ndarray:
    """Mask of the points of a closed 2D outline that lie on zero-width spikes.

    A spike is where the outline runs out and straight back: a slit or a notch
    mark drawn into a cut line, not cloth; a step back of at most ``width``
    (a turn back by :data:`SPIKE_TURN_DEG` or more next to so short an edge)
    is one too. A spike starts at a vertex that turns
    back by :data:`SPIKE_TURN_DEG` or more whose two neighbours are at most
    ``width`` apart, and goes on outwards, both legs a point at a time (or one
    leg, where the other has no point there), while the legs still run back
    to back no more than ``width`` apart. Where a dart is narrower than
    ``width`` near its tip, that much of its tip is taken off too.

    Parameters
    ----------
    loop : numpy.ndarray
        ``(n, 2)`` outline, consecutive duplicates already removed.
    width : float
        Widest spike removed (same units as ``loop``).

    Returns
    -------
    numpy.ndarray
        ``(n,)`` boolean, True for the points on spikes.
    """
    p = np.asarray(loop, dtype=np.float64)[:, :2]
    n = len(p)
    out = np.zeros(n, dtype=bool)
    if n < 4:
        return out
    d_in = p - roll(p, 1)
    d_out = roll(p, -1) - p
    cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
    limit = np.radians(SPIKE_TURN_DEG)
    tips = np.flatnonzero(np.abs(np.arctan2(cross, (d_in * d_out).sum(axis=1))) >= limit)
    prev = roll(np.arange(n), 1)
    nxt = roll(np.arange(n), -1)
    alive = n

    def gap(a: int, b: int) -> float:
        return float(np.hypot(*(p[a] - p[b])))

    def opposite(a0: int, a1: int, b0: int, b1: int) -> bool:
        """Do a0->a1 (towards the tip) and b0->b1 (away from it) run back to back?"""
        u, v = p[a1] - p[a0], p[b1] - p[b0]
        nu, nv = np.hypot(*u), np.hypot(*v)
        if nu == 0 or nv == 0:
            return True
        return float(u @ v) / (nu * nv) <= np.cos(np.pi - limit)

    for t in tips:
        if out[t] or alive < 4:
            continue
        left, right = int(prev[t]), int(nxt[t])
        if gap(left, right) > width:
            if min(gap(left, t), gap(t, right)) <= width:     # a back-step of at most width
                out[t] = True
                nxt[left], prev[right] = right, left
                alive -= 1
            continue
        taken = [int(t)]
        while alive - len(taken) > 3:
            pl, nr = int(prev[left]), int(nxt[right])
            if pl == right or nr == left:
                break
            back = opposite(pl, left, right, nr)
            if back and gap(pl, nr) <= width:
                taken += [left, right]
                left, right = pl, nr
            elif back and gap(pl, right) <= width and opposite(pl, left, left, right):
                taken.append(left)
                left = pl
            elif back and gap(left, nr) <= width and opposite(left, right, right, nr):
                taken.append(right)
                right = nr
            else:
                break
        if alive - len(taken) >= 3:
            out[taken] = True
            nxt[left], prev[right] = right, left
            alive -= len(taken)
    return out


#: candidate pairs handed to the exact segment test at a time
_PAIR_BATCH = 2_000_000


def candidate_pairs(lo: np.ndarray, hi: np.ndarray):
    """Yield ``(i, j)`` index arrays, ``i < j``, that include every pair of boxes that overlap.

    Near-linear for outlines: the boxes are hashed into a uniform grid of cells about
    twice the median box size; boxes spanning many cells (long segments) are tested
    against all others directly, in batches. Raises :class:`~clothgrid.errors.BoundaryError`
    where the pairs of nearby boxes would be more than :data:`clothgrid.limits.MAX_SEGMENT_PAIRS`.
    """
    n = len(lo)
    if n <= 128:                                 # small outlines: every pair at once
        i, j = np.triu_indices(n, 1)
        yield i, j
        return
    ext = (hi - lo).max(axis=1)
    span = float((hi.max(axis=0) - lo.min(axis=0)).max())
    cell = max(2.0 * float(np.median(ext)), span / 2**20, np.finfo(np.float64).tiny)
    c0 = np.floor((lo - lo.min(axis=0)) / cell).astype(np.int64)
    c1 = np.floor((hi - lo.min(axis=0)) / cell).astype(np.int64)
    cx, cy = c1[:, 0] - c0[:, 0] + 1, c1[:, 1] - c0[:, 1] + 1
    big = (cx * cy) > 16
    small = np.flatnonzero(~big)
    # every (cell, box) of the small boxes
    counts = (cx * cy)[small]
    owner = np.repeat(small, counts)
    start = np.repeat(np.cumsum(counts) - counts, counts)
    k = np.arange(len(owner)) - start
    w = cx[owner]
    gx, gy = c0[owner, 0] + k % w, c0[owner, 1] + k // w
    key = gx * (int(c1[:, 1].max()) + 2) + gy
    order = np.argsort(key, kind="stable")
    key, owner = key[order], owner[order]
    bounds = np.flatnonzero(np.diff(key)) + 1
    first = np.concatenate([[0], bounds])
    size = np.diff(np.concatenate([first, [len(key)]]))
    # the work, counted before it is done: a noisy, densely sampled outline has many boxes a cell
    pairs = int((size * (size - 1) // 2).sum()) + int(big.sum()) * n
    if pairs > limits.MAX_SEGMENT_PAIRS:
        raise BoundaryError(
            f"the outline is too dense to check for self-intersection: {n:,} segments whose wiggles are "
            f"much wider than their spacing give {pairs:.3g} pairs of nearby segments to compare, more than "
            f"the limit of {limits.MAX_SEGMENT_PAIRS:,} (clothgrid.limits.MAX_SEGMENT_PAIRS); simplify it "
            "(fewer points)")
    # pairs within each cell, by offset: element p with element p + off of its cell
    group_end = np.repeat(first + size, size)
    active = np.flatnonzero(np.repeat(size > 1, size))
    off = 1
    while active.size:
        active = active[active + off < group_end[active]]
        for s0 in range(0, active.size, _PAIR_BATCH):
            p = active[s0:s0 + _PAIR_BATCH]
            i, j = owner[p], owner[p + off]
            yield np.minimum(i, j), np.maximum(i, j)
        off += 1
    # the big boxes against every box
    everything = np.arange(n)
    for b_ in np.flatnonzero(big):
        for s0 in range(0, n, _PAIR_BATCH):
            other = everything[s0:s0 + _PAIR_BATCH]
            other = other[other != b_]
            yield np.minimum(other, b_), np.maximum(other, b_)


def loop_segment_pairs(lo: np.ndarray, hi: np.ndarray):
    """Yield ``(i, j)`` index arrays, ``i < j``, of the non-adjacent segments of a closed loop whose
    boxes ``lo``, ``hi`` (``(n, 2)``, segment ``k`` from point ``k`` to ``k + 1``) overlap: every
    such pair once, none empty (:func:`candidate_pairs`, filtered)."""
    n = len(lo)
    for i, j in candidate_pairs(lo, hi):
        keep = (j >= i + 2) & ~((i == 0) & (j == n - 1))
        keep &= ((lo[i, 0] <= hi[j, 0]) & (lo[j, 0] <= hi[i, 0])
                 & (lo[i, 1] <= hi[j, 1]) & (lo[j, 1] <= hi[i, 1]))
        if keep.any():
            yield i[keep], j[keep]


def _first_crossing(p: np.ndarray) -> tuple[int, int, np.ndarray] | None:
    """The first pair ``(i, j)``, ``i < j``, of non-adjacent crossing segments of a closed loop
    (the least ``i``, then the least ``j``), and where they cross. Only the pairs of segments whose
    boxes overlap are tested (:func:`loop_segment_pairs`: near-linear; a loop over every segment was
    quadratic, 64 ms a call on a 6,700-point glyph outline of a real SVG)."""
    a, b = p, roll(p, -1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    best: tuple[int, int, np.ndarray] | None = None
    for i, j in loop_segment_pairs(lo, hi):
        r = b[i] - a[i]
        s = b[j] - a[j]
        den = r[:, 0] * s[:, 1] - r[:, 1] * s[:, 0]
        q = a[j] - a[i]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (q[:, 0] * s[:, 1] - q[:, 1] * s[:, 0]) / den
            u = (q[:, 0] * r[:, 1] - q[:, 1] * r[:, 0]) / den
        hit = (den != 0) & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)
        if hit.any():
            h = np.flatnonzero(hit)
            h = h[np.lexsort((j[h], i[h]))[0]]
            if best is None or (int(i[h]), int(j[h])) < best[:2]:
                best = (int(i[h]), int(j[h]), a[i[h]] + t[h] * r[h])
    return best


def untie_loops(loop: np.ndarray, max_area: float, max_loops: int = 64) -> np.ndarray | None:
    """A closed 2D outline with its small self-crossing loops cut off, or None.

    Seam lines drawn by pattern CAD systems often run past a corner and cross
    the next one, leaving a small loop; the corner is where they cross. Each
    crossing of two segments splits the outline in two loops: the one of
    smaller area is cut off and the crossing point put in its place, while the
    loops cut off add up to at most ``max_area``. Returns the untied outline
    (the input itself when nothing crosses), or None when a crossing cuts
    off more than that (the outline really crosses itself).
    """
    p = np.asarray(loop, dtype=np.float64)[:, :2]
    removed = 0.0
    for _ in range(max_loops + 1):
        found = _first_crossing(p)
        if found is None:
            return p
        i, j, x = found
        inner = p[i + 1:j + 1]                       # between the crossing segments
        outer = np.vstack([p[j + 1:], p[:i + 1]])
        a_in = abs(signed_area(np.vstack([x, inner])))
        a_out = abs(signed_area(np.vstack([x, outer])))
        if a_in <= a_out:
            removed += a_in
            p = np.vstack([p[:i + 1], x, p[j + 1:]])
        else:
            removed += a_out
            p = np.vstack([x, inner])
        if removed > max_area or len(p) < 3:
            return None
    return None


def reflect(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(..., 2)`` ``points`` mirrored across the line through ``a`` and ``b`` (distinct 2D points)."""
    d = (b - a) / np.linalg.norm(b - a)
    rel = np.asarray(points, dtype=np.float64) - a
    return a + 2.0 * (rel @ d)[..., None] * d - rel


def box_holds(lo: np.ndarray, hi: np.ndarray, inner_lo: np.ndarray, inner_hi: np.ndarray, tol: float = 0.0) -> bool:
    """Does the box ``lo .. hi`` hold the box ``inner_lo .. inner_hi``, within ``tol`` on every side?"""
    return bool(np.all(inner_lo >= lo - tol) and np.all(inner_hi <= hi + tol))


def points_in_polygon(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd point-in-polygon test of each point (vectorised ray casting). Only the polygon's
    edges whose height range meets the points' can cross a point's ray: the others are left out
    first (a glyph inside a piece meets a few of its 2,000 edges; the same answer)."""
    if not len(points):
        return np.zeros(0, dtype=bool)
    x, y = points[:, 0:1], points[:, 1:2]
    x0, y0 = poly[:, 0], poly[:, 1]
    x1, y1 = roll(x0, -1), roll(y0, -1)
    low, high = float(points[:, 1].min()), float(points[:, 1].max())
    near = ~(((y0 > high) & (y1 > high)) | ((y0 <= low) & (y1 <= low)))
    x0, y0, x1, y1 = x0[near], y0[near], x1[near], y1[near]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xs = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return (crosses & (x < xs)).sum(axis=1) % 2 == 1
