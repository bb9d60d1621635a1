"""Four boundary curves of a piece: :class:`Boundary`.

Conventions (MATH.md): bottom and top run left to right, left and right run
bottom to top, and the four corners are shared: ``bottom[0] == left[0]``,
``bottom[-1] == right[0]``, ``top[0] == left[-1]``, ``top[-1] == right[-1]``.
Points are 2D or 3D; 2D points get ``z = 0``.

Build a boundary with :meth:`Boundary.from_sides` (four point lists) or
:meth:`Boundary.from_outline` (a closed outline and four corner indices); both
validate the input and raise :class:`~clothgrid.errors.BoundaryError` with a
message that says what is wrong and where.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from . import limits
from .errors import BoundaryError, InputError
from .geometry import PLANAR_TOL, best_fit_plane, cross, loop_segment_pairs, plane_axes, roll
from .limits import MAX_OUTLINE_POINTS, check_coordinates

__all__ = ["Boundary", "resample_polyline", "ArcSampler"]

SIDES = ("bottom", "right", "top", "left")
#: corner name -> ((side, index), (side, index)); the first is kept on snapping
CORNERS = {
    "bottom-left": (("bottom", 0), ("left", 0)),
    "bottom-right": (("bottom", -1), ("right", 0)),
    "top-left": (("top", 0), ("left", -1)),
    "top-right": (("top", -1), ("right", -1)),
}
CORNER_TOL = 1e-9    # corners, touching: relative to the piece's size
LENGTH_TOL = 1e-12   # a side shorter than this (relative) has zero length
_TINY = np.finfo(np.float64).tiny


def _fmt(p: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in p) + ")"


def _as_points(data: Any, what: str) -> np.ndarray:
    """``data`` as an ``(n, 2)`` or ``(n, 3)`` finite float64 array, or BoundaryError."""
    if isinstance(data, (list, tuple)) and len(data) > MAX_OUTLINE_POINTS:
        raise BoundaryError(f"{what} has {len(data):,} points, more than the limit of "
                            f"{MAX_OUTLINE_POINTS:,} points per outline")
    try:
        raw = np.asarray(data)
        if raw.dtype.kind not in "iuf":    # booleans, strings, numbers too big for a float
            kind = {"b": "a boolean", "U": "a string", "S": "a string"}.get(raw.dtype.kind)
            if kind is None and raw.dtype.kind == "O":
                flat = [v for v in _flat(data) if not isinstance(v, (int, float)) or isinstance(v, bool)]
                kind = (f"{type(flat[0]).__name__} {flat[0]!r:.40}" if flat
                        else "an integer too big for a float")
            raise BoundaryError(f"{what} must be a list of 2D or 3D points [x, y] or [x, y, z] of "
                                f"numbers; a coordinate is {kind or raw.dtype.name}")
        if isinstance(data, list) and raw.dtype.kind in "iuf" and any(
                type(v) is bool for row in data if isinstance(row, (list, tuple)) for v in row):
            raise BoundaryError(f"{what} must be a list of 2D or 3D points [x, y] or [x, y, z] of "
                                "numbers; a coordinate is a boolean")
        pts = np.array(raw, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as exc:
        if isinstance(exc, BoundaryError):
            raise
        raise BoundaryError(f"{what} must be a list of 2D or 3D points [x, y] or [x, y, z] "
                            f"({exc})") from None
    if pts.size == 0:
        raise BoundaryError(f"{what} has no points")
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise BoundaryError(f"{what} must be a list of 2D or 3D points [x, y] or [x, y, z], "
                            f"got an array of shape {pts.shape}")
    bad = np.flatnonzero(~np.isfinite(pts).all(axis=1))
    if bad.size:
        raise BoundaryError(f"{what} has a non-finite coordinate (NaN or inf) at point "
                            f"{bad[0]}: {pts[bad[0]].tolist()}"
                            + (f" ({bad.size} such points)" if bad.size > 1 else ""))
    if len(pts) > MAX_OUTLINE_POINTS:
        raise BoundaryError(f"{what} has {len(pts):,} points, more than the limit of "
                            f"{MAX_OUTLINE_POINTS:,} points per outline")
    try:
        check_coordinates(pts, what)
    except InputError as exc:
        raise BoundaryError(str(exc)) from None
    return pts


def outline_points(points: Any) -> np.ndarray:
    """The points of a closed outline as an ``(N, 2)`` or ``(N, 3)`` finite float64 array, a last
    point equal to the first (within :data:`CORNER_TOL` of the outline's size) dropped.

    Raises
    ------
    BoundaryError
        Not a list of 2D or 3D points of finite numbers, or too many of them.
    """
    pts = _as_points(points, "the outline")
    if len(pts) >= 2 and np.linalg.norm(pts[-1] - pts[0]) <= max(CORNER_TOL * _bbox_diagonal(pts), _TINY):
        pts = pts[:-1]
    return pts


def _flat(data: Any, limit: int = 10_000):
    """The scalars of nested lists (at most ``limit`` of them), for messages."""
    stack = [data]
    while stack and limit > 0:
        x = stack.pop()
        if isinstance(x, (list, tuple)):
            stack.extend(reversed(x))
        else:
            limit -= 1
            yield x


def _to3d(pts: np.ndarray) -> np.ndarray:
    if pts.shape[1] == 3:
        return np.ascontiguousarray(pts)
    return np.ascontiguousarray(np.column_stack([pts, np.zeros(len(pts))]))


def _bbox_diagonal(pts: np.ndarray) -> float:
    return float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))


def _arc_length(pts: np.ndarray) -> np.ndarray:
    """Cumulative arc length, starting at 0."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])


def _check_count(n: Any, what: str) -> int:
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 2:
        raise InputError(f"{what} must be an integer >= 2, not {n!r}")
    return int(n)


#: A polyline vertex that turns by at least this (degrees) is kept as a node when a side is
#: resampled (:meth:`Boundary.resampled`): a dart's tip and mouth, a notch, a kink.
SHARP_TURN_DEG = 30.0


#: Kept vertices (:func:`resample_polyline`) closer than this fraction of the
#: mean node spacing to a side's end or to each other are not kept.
MIN_KEPT_PIECE = 0.5


def sharp_vertices(points: Any, min_turn: float = SHARP_TURN_DEG) -> np.ndarray:
    """Indices of the inner vertices of a polyline that turn by at least ``min_turn`` degrees."""
    pts = _to3d(_as_points(points, "the polyline"))
    if len(pts) < 3:
        return np.zeros(0, dtype=np.int64)
    d = np.diff(pts, axis=0)
    ln = np.linalg.norm(d, axis=1)
    ok = ln > 0
    idx = np.flatnonzero(ok)
    if len(idx) < 2:
        return np.zeros(0, dtype=np.int64)
    u = d[idx] / ln[idx, None]
    cosang = np.clip((u[:-1] * u[1:]).sum(axis=1), -1.0, 1.0)
    turn = np.degrees(np.arccos(cosang))
    # the vertex between segment idx[k] and idx[k+1] is idx[k+1]
    return (idx[1:][turn >= min_turn]).astype(np.int64)


def resample_polyline(points: Any, n: int, keep: Any = None) -> np.ndarray:
    """Resample a polyline to ``n`` points uniformly spaced in arc length.

    Parameters
    ----------
    points : array_like
        ``(m, 2)`` or ``(m, 3)`` points, ``m >= 2``; consecutive duplicates are
        allowed.
    n : int
        Number of points wanted, ``n >= 2``.
    keep : sequence of int, optional
        Inner vertices of ``points`` that must be nodes: the polyline is cut
        there and each piece gets a share of the ``n - 1`` segments in
        proportion to its length (at least one each; where there are more
        such vertices than inner nodes, those of the shortest pieces are dropped,
        as are those closer than half the mean node spacing to an end or to
        each other).

    Returns
    -------
    numpy.ndarray
        ``(n, 3)`` float64 points on the polyline, equally spaced in its arc
        length (piecewise, with ``keep``); the first and last points are
        exactly ``points[0]`` and ``points[-1]``.
    """
    n = _check_count(n, "the number of points")
    arc = ArcSampler(_as_points(points, "the polyline"))
    pts, s = arc.pts, arc.s
    cuts = sorted({int(i) for i in (keep if keep is not None else ()) if 0 < int(i) < len(pts) - 1})
    if cuts and n > 2:
        out = arc.at(t := _piecewise_targets(s, cuts, n))
        out[0], out[-1] = pts[0], pts[-1]
        exact = {float(s[i]): pts[i] for i in cuts}
        for k, x in enumerate(t):
            if float(x) in exact:
                out[k] = exact[float(x)]
        return out
    return arc.sample(n)


class ArcSampler:
    """A polyline's arc-length parametrisation, made once and sampled at any node count.

    :func:`resample_polyline` is one sampling of one; the corner choice samples each side of its
    coarse grids twice (some 2,700 grids over the survey's files), without the input checks.

    Parameters
    ----------
    pts : array_like
        ``(m, 2)`` or ``(m, 3)`` points, ``m >= 2``, finite (not checked); consecutive duplicates
        are allowed.

    Raises
    ------
    BoundaryError
        Fewer than 2 points, or a polyline of zero length.
    """

    __slots__ = ("pts", "s", "_sk", "_q")

    def __init__(self, pts: Any):
        pts = _to3d(np.asarray(pts, dtype=np.float64))
        if len(pts) < 2:
            raise BoundaryError(f"a polyline needs at least 2 points, got {len(pts)}")
        s = _arc_length(pts)
        if s[-1] <= 0.0:
            raise BoundaryError("cannot resample a polyline of zero length")
        nz = np.concatenate([[True], np.diff(s) > 0.0])   # strictly increasing for interp
        self.pts, self.s = pts, s
        self._sk, self._q = s[nz], np.ascontiguousarray(pts[nz].T)

    def at(self, t: np.ndarray) -> np.ndarray:
        """``(len(t), 3)`` points at arc positions ``t`` (linear between the vertices)."""
        out = np.empty((len(t), 3))
        for k in range(3):
            out[:, k] = np.interp(t, self._sk, self._q[k])
        return out

    def sample(self, n: int) -> np.ndarray:
        """``(n, 3)`` points equally spaced in arc length, the first and last exactly the polyline's."""
        out = self.at(np.linspace(0.0, self.s[-1], n))
        out[0], out[-1] = self.pts[0], self.pts[-1]
        return out


def _piecewise_targets(s: np.ndarray, cuts: list[int], n: int) -> np.ndarray:
    """Arc positions of ``n`` nodes: every cut vertex a node, the rest spread by length.

    A cut closer than :data:`MIN_KEPT_PIECE` of the mean node spacing to an end
    or to another cut is dropped (a kept vertex 0.03 mm from a corner would
    otherwise make a 0.03 mm edge, and a cell that is all but flat).
    """
    total = float(s[-1])
    pos = [float(s[i]) for i in cuts]
    pos = [p for p in pos if 0.0 < p < total]
    shortest = MIN_KEPT_PIECE * total / (n - 1)
    while True:
        bounds = [0.0] + pos + [total]
        lens = np.diff(bounds)
        if len(pos) <= n - 2 and (lens >= shortest).all():
            break
        # too many cuts, or too close: drop the one that ends the shortest piece
        k = int(np.argmin(lens))
        pos.pop(min(k, len(pos) - 1))
        if not pos:
            return np.linspace(0.0, total, n)
    segs = len(lens)
    share = lens / total * (n - 1)
    cnt = np.maximum(1, np.floor(share)).astype(np.int64)
    while cnt.sum() > n - 1:                              # at least one each: take from the richest
        k = int(np.argmax(np.where(cnt > 1, cnt - share, -np.inf)))
        cnt[k] -= 1
    while cnt.sum() < n - 1:                              # largest remainders
        k = int(np.argmax(share - cnt))
        cnt[k] += 1
    t = [np.linspace(bounds[k], bounds[k + 1], int(cnt[k]) + 1)[:-1] for k in range(segs)]
    return np.concatenate(t + [[total]])


def _segments_intersect(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray,
                        tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Do 2D segments ``a-b`` and ``c-d`` cross or touch (within ``tol``)?

    Returns the boolean mask and an approximate meeting point per pair.
    """
    r, s = b - a, d - c
    lr = np.maximum(np.hypot(r[:, 0], r[:, 1]), _TINY)
    ls = np.maximum(np.hypot(s[:, 0], s[:, 1]), _TINY)

    def side(u, lu, p):   # signed distance of p from the line along u, 0 if within tol
        dist = (u[:, 0] * p[:, 1] - u[:, 1] * p[:, 0]) / lu
        return dist, np.where(np.abs(dist) <= tol, 0.0, np.sign(dist))

    d1, s1 = side(r, lr, c - a)
    d2, s2 = side(r, lr, d - a)
    _, s3 = side(s, ls, a - c)
    _, s4 = side(s, ls, b - c)
    hit = (s1 * s2 <= 0) & (s3 * s4 <= 0)
    collinear = (s1 == 0) & (s2 == 0) & (s3 == 0) & (s4 == 0)
    if collinear.any():   # overlap of the projections on a-b
        t1 = ((c - a) * r).sum(axis=1) / lr
        t2 = ((d - a) * r).sum(axis=1) / lr
        overlap = (np.maximum(t1, t2) >= -tol) & (np.minimum(t1, t2) <= lr + tol)
        hit &= ~collinear | overlap
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(d1 != d2, d1 / (d1 - d2), 0.0)
    where = c + np.clip(f, 0.0, 1.0)[:, None] * s
    return hit, where


def _find_self_intersection(p: np.ndarray, tol: float) -> tuple[int, int, np.ndarray] | None:
    """First pair of non-adjacent segments of the closed 2D polygon ``p`` that meet.

    Segment ``k`` runs from ``p[k]`` to ``p[k+1]`` (cyclically). Adjacent segments
    count only when they fold back onto each other. Returns ``(k, m, point)``
    with ``k < m`` (``k == m`` for a fold-back at the end of ``k``), or None.
    """
    a, b = p, roll(p, -1)
    # adjacent segments: fold back when the turn is a reversal
    u, w = b - a, roll(b - a, -1)
    lu = np.maximum(np.hypot(u[:, 0], u[:, 1]), _TINY)
    back = (np.abs(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]) / lu <= tol) & ((u * w).sum(axis=1) < 0)
    if back.any():
        k = int(np.flatnonzero(back)[0])
        return k, k, b[k]
    lo, hi = np.minimum(a, b) - tol, np.maximum(a, b) + tol
    best: tuple[int, int, np.ndarray] | None = None
    for i, j in loop_segment_pairs(lo, hi):                    # non-adjacent, each pair once
        hit, where = _segments_intersect(a[i], b[i], a[j], b[j], tol)
        if hit.any():
            h = np.flatnonzero(hit)
            h = h[np.lexsort((j[h], i[h]))[0]]          # the first pair in outline order
            if best is None or (int(i[h]), int(j[h])) < best[:2]:
                best = (int(i[h]), int(j[h]), where[h])
    return best


@dataclass(frozen=True, eq=False, repr=False)
class Boundary:
    """The four boundary curves of a piece.

    Build it with :meth:`from_sides` or :meth:`from_outline`, which validate
    the input; the plain constructor does not.

    Attributes
    ----------
    bottom, right, top : numpy.ndarray
        ``(n, 3)`` C-contiguous float64 points. Bottom and top run left to
        right, right runs bottom to top.
    left : numpy.ndarray
        ``(n, 3)`` points, bottom to top. The four corners are shared exactly
        (bitwise identical values at both ends).
    dim : int
        2 if the points were given in 2D (with ``z = 0`` added), else 3.
    name : str or None
        A name for messages and output files.
    sampled : bool
        The sides are points sampled along an outline (a pattern piece's, a region's whose corners
        were chosen), not nodes: :meth:`resampled` spaces nodes along them whatever their count.
    """

    bottom: np.ndarray
    right: np.ndarray
    top: np.ndarray
    left: np.ndarray
    dim: int = 3
    name: str | None = None
    sampled: bool = False

    # ------------------------------------------------------------------ build
    @classmethod
    def from_sides(cls, bottom: Any, right: Any, top: Any, left: Any, *,
                   name: str | None = None) -> Boundary:
        """Validate four sides and build a boundary.

        Parameters
        ----------
        bottom, right, top, left : array_like
            ``(n, 2)`` or ``(n, 3)`` points each, ``n >= 2``, all sides of the
            same dimension. Bottom and top run left to right, left and right
            bottom to top; the corners must meet within ``1e-9`` times the
            bounding-box diagonal and are then made bitwise identical (the
            bottom's and top's values are kept). Opposite sides may have
            different numbers of points (see :attr:`shape`).
        name : str, optional
            Name of the piece.

        Raises
        ------
        BoundaryError
            Points that are not a list of 2D/3D points, fewer than 2 points on a
            side, NaN or inf, corners that do not meet, a side of zero length,
            or an outline that crosses or touches itself (checked for 2D and
            planar 3D pieces).
        """
        raw = {s: _as_points(p, f"the {s} side") for s, p in zip(SIDES, (bottom, right, top, left))}
        dims = {s: p.shape[1] for s, p in raw.items()}
        if len(set(dims.values())) > 1:
            raise BoundaryError("all sides must have points of the same dimension, got "
                                + ", ".join(f"{s} {d}D" for s, d in dims.items()))
        for s, p in raw.items():
            if len(p) < 2:
                raise BoundaryError(f"the {s} side needs at least 2 points, got {len(p)}")
        side = {s: _to3d(p) for s, p in raw.items()}
        size = _bbox_diagonal(np.concatenate(list(side.values())))
        tol = max(CORNER_TOL * size, _TINY)

        def gaps(sd: dict[str, np.ndarray]) -> dict[str, float]:
            return {c: float(np.linalg.norm(sd[s1][i1] - sd[s2][i2]))
                    for c, ((s1, i1), (s2, i2)) in CORNERS.items()}

        gap = gaps(side)
        d = dims["bottom"]
        open_ = [c for c, g in gap.items() if g > tol]
        if open_:
            c = open_[0]
            (s1, i1), (s2, i2) = CORNERS[c]
            msg = (f"the {c} corner does not meet: {s1}[{i1}] = {_fmt(side[s1][i1][:d])} but "
                   f"{s2}[{i2}] = {_fmt(side[s2][i2][:d])}, {gap[c]:.6g} apart "
                   f"({100 * gap[c] / size:.3g}% of the piece's size {size:.6g})")
            if len(open_) > 1:
                msg += "; also open: " + ", ".join(open_[1:])
            for s in SIDES:   # would reversing one side close every corner?
                if max(gaps({**side, s: side[s][::-1]}).values()) <= tol:
                    direction = "left to right" if s in ("bottom", "top") else "bottom to top"
                    msg += f". The {s} side seems reversed: it must run {direction}"
                    break
            else:
                msg += (". Bottom and top must run left to right, left and right bottom to top, "
                        "sharing the four corners")
            raise BoundaryError(msg)
        side = {s: p.copy() for s, p in side.items()}
        for (s1, i1), (s2, i2) in CORNERS.values():
            side[s2][i2] = side[s1][i1]

        for s, p in side.items():
            length = _arc_length(p)[-1]
            if length <= LENGTH_TOL * size:
                raise BoundaryError(f"the {s} side has zero length ({len(p)} points, total "
                                    f"length {length:.3g}, piece size {size:.3g})")
        b = cls(side["bottom"], side["right"], side["top"], side["left"], dim=d, name=name)
        b._check_simple(tol)
        return b

    @classmethod
    def from_outline(cls, points: Any, corners: Any, *, name: str | None = None,
                     sampled: bool = False) -> Boundary:
        """Build a boundary from a closed outline and four corner indices.

        Parameters
        ----------
        points : array_like
            ``(N, 2)`` or ``(N, 3)`` points of the closed outline, the first
            point not repeated (a last point equal to the first is dropped).
        corners : sequence of 4 int
            Indices into ``points`` of the bottom-left, bottom-right, top-right
            and top-left corners, in the outline's order: going forward from
            ``corners[0]`` (wrapping around the end) one meets ``corners[1]``,
            ``corners[2]``, ``corners[3]``. The bottom side is
            ``corners[0] -> corners[1]``, the right ``corners[1] -> corners[2]``,
            the top ``corners[2] -> corners[3]`` and the left
            ``corners[3] -> corners[0]``; top and left are reversed to run left
            to right and bottom to top. A counter-clockwise outline gives
            :attr:`orientation` ``+1``, a clockwise one ``-1``.
        name : str, optional
            Name of the piece.
        sampled : bool
            The outline is points sampled along a curve (a pattern piece's), not
            nodes (a region file's own): :attr:`sampled`.

        Raises
        ------
        BoundaryError
            Invalid points, corners that are not 4 distinct in-range integer
            indices in cyclic order, or any error of :meth:`from_sides`.
        """
        pts = outline_points(points)
        n = len(pts)
        if n < 4:
            raise BoundaryError(f"the outline needs at least 4 points (one per corner), got {n}")
        if isinstance(corners, (str, bytes)) or not hasattr(corners, "__len__") \
                or len(corners) != 4:
            raise BoundaryError("corners must be 4 indices into the outline (bottom-left, "
                                f"bottom-right, top-right, top-left), got {corners!r}")
        for c in corners:
            if isinstance(c, (bool, np.bool_)) or not isinstance(c, (int, np.integer)):
                raise BoundaryError(f"corners must be integer indices into the outline, got {c!r} "
                                    f"in {list(corners)!r}")
        c = [int(x) for x in corners]
        if any(not 0 <= x < n for x in c):
            raise BoundaryError(f"corner indices must be in 0..{n - 1} (the outline has {n} "
                                f"points), got {c}")
        if len(set(c)) != 4:
            raise BoundaryError(f"the 4 corner indices must be distinct, got {c}")
        offsets = [(x - c[0]) % n for x in c]
        if not offsets[1] < offsets[2] < offsets[3]:
            raise BoundaryError(f"corners {c} are not in the outline's order: going forward from "
                                f"corners[0] = {c[0]} one must meet corners[1], corners[2] and "
                                "corners[3] in that order (bottom-left, bottom-right, top-right, "
                                "top-left)")

        def run(i: int, j: int) -> np.ndarray:
            return pts[np.arange(i, i + (j - i) % n + 1) % n]

        b = cls.from_sides(run(c[0], c[1]), run(c[1], c[2]), run(c[2], c[3])[::-1],
                           run(c[3], c[0])[::-1], name=name)
        return replace(b, sampled=True) if sampled else b

    # ------------------------------------------------------------- geometry
    @property
    def shape(self) -> tuple[int, int]:
        """``(nu, nv)``: points on the bottom and on the left side.

        Raises
        ------
        BoundaryError
            If the top has not as many points as the bottom, or the right not
            as many as the left.
        """
        nb, nr, nt, nl = (len(p) for p in (self.bottom, self.right, self.top, self.left))
        if nb != nt or nl != nr:
            raise BoundaryError(
                f"opposite sides have different numbers of points: bottom {nb} and top {nt}, "
                f"left {nl} and right {nr}; request the number of nodes to resample the sides, "
                f"e.g. --nodes {max(nb, nt)}x{max(nl, nr)} (Boundary.resampled(nu, nv))")
        return nb, nl

    @property
    def size(self) -> float:
        """Bounding-box diagonal of all points (> 0 for a valid boundary)."""
        return _bbox_diagonal(self.outline())

    @property
    def side_lengths(self) -> tuple[float, float, float, float]:
        """Arc lengths of the bottom, right, top and left sides."""
        sides = (self.bottom, self.right, self.top, self.left)
        b, r, t, l = (float(_arc_length(p)[-1]) for p in sides)
        return b, r, t, l

    def outline(self) -> np.ndarray:
        """The closed outline without repetition, ``(N, 3)``.

        bottom, right, top reversed, left reversed, each without its last point:
        counter-clockwise for a counter-clockwise piece.
        """
        return np.concatenate([self.bottom[:-1], self.right[:-1],
                               self.top[::-1][:-1], self.left[::-1][:-1]])

    def _plane(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """``(origin, axes, normal, planar)`` of the best-fit plane.

        ``axes`` is ``(2, 3)``: two orthonormal in-plane directions forming a
        right-handed frame with ``normal``; for 2D input the plane is the
        xy-plane with normal ``+z``. For 3D the normal's sign is fixed by its
        first non-zero component among z, y, x being positive, so a 3D piece
        in the xy-plane gets the same orientation as its 2D version.
        """
        p = self.outline()
        if self.dim == 2:
            return np.zeros(3), np.eye(3)[:2], np.array([0.0, 0.0, 1.0]), True
        origin, normal, dist = best_fit_plane(p)
        for k in (2, 1, 0):
            if abs(normal[k]) > 1e-9:
                normal = normal if normal[k] > 0 else -normal
                break
        return origin, plane_axes(normal), normal, dist <= PLANAR_TOL * _bbox_diagonal(p)

    @property
    def orientation(self) -> float:
        """``+1.0`` if the outline is counter-clockwise in its best-fit plane, else ``-1.0``.

        The plane is the xy-plane for 2D pieces; for 3D pieces its reference
        normal has a positive z (or, if it lies in a vertical plane, positive y,
        then x) component.
        """
        origin, _, normal, _ = self._plane()
        p = self.outline() - origin
        area = 0.5 * cross(p, roll(p, -1)).sum(axis=0)
        return -1.0 if float(area @ normal) < 0 else 1.0

    @property
    def planar(self) -> bool:
        """True if the piece lies in a plane (to ``PLANAR_TOL`` of its size); always for 2D."""
        return self._plane()[3]

    @property
    def normal(self) -> np.ndarray:
        """``(3,)`` unit normal of the best-fit plane; the outline is counter-clockwise about it."""
        return self._plane()[2] * self.orientation

    def _check_simple(self, tol: float) -> None:
        """Raise BoundaryError if the (planar) outline crosses or touches itself."""
        origin, axes, _, planar = self._plane()
        if not planar:
            return
        p3 = self.outline()
        p = (p3 - origin) @ axes.T
        # drop (near-)duplicate consecutive points: zero-length segments
        keep = np.flatnonzero(np.linalg.norm(p - roll(p, 1), axis=1) > tol)
        if len(keep) < 2:
            return
        found = _find_self_intersection(p[keep], tol)
        if found is None:
            return
        k, m, where = found
        n = len(p)
        # a kept segment ends at keep[k+1]; the non-degenerate original one is just before it
        seg = [int((keep[(x + 1) % len(keep)] - 1) % n) for x in (k, m)]
        place = _fmt((origin + where @ axes)[:self.dim])
        if k == m:
            raise BoundaryError(f"the outline folds back onto itself at the end of "
                                f"{self._segment_name(seg[0])}, near {place}")
        raise BoundaryError(f"the outline crosses or touches itself: {self._segment_name(seg[0])} "
                            f"meets {self._segment_name(seg[1])} near {place}")

    def _segment_name(self, k: int) -> str:
        """Describe segment ``k`` of :meth:`outline` (from point ``k`` to ``k+1``)."""
        for s in SIDES:
            m = len(getattr(self, s)) - 1
            if k < m:
                i = k if s in ("bottom", "right") else m - 1 - k
                return f"{s} segment {i} ({s}[{i}] to {s}[{i + 1}])"
            k -= m
        raise IndexError(k)

    # ------------------------------------------------------------ derived
    def resampled(self, nu: int, nv: int) -> Boundary:
        """The boundary with ``nu`` points on bottom and top, ``nv`` on left and right.

        Sides with a different count are resampled uniformly by arc length
        (:func:`resample_polyline`), keeping the corners exactly and, as nodes,
        the vertices where a side turns by :data:`SHARP_TURN_DEG` or more (a
        dart's tip and mouth; the side is spaced uniformly between them);
        sides that already have the requested count are kept as they are, unless
        the boundary is :attr:`sampled` from an outline (then its points are no
        nodes: a sleeve cap drawn as 41 vertices 4.5 to 45 mm apart, gridded with
        41 nodes on that side, kept them, an edge spread of 10).

        Raises
        ------
        InputError
            If ``nu`` or ``nv`` is not an integer >= 2.
        """
        nu, nv = _check_count(nu, "nu"), _check_count(nv, "nv")
        want = {"bottom": nu, "top": nu, "left": nv, "right": nv}
        new = {s: (getattr(self, s) if len(getattr(self, s)) == n and not self.sampled
                   else resample_polyline(getattr(self, s), n, sharp_vertices(getattr(self, s))))
               for s, n in want.items()}
        return Boundary(new["bottom"], new["right"], new["top"], new["left"], dim=self.dim, name=self.name)

    def __repr__(self) -> str:
        counts = " ".join(f"{s}={len(getattr(self, s))}" for s in SIDES)
        name = f"{self.name!r}, " if self.name else ""
        return f"Boundary({name}{self.dim}D, {counts}, size={self.size:.6g})"
