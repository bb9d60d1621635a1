"""Pieces cut on the fold (their fold line, and the whole piece unfolded across it) and pieces cut
in mirrored pairs (:func:`mirrored`).

A pattern draws a symmetric piece (a T-shirt's back, a skirt's front) as one half, cut with its
straight centre edge on the fold of the fabric. The cloth is the whole piece. Pattern files say so:

- AAMA/ASTM D6673 DXF: a ``LINE`` on layer ``6`` (the mirror line) along the piece's edge;
- FreeSewing SVG: the "cut on fold" mark, a path whose markers are ``cutonfoldFrom`` and
  ``cutonfoldTo``, whose two ends lie on the piece's edge.

The readers keep that line as ``Piece.meta["fold_line"]`` (``[[x0, y0], [x1, y1]]``, mm; see
:func:`attach_fold_lines`) and :func:`unfold` makes the whole piece: the outline and its mirror
image across the line, joined where the outline meets the line. The indices of the original
outline's vertices and turn points are carried over (and mirrored); a turn point at an end of the
fold edge stays a turn point only where the unfolded outline still turns there.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from ..errors import InputError
from ..geometry import reflect, turn_angles
from .piece import Piece, piece_from_polygon

__all__ = ["FOLD_TOL_REL", "FOLD_TOL_MM", "fold_edge", "unfold", "unfolded", "mirrored", "attach_fold_lines"]

#: How far (relative to the piece's size, and at least :data:`FOLD_TOL_MM`) an outline point may lie
#: from the fold line and still be on it.
FOLD_TOL_REL = 1e-4
FOLD_TOL_MM = 0.05

#: A turn point at an end of the fold edge stays one where the unfolded outline turns by at least this
#: (degrees): a square corner at the fold becomes a straight line; a V-neck's point stays a corner.
KEEP_TURN_DEG = 20.0


def _tolerance(piece: Piece) -> float:
    return max(FOLD_TOL_MM, FOLD_TOL_REL * piece.size, 2.0 * piece.tolerance)


def _line(fold: Any) -> tuple[np.ndarray, np.ndarray, float]:
    a, b = (np.asarray(p, dtype=np.float64)[:2] for p in (fold[0], fold[-1]))
    length = float(np.hypot(*(b - a)))
    if not (np.isfinite(a).all() and np.isfinite(b).all()) or not length > 0:
        raise InputError("the fold line has no length")
    return a, (b - a) / length, length


def _runs(on: np.ndarray) -> list[tuple[int, int]]:
    """Maximal cyclic runs ``(start, length)`` of True in ``on`` (one run of all if every one is)."""
    n = len(on)
    if on.all():
        return [(0, n)]
    if not on.any():
        return []
    shift = int(np.argmin(on))                       # a False: no run wraps past it
    r = np.roll(on, -shift).astype(np.int8)
    edges = np.diff(np.r_[0, r, 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int((a + shift) % n), int(b - a)) for a, b in zip(starts, ends)]


def fold_edge(piece: Piece, fold: Any | None = None) -> tuple[int, int]:
    """The part of ``piece``'s outline along its fold line: indices ``(first, last)`` of the outline
    points where it starts and ends (counter-clockwise, ``first`` to ``last``).

    Parameters
    ----------
    piece : Piece
    fold : array_like, optional
        The fold line's two end points (mm); by default ``piece.meta["fold_line"]``.

    Raises
    ------
    InputError
        No fold line, a fold line along no edge of the outline (two outline points on it,
        consecutive, spanning part of it), or an outline on both sides of it.
    """
    fold = piece.meta.get("fold_line") if fold is None else fold
    label = f"piece {piece.name!r}"
    if fold is None:
        raise InputError(f"{label}: no fold line (the file marks none)")
    try:
        a, d, length = _line(fold)
    except InputError as exc:
        raise InputError(f"{label}: {exc}") from None
    o = piece.outline
    tol = _tolerance(piece)
    rel = o - a
    off = rel[:, 0] * d[1] - rel[:, 1] * d[0]          # signed distance from the line
    along = rel @ d
    on = np.abs(off) <= tol
    best, overlap = None, 0.0
    for start, m in _runs(on):
        if m < 2 or m == len(o):
            continue
        t = along[(start + np.arange(m)) % len(o)]
        got = min(t.max(), length) - max(t.min(), 0.0)
        if got > overlap:
            best, overlap = (start, m), got
    if best is None or overlap < 0.5 * length:
        raise InputError(f"{label}: its fold line ({_pt(a)} to {_pt(a + d * length)}) runs along no "
                         "edge of its outline, so it cannot be unfolded")
    start, m = best
    run = (start + np.arange(m)) % len(o)
    rest = np.ones(len(o), bool)
    rest[run] = False
    side = off[rest & ~on]
    if (side > tol).any() and (side < -tol).any():
        raise InputError(f"{label}: its outline lies on both sides of its fold line, so it cannot be "
                         "unfolded")
    return int(run[0]), int(run[-1])


def _pt(p: np.ndarray) -> str:
    return f"({p[0]:.6g}, {p[1]:.6g})"


def unfold(piece: Piece, fold: Any | None = None) -> Piece:
    """The whole piece of a half cut on the fold: ``piece``'s outline and its mirror image across the
    fold line (:func:`fold_edge`), counter-clockwise, starting at the far end of the fold edge.

    The outline's vertices and turn points are carried over, and their mirror images added; the
    fold edge's inner points are dropped, and a turn point at either of its ends is kept where the
    unfolded outline turns there by :data:`KEEP_TURN_DEG` or more. The grain line is kept;
    ``meta["internal_lines"]`` gain their mirror images. ``meta["unfolded"]`` is True and a note says
    so.

    Raises
    ------
    InputError
        As :func:`fold_edge`.
    """
    first, last = fold_edge(piece, fold)
    fold = piece.meta.get("fold_line") if fold is None else fold
    a, d, _ = _line(fold)
    o = piece.outline
    n = len(o)
    # the half from the fold edge's last point round to its first, off the line between
    idx = (last + np.arange((first - last) % n + 1)) % n
    half = o[idx]
    # the end points on the line exactly (within the tolerance they were), so the two halves meet
    for k in (0, -1):
        rel = half[k] - a
        half[k] = a + d * (rel @ d)

    def mirror(p: np.ndarray) -> np.ndarray:
        return reflect(p, a, a + d)

    h = len(half)
    back = mirror(half[::-1])[1:-1]
    points = np.vstack([half, back])                 # half, then its image from the first point's side
    position = {int(i): k for k, i in enumerate(idx)}

    def carried(indices: np.ndarray, ends: bool) -> np.ndarray:
        out = []
        for i in indices:
            k = position.get(int(i))
            if k is None:
                continue
            if k in (0, h - 1):                      # an end of the fold edge: once, if it still turns
                if ends:
                    prev = back[-1] if k == 0 else half[k - 1]
                    nxt = half[1] if k == 0 else back[0] if len(back) else half[0]
                    if abs(np.degrees(turn_angles(np.array([prev, half[k], nxt]))[1])) >= KEEP_TURN_DEG:
                        out.append(k)
                else:
                    out.append(k)
                continue
            out.extend([k, h + (h - 2 - k)])          # itself and its image
        return np.unique(np.array(out, dtype=np.int64))

    meta = dict(piece.meta)
    meta["unfolded"] = True
    if meta.get("internal_lines"):
        meta["internal_lines"] = list(meta["internal_lines"]) + [
            [[float(x), float(y)] for x, y in mirror(np.asarray(line, dtype=np.float64))]
            for line in meta["internal_lines"]]
    whole = piece_from_polygon(piece.name, points, vertices=carried(piece.vertices, False),
                               turn_points=carried(piece.turn_points, True), grain_line=piece.grain_line,
                               units=piece.units, source=piece.source, tolerance=piece.tolerance,
                               notes=piece.notes + (
                                   f"unfolded across its fold line ({_pt(a)} to "
                                   f"{_pt(np.asarray(fold[-1], dtype=np.float64))} mm): the outline "
                                   "and its mirror image",),
                               meta=meta)
    return whole


def mirrored(piece: Piece, name: str | None = None) -> Piece:
    """The mirror image of ``piece`` (the second of a pair cut "2 mirrored": a left and a right
    sleeve), across the vertical line through the centre of its bounding box, counter-clockwise
    again and named ``name`` (default: the same name).

    Outline point ``k`` of ``piece`` is point ``(n - k) % n`` of its image (``n`` points), so the
    part of the outline from ``i`` to ``j`` (counter-clockwise) is the image's from ``(n - j) % n``
    to ``(n - i) % n``. Vertices, turn points, the grain line, the fold line and internal lines are
    mirrored with it; ``meta["mirror_of"]`` names the original.
    """
    c = 0.5 * (piece.outline[:, 0].min() + piece.outline[:, 0].max())

    def flip(points: Any) -> np.ndarray:
        q = np.array(points, dtype=np.float64, copy=True)
        q[..., 0] = 2.0 * c - q[..., 0]
        return q

    meta = dict(piece.meta)
    meta["mirror_of"] = piece.name
    if meta.get("fold_line") is not None:
        meta["fold_line"] = flip(meta["fold_line"]).tolist()
    if meta.get("internal_lines"):
        meta["internal_lines"] = [flip(line).tolist() for line in meta["internal_lines"]]
    grain = None if piece.grain_line is None else flip(piece.grain_line)
    out = piece_from_polygon(name or piece.name, flip(piece.outline), vertices=piece.vertices,
                             turn_points=piece.turn_points, grain_line=grain, units=piece.units,
                             source=piece.source, tolerance=piece.tolerance,
                             notes=piece.notes + (f"the mirror image of piece {piece.name!r}",), meta=meta)
    return out


def unfolded(pieces: Sequence[Piece]) -> list[Piece]:
    """``pieces`` with every piece that has a fold line unfolded (:func:`unfold`); the others as
    they are."""
    return [unfold(p) if p.meta.get("fold_line") is not None else p for p in pieces]


def attach_fold_lines(pieces: Sequence[Piece], lines: Sequence[Any]) -> list[Piece]:
    """``pieces`` with each fold line of ``lines`` (two end points each, mm) in the ``meta`` of the
    piece whose outline it runs along (:func:`fold_edge`), the first such piece; a line along
    no piece's edge is dropped."""
    out = list(pieces)
    boxes = [(p.outline.min(axis=0), p.outline.max(axis=0), _tolerance(p)) for p in out]
    for line in lines:
        ends = np.asarray([line[0], line[-1]], dtype=np.float64)[:, :2]
        for k, p in enumerate(out):
            lo, hi, tol = boxes[k]
            # (the line may run past the outline's ends: a sew line's fold edge is the cut line's less
            # the seam allowances at its ends; its box need only meet the piece's)
            if p.meta.get("fold_line") is not None or (ends.max(axis=0) < lo - tol).any() or (
                    ends.min(axis=0) > hi + tol).any():
                continue
            try:
                fold_edge(p, line)
            except InputError:
                continue
            out[k] = replace(p, meta={**p.meta, "fold_line": ends.tolist()})
            break
    return out
