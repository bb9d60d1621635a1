"""Choosing the four grid corners of a pattern piece.

A structured grid needs four sides, but a piece may have any number of
natural corners. :func:`choose_corners` decides, in this order:

1. **Given corners**: four indices into the outline, or four points (the
   outline point nearest to each is used), bottom-left, bottom-right,
   top-right, top-left in the outline's counter-clockwise order.
2. **The file's turn points** (AAMA/ASTM layer 2, GarmentCode panel vertices):
   exactly four are used as they are; more than four are scored as below.
3. **Corner candidates**: the source's vertices where the outline turns by at
   least ``min_turn`` degrees (20 by default).

With more than four candidates every choice of four (of the 16 best) is scored
by ``sum(q) + balance``: ``q = 1 - |turn - 90°| / 90°`` (clipped to ``[0, 1]``)
rewards right-angled convex corners (1) over flat points, needle tips and
concave corners (0), and ``balance = (min/max of bottom and top lengths) x
(min/max of left and right lengths)`` in ``(0, 1]`` rewards opposite sides of
similar length, which gives well-shaped cells. With fewer than four, the
longest side (by arc length) is split at its middle until there are four; a
smooth outline without any candidate (a circle) starts at the point nearest
the bottom-left of its bounding box and is cut into four sides of equal
length. A new corner falls on an existing outline point of that side when one
lies within 2% of the side's length of the middle (so it is exactly on the
curve), else a point is inserted on the outline there.

Which automatic corner is the bottom-left: the one that makes the bottom side
run most nearly across the grain line (left and right along it), or, without
a grain line, most nearly along +x.
"""

from __future__ import annotations

import bisect
import itertools
import math
from dataclasses import dataclass, replace
from typing import Any, Sequence

import numpy as np

from ..errors import InputError
from ..geometry import reflect, roll, turn_angles
from .piece import Piece

__all__ = ["CornerCandidate", "CornerChoice", "turn_angles", "corner_candidates",
           "choose_corners", "MIN_TURN_DEG", "windowed_turn", "rounded_corners", "dart_mouths"]

#: smallest turn (degrees) that makes a vertex a corner candidate
MIN_TURN_DEG = 20.0
MAX_SCORED = 16
_SNAP = 0.02
_NAMES = ("bottom-left", "bottom-right", "top-right", "top-left")


@dataclass(frozen=True)
class CornerCandidate:
    """A possible grid corner: outline ``index``, ``point`` (mm), ``turn`` (degrees, + convex)."""

    index: int
    point: tuple[float, float]
    turn: float
    turn_point: bool
    score: float

    def as_dict(self) -> dict[str, Any]:
        return {"index": self.index, "point": list(self.point), "turn": self.turn,
                "turn_point": self.turn_point, "score": self.score}


@dataclass(frozen=True, eq=False)
class CornerChoice:
    """The four corners chosen for a piece.

    Attributes
    ----------
    outline : numpy.ndarray
        ``(N, 2)`` outline the indices refer to: the piece's, or it with the
        inserted corner points.
    corners : tuple of 4 int
        Bottom-left, bottom-right, top-right, top-left indices into ``outline``.
    method : str
        ``"given"``, ``"near"``, ``"turn-points"``, ``"scored"``, ``"split"`` or
        ``"equal-sides"``.
    message : str
        One sentence saying what was chosen and why.
    candidates : int
        How many candidates there were.
    inserted : tuple of int
        Indices (into ``outline``) of points added to the piece's outline.
    alternatives : tuple of CornerChoice
        Automatic choices (``"scored"``) only: the next best corner sets by
        their coarse grids, best first (at most :data:`ALTERNATIVES`), to try
        where the chosen set's grid misses the angle target
        (:func:`clothgrid.pipeline.runners_up`).
    darts : int
        Automatic choices: the darts found in the outline (:func:`dart_mouths`).
    """

    outline: np.ndarray
    corners: tuple[int, int, int, int]
    method: str
    message: str
    candidates: int = 0
    inserted: tuple[int, ...] = ()
    alternatives: tuple["CornerChoice", ...] = ()
    darts: int = 0

    def runner_up(self, k: int, why: str) -> "CornerChoice":
        """Alternative ``k``, its message saying why it was taken (``why``: what the first choice's
        grid missed, one phrase)."""
        alt = self.alternatives[k]
        named = _corners_named(alt.corners)             # what the message ends with
        return replace(alt, message=f"{alt.message.removesuffix(named)}; the first choice "
                                    f"{_fmt_idx(self.corners)}: {why}, so took runner-up {k + 2} by its "
                                    f"coarse grid{named}")

    @property
    def points(self) -> np.ndarray:
        """``(4, 2)`` corner points (mm)."""
        return self.outline[list(self.corners)]

    def as_dict(self) -> dict[str, Any]:
        return {"indices": list(self.corners), "points": self.points.tolist(),
                "method": self.method, "message": self.message,
                "candidates": self.candidates, "inserted": list(self.inserted),
                "alternatives": [list(c.corners) for c in self.alternatives]}


def _quality(turn: np.ndarray) -> np.ndarray:
    return np.clip(1.0 - np.abs(turn - math.pi / 2) / (math.pi / 2), 0.0, 1.0)


def corner_candidates(piece: Piece, min_turn: float = MIN_TURN_DEG) -> list[CornerCandidate]:
    """The piece's corner candidates, in outline order.

    The file's turn points, the source vertices that turn by at least
    ``min_turn`` degrees either way, and the middles of rounded corners
    (:func:`rounded_corners`; their ``turn`` is the windowed turn).
    """
    return _candidates(piece, min_turn)[0]


def _candidates(piece: Piece, min_turn: float) -> tuple[list[CornerCandidate], np.ndarray, np.ndarray]:
    """:func:`corner_candidates`, the outline's turns and its windowed turns (computed once)."""
    turn = _candidate_turns(piece)
    turns = turn
    tp = set(int(i) for i in piece.turn_points)
    v = np.asarray(piece.vertices, dtype=np.int64)
    sharp = set(int(i) for i in v[np.abs(turn[v]) >= math.radians(min_turn)]) if v.size else set()
    window = round_window(piece.outline)
    wt = windowed_turn(piece.outline, window)
    rounded = set(rounded_corners(piece.outline, sorted(tp | sharp), window, wt=wt))
    turn = turn.copy()
    if rounded:
        idx = np.array(sorted(rounded))
        turn[idx] = wt[idx]
    q = _quality(turn)
    return ([CornerCandidate(i, (float(piece.outline[i, 0]), float(piece.outline[i, 1])),
                             float(math.degrees(turn[i])), i in tp, float(q[i]))
             for i in sorted(tp | sharp | rounded)], turns, wt)


def _candidate_turns(piece: Piece) -> np.ndarray:
    return turn_angles(piece.outline)


def _arc(outline: np.ndarray) -> tuple[np.ndarray, float]:
    """Arc length at each outline point from the first, and the perimeter."""
    d = roll(outline, -1) - outline
    seg = np.hypot(d[:, 0], d[:, 1])
    s = np.empty_like(seg)
    s[0] = 0.0
    np.cumsum(seg[:-1], out=s[1:])
    return s, float(seg.sum())


#: Arc-length window (fraction of the perimeter, at most :data:`ROUND_WINDOW_MM`) over
#: which :func:`windowed_turn` measures how much the outline turns.
ROUND_WINDOW = 0.06
ROUND_WINDOW_MM = 60.0
#: Smallest windowed turn (degrees) that makes a rounded corner a candidate.
ROUND_MIN_TURN_DEG = 60.0
#: A dart tip turns (concave) by at least this much (degrees): a V opening of 70° or less.
DART_TIP_TURN_DEG = 110.0


def round_window(outline: np.ndarray) -> float:
    """The arc-length window (mm) of :func:`windowed_turn` for a piece.

    :data:`ROUND_WINDOW` of the perimeter, at most :data:`ROUND_WINDOW_MM`
    and at most half the piece's mean width (twice its area over its
    perimeter), so that a narrow band's rounded ends are not one U-turn.
    """
    from ..geometry import signed_area

    _, perimeter = _arc(outline)
    width = 2.0 * abs(signed_area(outline)) / perimeter if perimeter > 0 else 0.0
    return max(min(ROUND_WINDOW * perimeter, ROUND_WINDOW_MM, 0.5 * width), 1e-9)


def windowed_turn(outline: np.ndarray, window: float) -> np.ndarray:
    """Signed turn (radians, + convex) at every outline point over an arc-length window.

    The turn from the chord arriving from the point half a window back to the
    chord leaving to the point half a window ahead: a corner rounded with a
    radius well under the window turns about as much as a sharp one, while a
    point on a gently curved side turns little.
    """
    p = np.asarray(outline, dtype=np.float64)
    s, perimeter = _arc(p)
    if perimeter <= 0 or len(p) < 3:
        return np.zeros(len(p))
    half = min(0.5 * window, perimeter / 6)
    ext_s = np.concatenate([s - perimeter, s, s + perimeter])
    ext = np.vstack([p, p, p])
    back = np.column_stack([np.interp(s - half, ext_s, ext[:, k]) for k in range(2)])
    ahead = np.column_stack([np.interp(s + half, ext_s, ext[:, k]) for k in range(2)])
    d_in, d_out = p - back, ahead - p
    cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
    return np.arctan2(cross, (d_in * d_out).sum(axis=1))


def rounded_corners(outline: np.ndarray, taken: Sequence[int], window: float,
                    min_turn: float = ROUND_MIN_TURN_DEG, wt: np.ndarray | None = None) -> list[int]:
    """Outline points at the middle of rounded corners: a convex windowed turn of ``min_turn`` or more.

    Local maxima of :func:`windowed_turn` (``wt``, computed here unless given),
    at least a window apart from each other and from the points in ``taken``
    (the sharp candidates).
    """
    if wt is None:
        wt = windowed_turn(outline, window)
    s, perimeter = _arc(outline)
    order = np.argsort(-wt, kind="stable")
    found: list[int] = []
    near = sorted(float(s[i]) for i in taken)      # arc positions, sorted: the nearest two decide
    limit = math.radians(min_turn)
    for i in order:
        if wt[i] < limit:
            break
        x = float(s[i])
        if near:
            # the point nearest x along the closed outline is the one before or after it in
            # arc order (wrapping round): the same answer as looking at every point, in log time
            # (a noisy outline of 20,000 points has thousands of sharp candidates: 11 s that way)
            k = bisect.bisect_left(near, x)
            if any(min(abs(x - y), perimeter - abs(x - y)) < window for y in (near[k - 1], near[k % len(near)])):
                continue
        found.append(int(i))
        bisect.insort(near, x)
    return sorted(found)


def dart_mouths(outline: np.ndarray, cands: Sequence[int], turn: np.ndarray,
                wturn: np.ndarray | None = None) -> list[tuple[int, int, int]]:
    """The darts of an outline: ``(mouth, tip, mouth)`` outline indices in outline order.

    A dart tip is a candidate that turns concave by :data:`DART_TIP_TURN_DEG`
    or more, at the point or over a window (``wturn``, :func:`windowed_turn`:
    a tip drawn rounded, or where curved legs meet); its mouths are the nearest convex candidates before and after it,
    when the two legs are of similar length (within a factor 2) and the mouth
    is narrower than the shorter leg. A dart's mouths are where the dart meets
    the seam line, not corners a pattern maker would choose.
    """
    cs = sorted(int(i) for i in cands)
    if len(cs) < 3:
        return []
    s, perimeter = _arc(outline)
    darts = []
    for k, tip in enumerate(cs):
        deepest = turn[tip] if wturn is None else min(turn[tip], wturn[tip])
        if deepest > -math.radians(DART_TIP_TURN_DEG):
            continue
        a = next((cs[(k - j) % len(cs)] for j in range(1, len(cs)) if turn[cs[(k - j) % len(cs)]] > 0),
                 None)
        b = next((cs[(k + j) % len(cs)] for j in range(1, len(cs)) if turn[cs[(k + j) % len(cs)]] > 0),
                 None)
        if a is None or b is None or a == b:
            continue
        leg_a = (s[tip] - s[a]) % perimeter
        leg_b = (s[b] - s[tip]) % perimeter
        chord = float(np.hypot(*(outline[b] - outline[a])))
        if min(leg_a, leg_b) <= 0 or max(leg_a, leg_b) > 2 * min(leg_a, leg_b):
            continue
        if chord >= min(leg_a, leg_b):
            continue
        darts.append((a, tip, b))
    return darts


def _closed_arc(outline: np.ndarray, darts: Sequence[tuple[int, int, int]]
                ) -> tuple[np.ndarray, float]:
    """Arc length along the outline with every dart closed (its legs count as its mouth's width)."""
    n = len(outline)
    d = np.diff(np.vstack([outline, outline[:1]]), axis=0)
    seg = np.hypot(d[:, 0], d[:, 1])
    for a, _, b in darts:
        span = np.arange(a, a + ((b - a) % n)) % n
        if span.size:
            seg[span] = float(np.hypot(*(outline[b] - outline[a]))) / span.size
    return np.concatenate([[0.0], np.cumsum(seg)[:-1]]), float(seg.sum())


def mirror_partners(outline: np.ndarray, idx: Sequence[int], fold: Any, tol: float) -> dict[int, int]:
    """For a piece symmetric about the line ``fold`` (two points; an unfolded piece): each index of
    ``idx`` whose mirror image is within ``tol`` of another index of ``idx`` (or itself, on the line),
    mapped to it."""
    a, b = (np.asarray(p, dtype=np.float64)[:2] for p in (fold[0], fold[-1]))
    pts = outline[np.asarray(idx, dtype=np.int64)]
    img = reflect(pts, a, b)
    dist = np.linalg.norm(img[:, None, :] - pts[None, :, :], axis=2)
    k = dist.argmin(axis=1)
    return {int(idx[i]): int(idx[k[i]]) for i in range(len(idx)) if dist[i, k[i]] <= tol}


def _best_four(idx: list[int], q: np.ndarray, s: np.ndarray, perimeter: float,
               outline: np.ndarray | None = None, partners: dict[int, int] | None = None) -> list[list[int]]:
    """Sets of 4 of ``idx`` (outline order), best score first; ``q``, ``s`` per outline point.

    Without ``outline``, the best set alone. With it, the :data:`GRID_RANKED`
    best by the quick score, ranked again by the quality of a coarse grid
    (:func:`grid_score`; sets whose coarse grid cannot be made left out).
    With ``partners`` (:func:`mirror_partners` of a symmetric piece), only the sets that are their
    own mirror image, where there are any.
    """
    idx = sorted(idx)
    if len(idx) > MAX_SCORED:
        keep = sorted(idx, key=lambda i: -q[i])[:MAX_SCORED]
        idx = sorted(keep)
    cand = np.asarray(idx)
    combos = np.array(list(itertools.combinations(range(len(cand)), 4)))
    c = cand[combos]
    if partners:
        image = np.vectorize(lambda i: partners.get(int(i), -1), otypes=[np.int64])(c)
        symmetric = np.array([set(x) == set(y) for x, y in zip(c.tolist(), image.tolist())], dtype=bool)
        if symmetric.any():
            c = c[symmetric]
    pos = s[c]
    sides = np.column_stack([pos[:, 1] - pos[:, 0], pos[:, 2] - pos[:, 1], pos[:, 3] - pos[:, 2],
                             perimeter - (pos[:, 3] - pos[:, 0])])
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.minimum(sides[:, 0], sides[:, 2]) / np.maximum(sides[:, 0], sides[:, 2])
        r2 = np.minimum(sides[:, 1], sides[:, 3]) / np.maximum(sides[:, 1], sides[:, 3])
    balance = np.nan_to_num(r1 * r2)
    score = q[c].sum(axis=1) + balance
    if outline is None or len(c) == 1:
        return [[int(x) for x in c[int(np.argmax(score))]]]
    top = np.argsort(-score, kind="stable")[:GRID_RANKED]
    return _rank_by_grid(outline, [list(c[k]) for k in top], q)



#: Corner sets scored by a coarse grid (the best by the quick score go on to it).
GRID_RANKED = 10
#: Runners-up an automatic choice keeps (:attr:`CornerChoice.alternatives`).
ALTERNATIVES = 3
#: Cells of the coarse grid that scores a corner set.
COARSE_CELLS = 150


def _side_points(outline: np.ndarray, a: int, b: int) -> np.ndarray:
    """Outline points from index ``a`` to ``b`` (forward, wrapping), both ends included."""
    n = len(outline)
    if b <= a:
        b += n
    return outline[np.arange(a, b + 1) % n]


def _sides_grid(sides: Sequence[Any], nu: int, nv: int) -> np.ndarray:
    """A ``(nu, nv, 3)`` transfinite grid (eq. 4) of four sides (outline order, point arrays or
    :class:`~clothgrid.boundary.ArcSampler`), sampled by arc length."""
    from ..boundary import ArcSampler
    from ..initial import transfinite

    sm = [sd if isinstance(sd, ArcSampler) else ArcSampler(sd) for sd in sides]   # the piece's points: checked
    r = np.zeros((nu, nv, 3))
    r[:, 0], r[-1, :] = sm[0].sample(nu), sm[1].sample(nv)
    r[:, -1], r[0, :] = sm[2].sample(nu)[::-1], sm[3].sample(nv)[::-1]
    return transfinite(r)


def coarse_grid(outline: np.ndarray, corners: Sequence[int], cells: int = COARSE_CELLS
                ) -> np.ndarray:
    """A coarse fold-free ``(nu, nv, 3)`` grid of ``outline`` with these 4 corners (outline order).

    Sides sampled uniformly by arc length, about ``cells`` cells of about
    equal size, the interior by transfinite interpolation (eq. 4), then
    relaxed by :func:`clothgrid.foldfree.relax` over the whole grid.
    """
    from ..boundary import ArcSampler
    from ..foldfree import relax
    from ..geometry import signed_area
    from ..quality import line_lengths

    c = list(corners)
    sides = [_side_points(outline, c[k], c[(k + 1) % 4]) for k in range(4)]
    area = abs(signed_area(outline))
    if area > 0:
        h = math.sqrt(area / cells)
    else:
        h = max(float(np.hypot(*np.diff(sd, axis=0).T).sum()) for sd in sides) / 8
    sm = [ArcSampler(sd) for sd in sides]
    # node counts on the typical u- and v-line (as for the full grid: nodes_for_edge_length)
    lu, lv = line_lengths(_sides_grid(sm, 33, 33))
    nu = int(min(64, max(3, round(lu / h) + 1)))
    nv = int(min(64, max(3, round(lv / h) + 1)))
    r = _sides_grid(sm, nu, nv)
    out, _ = relax(r, dim=2, whole=True, quick=True)
    return out


def grid_score(points: np.ndarray) -> float:
    """Higher is better: folds first, then the smallest and mean corner sines, then the edge spread.

    The four grid-corner cells count for folds (a corner on a concave point
    folds its cell) but not for the angles (their angle is the outline's).
    """
    from ..foldfree_kernels import cell_min_sine
    from ..quality import edge_spread

    X = np.ascontiguousarray(points[..., :2])
    s = cell_min_sine(X)
    mask = np.ones(s.shape, bool)
    mask[0, 0] = mask[-1, 0] = mask[0, -1] = mask[-1, -1] = False
    if not mask.any():
        mask[:] = True
    sv = s[mask]
    folded = float(np.mean(s <= 0))       # a corner cell folds where its corner is concave
    if folded > 0:
        return -10.0 - folded
    spread = edge_spread(points)
    return float(2.0 * sv.min() + sv.mean() - 0.25 * math.log10(spread))


def _rank_by_grid(outline: np.ndarray, combos: list[list[int]], q: np.ndarray) -> list[list[int]]:
    """The corner sets of ``combos``, best coarse grid first (corner quality ``q`` breaks near-ties;
    ties keep ``combos``' order); ``combos[:1]`` where no coarse grid can be made."""
    scored = []
    for k, c in enumerate(combos):
        try:
            score = grid_score(coarse_grid(outline, c)) + 0.25 * float(np.mean(q[c]))
        except (InputError, ValueError, FloatingPointError):
            continue
        scored.append((-score, k))
    scored.sort()
    return [[int(i) for i in combos[k]] for _, k in scored] or [[int(i) for i in combos[0]]]


#: A side is split (:func:`_split`) within this central fraction of its length ...
SPLIT_BAND = 0.5
#: ... unless it turns (windowed) by this much (degrees) somewhere at least a
#: window (:func:`round_window`) from both ends: a corner rounded off more
#: gently than :data:`ROUND_MIN_TURN_DEG`.
SPLIT_PEAK_DEG = 30.0


def _convex_middle(s: np.ndarray, perimeter: float, wt: np.ndarray,
                   sides: Sequence[tuple[float, float]], window: float) -> float:
    """Arc position of a new corner on one of ``sides`` (``(start, length)`` pairs, longest first).

    The longest side with a rounded corner (a windowed turn ``wt`` of
    :data:`SPLIT_PEAK_DEG` or more away from its ends) gets the new corner
    where it turns most. Otherwise the longest side that is convex somewhere
    in its central :data:`SPLIT_BAND` gets it at the point there that turns
    most (within 2°), nearest the middle: the corner cell's angle is the
    outline's, so a corner on a concave stretch would make a folded cell.
    The middle of the longest side is the last resort (as on a straight side,
    every point of which turns alike).
    """
    def rel_of(a: float, length: float) -> np.ndarray:
        return ((s - a) % perimeter) / length

    for a, length in sides:
        rel = rel_of(a, length)
        margin = min(window / length, 0.25)
        inner = np.flatnonzero((rel >= margin) & (rel <= 1 - margin))
        if inner.size and wt[inner].max() >= math.radians(SPLIT_PEAK_DEG):
            return float(s[inner[np.argmax(wt[inner])]])
    for a, length in sides:
        rel = rel_of(a, length)
        band = np.flatnonzero(np.abs(rel - 0.5) <= 0.5 * SPLIT_BAND)
        if band.size == 0:
            continue
        best = float(wt[band].max())
        if best < -math.radians(1.0):
            continue
        good = band[wt[band] >= best - math.radians(2.0)]
        i = int(good[np.argmin(np.abs(rel[good] - 0.5))])
        return float(s[i])
    a, length = sides[0]
    return (a + 0.5 * length) % perimeter


def _split(outline: np.ndarray, corners: list[int]) -> tuple[np.ndarray, list[int], list[int]]:
    """Add corners near the middle of the longest sides, at convex points, until there are four.

    Returns the (possibly extended) outline, the 4 corner indices in outline
    order, and the indices of inserted points.
    """
    s, perimeter = _arc(outline)
    n = len(outline)
    window = round_window(outline)
    wt = windowed_turn(outline, window)
    pos = sorted(float(s[i]) for i in corners)       # arc-length positions
    while len(pos) < 4:
        if len(pos) == 1:
            sides = [(pos[0], perimeter)]
        else:
            lens = [(pos[(k + 1) % len(pos)] - pos[k]) % perimeter or perimeter
                    for k in range(len(pos))]
            sides = sorted(((pos[k], lens[k]) for k in range(len(pos))), key=lambda t: -t[1])
        pos.append(_convex_middle(s, perimeter, wt, sides, window))
        pos.sort()
    # materialise: existing point near the target (within 2% of that side), else insert
    original = {float(s[i]): i for i in corners}
    chosen: list[tuple[float, int | None]] = []      # (position, existing index or None)
    for k, x in enumerate(pos):
        if x in original:
            chosen.append((x, original[x]))
            continue
        prev, nxt = pos[k - 1], pos[(k + 1) % 4]
        side = ((nxt - prev) % perimeter) or perimeter
        rel = (s - x + perimeter / 2) % perimeter - perimeter / 2
        lo_ok = ((s - prev) % perimeter > 0) & ((nxt - s) % perimeter > 0)
        near = np.flatnonzero(lo_ok & (np.abs(rel) <= _SNAP * side))
        if near.size:
            chosen.append((x, int(near[np.argmin(np.abs(rel[near]))])))
        else:
            chosen.append((x, None))
    inserts = sorted((x, int(np.searchsorted(s, x, side="right") - 1))
                     for x, i in chosen if i is None)
    if not inserts:
        return outline, sorted(i for _, i in chosen), []
    rows: list[np.ndarray] = []
    mapping = np.empty(n, dtype=np.int64)
    new_of: dict[float, int] = {}
    k = 0
    for j in range(n):
        mapping[j] = len(rows)
        rows.append(outline[j])
        while k < len(inserts) and inserts[k][1] == j:
            x = inserts[k][0]
            a, b = outline[j], outline[(j + 1) % n]
            seg = float(np.hypot(*(b - a)))
            f = 0.0 if seg == 0 else min(max((x - s[j]) / seg, 0.0), 1.0)
            new_of[x] = len(rows)
            rows.append(a + f * (b - a))
            k += 1
    out = np.asarray(rows)
    idx = [int(mapping[i]) if i is not None else new_of[x] for x, i in chosen]
    return out, sorted(idx), sorted(new_of.values())


def _rotate_to_grain(outline: np.ndarray, corners: list[int],
                     grain: np.ndarray | None) -> list[int]:
    """Order the 4 corners (outline order) so that corners[0] is the bottom-left."""
    up = np.array([0.0, 1.0])
    if grain is not None:
        g = np.asarray(grain, dtype=np.float64)
        d = g[1] - g[0]
        if np.hypot(*d) > 0:
            up = d / np.hypot(*d)
            if up[1] < 0 or (up[1] == 0 and up[0] < 0):
                up = -up
    right = np.array([up[1], -up[0]])
    p = outline[corners]
    best, best_k = -np.inf, 0
    for k in range(4):
        d = p[(k + 1) % 4] - p[k]
        norm = np.hypot(*d)
        val = float(d @ right / norm) if norm > 0 else -np.inf
        if val > best + 1e-12:
            best, best_k = val, k
    return corners[best_k:] + corners[:best_k]


def _fmt_idx(idx: Sequence[int]) -> str:
    return ", ".join(str(int(i)) for i in idx)


def choose_corners(piece: Piece, corners: Sequence[int] | None = None,
                   near: Any = None, *, min_turn: float = MIN_TURN_DEG) -> CornerChoice:
    """Choose the four grid corners of ``piece`` (see the module's description).

    Parameters
    ----------
    piece : Piece
        The piece.
    corners : sequence of 4 int, optional
        Outline indices of the bottom-left, bottom-right, top-right and top-left
        corners (counter-clockwise order).
    near : array_like, optional
        ``(4, 2)`` points (mm): the outline point nearest to each is a corner,
        in the same order as ``corners``.
    min_turn : float
        Smallest turn (degrees) for a vertex to be a corner candidate.

    Returns
    -------
    CornerChoice

    Raises
    ------
    InputError
        Both ``corners`` and ``near`` given, or not four of them.
    """
    outline = piece.outline
    n = len(outline)
    if corners is not None and near is not None:
        raise InputError("give the corners either as outline indices or as points, not both")
    if corners is not None:
        if isinstance(corners, (str, bytes)) or len(corners) != 4:
            raise InputError(f"corners must be 4 outline indices (bottom-left, bottom-right, "
                             f"top-right, top-left), got {corners!r}")
        idx = []
        for c in corners:
            if isinstance(c, (bool, np.bool_)) or not isinstance(c, (int, np.integer)):
                raise InputError(f"corner indices must be integers, got {c!r}")
            if not -n <= int(c) < n:
                raise InputError(f"corner index {int(c)} is out of range: piece {piece.name!r} "
                                 f"has {n} outline points (0..{n - 1})")
            idx.append(int(c) % n)
        return CornerChoice(outline, tuple(idx), "given",
                            f"corners given by outline index: {_fmt_idx(idx)}")
    if near is not None:
        try:
            pts = np.asarray(near, dtype=np.float64)
        except (TypeError, ValueError):
            pts = np.zeros((0,))
        if pts.shape != (4, 2) or not np.isfinite(pts).all():
            raise InputError(f"corner points must be 4 finite points (x, y) in mm, got {near!r}")
        d = np.linalg.norm(outline[None] - pts[:, None], axis=2)
        idx = [int(i) for i in d.argmin(axis=1)]
        far = d[np.arange(4), idx].max()
        return CornerChoice(outline, tuple(idx), "near",
                            f"corners nearest to the given points: outline indices "
                            f"{_fmt_idx(idx)} (farthest {far:.3g} mm from its point)")

    cands, turn, wt = _candidates(piece, min_turn)
    turn = turn.copy()
    for c in cands:                       # rounded corners count with their windowed turn
        turn[c.index] = math.radians(c.turn)
    q = _quality(turn)
    darts = dart_mouths(outline, [c.index for c in cands], turn, wt)
    mouths = sorted({a for a, _, _ in darts} | {b for _, _, b in darts})
    s, perimeter = _closed_arc(outline, darts)
    tps = [c.index for c in cands if c.turn_point]
    geo = [c.index for c in cands]
    inserted: list[int] = []
    pool = tps if len(tps) >= 4 else geo if len(geo) >= 4 else None
    from_tps = pool is tps
    notes: list[str] = []
    if pool is not None:
        # a grid corner on a concave point folds its cell: such points are left out where more than
        # four remain, and where fewer than four convex ones would remain (four candidates, one of
        # them concave: a real SVG's trouser fly kept a folded cell), corners are added to the
        # convex ones on the longest sides instead
        convex = [i for i in pool if turn[i] > 0]
        if len(convex) < len(pool) and (len(pool) > 4 or len(convex) < 4):
            notes.append(f"concave points {_fmt_idx(i for i in pool if turn[i] <= 0)} are not corners")
            if len(convex) < 4 and from_tps:          # too few of the file's turn points: the outline's own
                convex = [i for i in geo if turn[i] > 0]
                from_tps = False
            if len(convex) >= 4:
                pool = convex
            else:
                pool, geo = None, convex
    in_mouth = set(mouths)          # (a set: a noisy outline has thousands of candidates and mouths)
    if pool is not None and mouths and any(i in in_mouth for i in pool):
        rest = [i for i in pool if i not in in_mouth]
        if len(rest) >= 4:
            pool = rest
            notes.append(f"dart mouths {_fmt_idx(mouths)} are not corners "
                         f"({len(darts)} dart{'s' if len(darts) != 1 else ''})")
        else:
            q = q.copy()
            q[mouths] *= 0.25
    if pool is not None:
        kind = ("turn point" if from_tps else "corner candidate")
        what = f"{len(pool)} {kind}{'s' if len(pool) != 1 else ''}" + (
            "" if from_tps else f" (turns of {min_turn:g}° or more"
            + (f"; {len(tps)} turn points in the file)" if tps else ")"))
    dart_note = "".join("; " + n for n in notes)
    others: list[list[int]] = []
    scored = ""
    if pool is not None and len(pool) == 4:
        chosen = sorted(pool)
        method = "turn-points" if from_tps else "candidates"
        message = f"the {what} are the corners"
    elif pool is not None:
        fold = piece.meta.get("fold_line") if piece.meta.get("unfolded") else None
        partners = (mirror_partners(outline, pool, fold, max(1e-6 * piece.size, 4 * piece.tolerance))
                    if fold is not None else None)
        ranked = _best_four(pool, q, s, perimeter, outline, partners)
        paired = bool(partners) and all(partners.get(i) in ranked[0] for i in ranked[0])
        chosen, method, others = ranked[0], "scored", ranked[1:1 + ALTERNATIVES]
        scored = (f"chose 4 of {what} by score (right-angled convex corners, opposite "
                  f"sides of similar length{'; an unfolded piece: in mirror pairs' if paired else ''}); "
                  "left out outline indices ")
        message = scored + _fmt_idx(i for i in pool if i not in chosen)
    if pool is not None:
        message += dart_note
    else:
        base = sorted(set(geo))
        if not base:
            bl = outline.min(axis=0)
            base = [int(np.argmin(np.linalg.norm(outline - bl, axis=1)))]
            method = "equal-sides"
            message = ("no corner candidates (a smooth outline): four sides of equal length, "
                       "the first corner nearest the bottom-left of the bounding box")
        else:
            method = "split"
            extra = 4 - len(base)
            message = (f"only {len(base)} corner candidate{'s' if len(base) != 1 else ''} "
                       f"(turn points and turns of {min_turn:g}° or more): added {extra} "
                       f"corner{'s' if extra != 1 else ''} on the longest "
                       f"side{'s' if extra != 1 else ''}, where {'they turn' if extra != 1 else 'it turns'} "
                       f"most (a rounded corner) or at a convex point near the middle")
        outline, chosen, inserted = _split(outline, base)
        if inserted:
            message += (f" (inserted outline point{'s' if len(inserted) > 1 else ''} "
                        f"{_fmt_idx(inserted)})")
        message += "".join("; " + n for n in notes)
    ordered = _rotate_to_grain(outline, sorted(chosen), piece.grain_line)
    message += _corners_named(ordered)
    alternatives = []
    for c in others:
        alt = _rotate_to_grain(outline, sorted(c), piece.grain_line)
        text = scored + _fmt_idx(i for i in pool if i not in c) + dart_note + _corners_named(alt)
        alternatives.append(CornerChoice(outline, tuple(alt), "scored", text, len(cands), darts=len(darts)))
    return CornerChoice(outline, tuple(ordered), method, message, len(cands), tuple(inserted),
                        tuple(alternatives), darts=len(darts))


def _corners_named(ordered: Sequence[int]) -> str:
    return ": " + ", ".join(f"{name} {i}" for name, i in zip(_NAMES, ordered))
