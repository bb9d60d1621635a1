"""Sampling curves into polylines with a guaranteed chord deviation.

Every curve of a pattern piece is one of two primitives, given in the piece's
final coordinates (millimetres):

- :class:`Bezier`: a polynomial or rational Bézier curve of any degree (lines
  are degree 1; SVG quadratic and cubic segments, GarmentCode curves and DXF
  splines after :func:`bspline_to_beziers` are Béziers);
- :class:`EllipseArc`: ``c + a cos t + b sin t`` for ``t`` from ``t0`` to ``t1``
  (circular and elliptical arcs, circles, ellipses, DXF bulges).

:func:`sample_loop` turns a closed chain of primitives into a polyline whose
every chord lies within ``tol`` of the true curve, and whose points lie on
the curve (up to rounding). The bounds are rigorous, not estimates:

- Bézier: the curve lies in the convex hull of its control points (also for
  rational curves with positive weights), and the distance to a segment is a
  convex function, so the largest distance of the control points from the
  chord bounds the curve's distance from it. Pieces are split in halves (de
  Casteljau, in homogeneous coordinates) until that bound is at most ``tol``:
  adaptive, dense only where the curve bends.
- Ellipse arc: on a parameter step ``h`` a curve deviates from its chord by at
  most ``h**2 / 8 * max|p''|``, and ``|p''| <= ||[a b]||_2`` (the largest
  singular value), so equal steps ``h = sqrt(8 tol / ||[a b]||_2)`` suffice.

Segment end points (the source's vertices) are kept exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import InputError

__all__ = ["Bezier", "EllipseArc", "Primitive", "control_box", "sample_bezier", "sample_beziers", "sample_ellipse_arc",
           "sample_loop", "bspline_to_beziers", "loop_extent", "DEFAULT_REL_TOL"]

#: default chord tolerance, relative to the piece's size (bounding-box diagonal)
DEFAULT_REL_TOL = 1e-7
_MAX_DEPTH = 52      # halvings of a Bézier piece: beyond double precision anyway
_MAX_POINTS = 2_000_000


@dataclass(frozen=True, eq=False)
class Bezier:
    """A Bézier curve: ``ctrl`` ``(k, 2)`` control points, optional positive ``weights`` ``(k,)``."""

    ctrl: np.ndarray
    weights: np.ndarray | None = None

    @property
    def start(self) -> np.ndarray:
        return np.asarray(self.ctrl[0], dtype=np.float64)

    @property
    def end(self) -> np.ndarray:
        return np.asarray(self.ctrl[-1], dtype=np.float64)

    def points(self, t: np.ndarray) -> np.ndarray:
        """Points at parameters ``t`` (de Casteljau, for checks and sizes)."""
        t = np.asarray(t, dtype=np.float64)
        h = _homogeneous(self)
        pts = np.broadcast_to(h, (t.size,) + h.shape).copy()
        tt = t.reshape(-1, 1, 1)
        for r in range(1, len(h)):
            pts[:, :-r] = (1 - tt) * pts[:, :-r] + tt * pts[:, 1:len(h) - r + 1]
        return pts[:, 0, :2] / pts[:, 0, 2:]


@dataclass(frozen=True, eq=False)
class EllipseArc:
    """``center + a cos t + b sin t`` for ``t`` from ``t0`` to ``t1`` (radians, either direction).

    ``start``/``end`` may give the exact end points (kept in the samples).
    """

    center: np.ndarray
    a: np.ndarray
    b: np.ndarray
    t0: float
    t1: float
    start_point: np.ndarray | None = field(default=None)
    end_point: np.ndarray | None = field(default=None)

    def points(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64).reshape(-1, 1)
        return self.center + np.cos(t) * self.a + np.sin(t) * self.b

    @property
    def start(self) -> np.ndarray:
        return (np.asarray(self.start_point, dtype=np.float64) if self.start_point is not None
                else self.points(np.array([self.t0]))[0])

    @property
    def end(self) -> np.ndarray:
        return (np.asarray(self.end_point, dtype=np.float64) if self.end_point is not None
                else self.points(np.array([self.t1]))[0])


Primitive = Bezier | EllipseArc


def _homogeneous(b: Bezier) -> np.ndarray:
    ctrl = np.asarray(b.ctrl, dtype=np.float64)
    w = np.ones(len(ctrl)) if b.weights is None else np.asarray(b.weights, dtype=np.float64)
    return np.column_stack([ctrl * w[:, None], w])


def _split_half(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """de Casteljau at t = 1/2 of ``(m, k, 3)`` homogeneous control points."""
    k = h.shape[1]
    left = np.empty_like(h)
    right = np.empty_like(h)
    work = h.copy()
    left[:, 0] = work[:, 0]
    right[:, k - 1] = work[:, k - 1]
    for r in range(1, k):
        work = 0.5 * (work[:, :-1] + work[:, 1:])
        left[:, r] = work[:, 0]
        right[:, k - 1 - r] = work[:, -1]
    return left, right


def _dist_to_chord(p: np.ndarray) -> np.ndarray:
    """Largest distance of the inner points of ``(m, k, 2)`` from the segment first-last."""
    a, b = p[:, :1], p[:, -1:]
    d = b - a
    dd = (d * d).sum(-1)
    rel = p[:, 1:-1] - a
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(dd > 0, (rel * d).sum(-1) / np.where(dd > 0, dd, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    off = rel - t[..., None] * d
    return np.sqrt((off * off).sum(-1)).max(axis=1)


def sample_bezier(curve: Bezier, tol: float) -> np.ndarray:
    """Points of ``curve`` from its start, without its end, every chord within ``tol``
    (:func:`sample_beziers` of the one curve).

    Returns
    -------
    numpy.ndarray
        ``(n, 2)``; ``[0]`` is exactly ``ctrl[0]``. A degree-1 curve gives its
        start only.
    """
    return sample_beziers([curve], tol)[0]


def sample_beziers(curves: Sequence[Bezier], tol: float) -> list[np.ndarray]:
    """Points of each curve from its start, without its end, every chord within ``tol``: halved
    (de Casteljau, in homogeneous coordinates for rational curves) until the inner control points
    lie within ``tol`` of the chord. The curves of one degree are halved side by side, one NumPy
    pass a halving for all of them (a real SVG's 8,700 glyph curves took 5.4 s one at a time); a
    curve's points do not depend on the others'.

    Raises InputError where a curve has a non-positive weight or a non-finite coordinate, or
    where the curves together need more than 2 million points."""
    out: list[np.ndarray | None] = [None] * len(curves)
    groups: dict[int, list[int]] = {}
    hs: list[np.ndarray] = []
    for c, curve in enumerate(curves):
        h = _homogeneous(curve)
        if np.any(h[:, 2] <= 0) or not np.isfinite(h).all():
            raise InputError("a curve has a non-positive weight or a non-finite coordinate")
        hs.append(h)
        if len(h) <= 2:
            out[c] = np.asarray(curve.ctrl[:1], dtype=np.float64).copy()
        else:
            groups.setdefault(len(h), []).append(c)
    for members in groups.values():
        pending = np.stack([hs[c] for c in members])
        owner = np.arange(len(members))
        t0 = np.zeros(len(members))
        width = 1.0
        done_c: list[np.ndarray] = []
        done_t: list[np.ndarray] = []
        done_p: list[np.ndarray] = []
        for depth in range(_MAX_DEPTH + 1):
            proj = pending[..., :2] / pending[..., 2:]
            flat = (_dist_to_chord(proj) <= tol) if depth < _MAX_DEPTH else np.ones(len(pending), bool)
            done_c.append(owner[flat])
            done_t.append(t0[flat])
            done_p.append(proj[flat, 0])
            if flat.all():
                break
            rest = pending[~flat]
            left, right = _split_half(rest)
            width *= 0.5
            keep = ~flat
            t0 = np.concatenate([t0[keep], t0[keep] + width])
            owner = np.concatenate([owner[keep], owner[keep]])
            pending = np.concatenate([left, right])
            if len(pending) + sum(len(x) for x in done_t) > _MAX_POINTS:
                raise InputError("the curves need more than 2 million points to meet the sampling "
                                 "tolerance; is one degenerate?")
        cs, ts, ps = np.concatenate(done_c), np.concatenate(done_t), np.concatenate(done_p)
        order = np.lexsort((ts, cs))          # by curve, then by t (each curve's ts are distinct)
        cs, ps = cs[order], ps[order]
        cuts = np.searchsorted(cs, np.arange(len(members) + 1))
        for m, c in enumerate(members):
            pts = ps[cuts[m]:cuts[m + 1]].copy()
            pts[0] = np.asarray(curves[c].ctrl[0], dtype=np.float64)
            out[c] = pts
    return out  # type: ignore[return-value]


def sample_ellipse_arc(arc: EllipseArc, tol: float) -> np.ndarray:
    """Points of ``arc`` from its start, without its end, every chord within ``tol``."""
    m = np.column_stack([np.asarray(arc.a, float), np.asarray(arc.b, float)])
    sigma = float(np.linalg.norm(m, 2))
    span = abs(float(arc.t1) - float(arc.t0))
    if not (math.isfinite(sigma) and math.isfinite(span)):
        raise InputError("an arc has a non-finite radius or angle")
    if sigma == 0.0 or span == 0.0:
        return arc.start[None].copy()
    n = max(1, math.ceil(span * math.sqrt(sigma / (8.0 * tol))))
    # a full circle or ellipse needs at least 4 chords to have an area
    if span >= math.pi:
        n = max(n, 4)
    if n > _MAX_POINTS:
        raise InputError("an arc needs more than 2 million points to meet the sampling tolerance")
    t = np.linspace(float(arc.t0), float(arc.t1), n + 1)[:-1]
    pts = arc.points(t)
    pts[0] = arc.start
    return pts


def loop_extent(prims: list[Primitive], n: int = 17) -> float:
    """Bounding-box diagonal of points on the primitives (at most their true size)."""
    pts = [p.points(np.linspace(0.0, 1.0, n)) if isinstance(p, Bezier)
           else p.points(np.linspace(p.t0, p.t1, n)) for p in prims]
    allp = np.concatenate(pts)
    return float(np.linalg.norm(allp.max(axis=0) - allp.min(axis=0)))


def control_box(prims: Sequence[Primitive]) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """A box around a chain of primitives without sampling it: the control points of its Bezier
    curves (which hold a curve with positive weights), and the box around each elliptic arc's whole
    ellipse; None where there is no finite point."""
    pts = []
    for p in prims:
        if isinstance(p, Bezier):
            pts.append(np.asarray(p.ctrl, dtype=np.float64)[:, :2])
        else:
            reach = np.hypot(np.asarray(p.a, dtype=np.float64)[:2], np.asarray(p.b, dtype=np.float64)[:2])
            c = np.asarray(p.center, dtype=np.float64)[:2]
            pts.append(np.array([c - reach, c + reach]))
    if not pts:
        return None
    allp = np.concatenate(pts)
    allp = allp[np.isfinite(allp).all(axis=1)]
    if not len(allp):
        return None
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    return (float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1]))


def sample_loop(prims: list[Primitive], tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample a closed chain of primitives.

    Parameters
    ----------
    prims : list of Bezier or EllipseArc
        Each ends where the next starts; the last ends at the first's start.
    tol : float
        Largest distance of any chord from the true curve (absolute).

    Returns
    -------
    outline : numpy.ndarray
        ``(N, 2)`` points, the first not repeated at the end.
    vertices : numpy.ndarray
        ``(len(prims),)`` indices into ``outline`` of each primitive's start.
    """
    if not (math.isfinite(tol) and tol > 0):
        raise InputError(f"the sampling tolerance must be positive, not {tol!r}")
    parts, starts, count = [], [], 0
    beziers = [p for p in prims if isinstance(p, Bezier)]
    sampled = iter(sample_beziers(beziers, tol))
    for p in prims:
        pts = next(sampled) if isinstance(p, Bezier) else sample_ellipse_arc(p, tol)
        starts.append(count)
        parts.append(pts)
        count += len(pts)
        if count > _MAX_POINTS:
            raise InputError("a piece needs more than 2 million outline points to meet the "
                             "sampling tolerance")
    return np.concatenate(parts), np.asarray(starts, dtype=np.int64)


# --------------------------------------------------------------------------- B-splines


def bspline_to_beziers(degree: int, knots, ctrl, weights=None) -> list[Bezier]:
    """Split a (rational) B-spline into Bézier pieces by knot insertion (Boehm).

    Parameters
    ----------
    degree : int
        Degree ``p >= 1``.
    knots : array_like
        ``n + p + 1`` non-decreasing knots for ``n`` control points.
    ctrl : array_like
        ``(n, 2)`` control points.
    weights : array_like, optional
        ``(n,)`` positive weights (rational spline).

    Returns
    -------
    list of Bezier
        The spline's pieces over ``[knots[p], knots[n]]``, in order.
    """
    p = int(degree)
    P = np.asarray(ctrl, dtype=np.float64)
    n = len(P)
    U = np.asarray(knots, dtype=np.float64)
    if p < 1 or n < p + 1 or len(U) != n + p + 1 or np.any(np.diff(U) < 0) \
            or not np.isfinite(U).all() or not np.isfinite(P).all():
        raise InputError(f"invalid spline: degree {p}, {n} control points, {len(U)} knots "
                         f"(a degree-p spline with n control points needs n + p + 1 "
                         f"non-decreasing knots and n > p)")
    w = np.ones(n) if weights is None or len(weights) == 0 else np.asarray(weights, dtype=np.float64)
    if len(w) != n or np.any(w <= 0) or not np.isfinite(w).all():
        raise InputError("invalid spline: weights must be positive, one per control point")
    H = np.column_stack([P * w[:, None], w])
    lo, hi = U[p], U[n]
    if not hi > lo:
        raise InputError("invalid spline: its knot vector spans no parameter range")

    def insert(U: np.ndarray, H: np.ndarray, u: float) -> tuple[np.ndarray, np.ndarray]:
        k = int(np.searchsorted(U, u, side="right") - 1)      # U[k] <= u < U[k+1]
        k = min(k, len(U) - p - 2)
        new = np.empty((len(H) + 1, H.shape[1]))
        new[:k - p + 1] = H[:k - p + 1]
        for i in range(k - p + 1, k + 1):
            den = U[i + p] - U[i]
            a = 0.0 if den == 0 else (u - U[i]) / den
            new[i] = (1 - a) * H[i - 1] + a * H[i]
        new[k + 1:] = H[k:]
        return np.insert(U, k + 1, u), new

    # raise every knot in [lo, hi] (including the ends) to multiplicity p
    for u in np.unique(U[(U >= lo) & (U <= hi)]):
        while np.count_nonzero(U == u) < p:
            U, H = insert(U, H, float(u))
    out: list[Bezier] = []
    distinct = np.unique(U[(U >= lo) & (U <= hi)])
    for a, b in zip(distinct[:-1], distinct[1:]):
        # the piece on [a, b] has the p + 1 control points starting where knot a ends
        last_a = int(np.flatnonzero(U == a)[-1])
        first = last_a - p
        seg = H[first:first + p + 1]
        ww = seg[:, 2]
        out.append(Bezier(seg[:, :2] / ww[:, None], None if weights is None or len(weights) == 0
                          else ww.copy()))
    return out
