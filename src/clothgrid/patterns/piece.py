"""A pattern piece read from a pattern file: :class:`Piece`; a reader's answer: :class:`Pieces`
(the good pieces, with the :class:`PieceFailure` of those that cannot be made and the
:class:`Skipped` outlines taken for annotations)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Sequence

import numpy as np

from ..errors import InputError, PiecesError
from ..geometry import roll, signed_area, spike_points, untie_loops
from ..limits import MAX_COORDINATE, MAX_OUTLINE_POINTS
from .sampling import DEFAULT_REL_TOL, Primitive, loop_extent, sample_loop

__all__ = ["Piece", "PieceFailure", "Skipped", "Pieces", "piece_failure", "pattern_pieces", "piece_from_primitives",
           "piece_from_polygon", "piece_from_points", "MIN_POINTS"]

#: the fewest distinct outline points of a piece (a triangle: a godet, a gusset)
MIN_POINTS = 3
#: Widest zero-width spike taken off an outline, relative to the piece's size (its bounding-box diagonal).
SPIKE_WIDTH = 1e-3


@dataclass(frozen=True, eq=False, repr=False)
class Piece:
    """One pattern piece: a closed outline in millimetres, with what the file says about it.

    Attributes
    ----------
    name : str
        The piece's name (SVG label or id, AAMA ``Piece Name``, GarmentCode panel
        name, else ``piece1``, ``piece2``, ...).
    outline : numpy.ndarray
        ``(N, 2)`` float64 points in millimetres, counter-clockwise (y up), the
        first point not repeated. Curves are sampled so that every chord lies
        within :attr:`tolerance` of the true curve; all points lie on it.
    vertices : numpy.ndarray
        Sorted indices into :attr:`outline` of the source's own vertices (path
        segment end points, polyline vertices, panel vertices), kept exactly.
    turn_points : numpy.ndarray
        Sorted indices into :attr:`outline` of the corners the file marks itself
        (AAMA/ASTM layer 2 turn points, GarmentCode panel vertices); empty if the
        format has none (SVG, plain DXF).
    grain_line : numpy.ndarray or None
        ``(2, 2)`` end points of the grain line in millimetres (AAMA layer 7).
    units : str
        The units of the file's coordinates (``"mm"``, ``"in"``, ``"px"``, ...);
        :attr:`outline` is converted to millimetres whatever they are.
    source : str
        The reader: ``"svg"``, ``"dxf"``, ``"aama-dxf"`` or ``"garmentcode"``.
    tolerance : float
        Bound on the distance of any outline chord from the true curve (mm).
    notes : tuple of str
        What the reader assumed or changed (default units, closed a gap, ...).
    meta : dict
        Format-specific extras (SVG element id, DXF layer and handle, AAMA size,
        GarmentCode translation and rotation).
    """

    name: str
    outline: np.ndarray
    vertices: np.ndarray
    turn_points: np.ndarray
    grain_line: np.ndarray | None = None
    units: str = "mm"
    source: str = ""
    tolerance: float = 0.0
    notes: tuple[str, ...] = ()
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def aliases(self) -> tuple[str, ...]:
        """Other names the piece answers to (``meta["aliases"]``): what earlier releases called it
        where a reader now names it better (an SVG piece with a made-up id, ``4`` or ``path1234``,
        now named after its group or the text drawn on it)."""
        return tuple(self.meta.get("aliases") or ())

    @property
    def size(self) -> float:
        """Bounding-box diagonal of the outline (mm)."""
        return float(np.linalg.norm(self.outline.max(axis=0) - self.outline.min(axis=0)))

    @property
    def extent(self) -> tuple[float, float]:
        """Width and height of the outline's bounding box (mm)."""
        w, h = self.outline.max(axis=0) - self.outline.min(axis=0)
        return float(w), float(h)

    @cached_property
    def perimeter(self) -> float:
        """Length of the closed outline (mm)."""
        d = np.diff(np.vstack([self.outline, self.outline[:1]]), axis=0)
        return float(np.hypot(d[:, 0], d[:, 1]).sum())

    @cached_property
    def area(self) -> float:
        """Enclosed area (mm², positive: the outline is counter-clockwise)."""
        return signed_area(self.outline)

    def __repr__(self) -> str:
        w, h = self.extent
        return (f"Piece({self.name!r}, {w:.6g} x {h:.6g} mm, {len(self.outline)} points, "
                f"{len(self.turn_points)} turn points, source={self.source!r})")


@dataclass(frozen=True)
class PieceFailure:
    """A piece of a pattern file that could not be made (read) or gridded, and why.

    Attributes
    ----------
    name : str
        The piece's name (as the file names it).
    reason : str
        Why, without the file's and the piece's names (an error message's text).
    stage : str
        Where it failed: ``"read"`` (the outline), ``"corners"`` (corner choice
        and the four-sided boundary), ``"size"`` (the grid would not fit in
        memory) or ``"grid"`` (:func:`clothgrid.generate` failed).
    error : Exception or None
        The exception itself (not compared; for callers that re-raise it).
    """

    name: str
    reason: str
    stage: str = "read"
    error: BaseException | None = field(default=None, compare=False, repr=False)

    def message(self, source: Any = None) -> str:
        """``FILE: piece 'NAME': reason`` (without ``FILE: `` when ``source`` is None)."""
        return f"{f'{source}: ' if source is not None else ''}piece {self.name!r}: {self.reason}"

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "reason": self.reason, "stage": self.stage}


@dataclass(frozen=True, eq=False)
class Skipped:
    """A closed outline that is not gridded, and why.

    Attributes
    ----------
    name : str
        Its name (unique with the pieces' names, stable from run to run).
    kind : str
        ``text``, ``arrow``, ``notch``, ``drill hole``, ``button``, ``mark``,
        ``inside``, ``small``, ``seam allowance`` or ``sew line``.
    reason : str
        One line for people.
    piece : Piece or None
        The outline as a piece (None for a degenerate one: fewer than 3 distinct
        points or no area, which cannot be gridded; None also for an outline the
        file's structure marks as an annotation, which a reader need not sample:
        then ``make`` makes it, for :meth:`Pieces.including`).
    of : str or None
        The piece it belongs to (is drawn on, or is the other line of).
    meta : dict
        The reader's facts (element, id, group, ...).
    make : callable or None
        Makes the piece where ``piece`` is None and the outline can be made (it may
        raise :class:`~clothgrid.errors.InputError`).
    size : (float, float) or None
        Width and height of its points' bounding box in mm, where ``piece`` is None.
    """

    name: str
    kind: str
    reason: str
    piece: Piece | None = None
    of: str | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    make: Any = field(default=None, repr=False)
    size: tuple[float, float] | None = None

    def made(self) -> Piece | None:
        """The outline as a piece (``piece``, else made by ``make``), or None where it cannot be one."""
        return self.piece if self.piece is not None or self.make is None else self.make()

    def as_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"name": self.name, "kind": self.kind, "reason": self.reason,
                             "of": self.of}
        if self.piece is not None:
            w, h = self.piece.extent
            d.update(size_mm=[w, h], area_mm2=self.piece.area)
        elif self.size is not None:
            d.update(size_mm=list(self.size))
        d["meta"] = {k: v for k, v in self.meta.items() if v is not None}
        return d


class Pieces(list):
    """The pieces read from a pattern file, in file order (a plain ``list`` of :class:`Piece`).

    Attributes
    ----------
    failed : list of PieceFailure
        The pieces of the file that could not be made (an outline that would be
        a piece: fewer than 3 distinct points, no area, invalid path data, no
        closed boundary), with why.
    skipped : list of Skipped
        The closed outlines taken for annotations by
        :func:`clothgrid.patterns.annotations.classify` (text, arrows, notches,
        drill holes, marks, seam-allowance outlines), in file order, with why;
        none is gridded unless named (:meth:`including`).
    stitches : dict or None
        The seams the file itself lists, as the data of a stitches file
        (:mod:`clothgrid.garment_stitches`; an SVG's ``<metadata><seams>``), or None.
    """

    def __init__(self, pieces: Any = (), failed: Any = (), skipped: Any = (), stitches: Any = None) -> None:
        super().__init__(pieces)
        self.failed: list[PieceFailure] = list(failed)
        self.skipped: list[Skipped] = list(skipped)
        self.stitches: dict[str, Any] | None = stitches

    @classmethod
    def like(cls, source: Any, pieces: Any, failed: Any = None, skipped: Any = None) -> "Pieces":
        """``pieces`` as a list that carries what ``source`` (a :class:`Pieces`, or a plain list that
        carries nothing) holds besides its pieces: its ``failed`` and ``skipped`` unless given, and the
        file's ``stitches``."""
        return cls(pieces, getattr(source, "failed", ()) if failed is None else failed,
                   getattr(source, "skipped", ()) if skipped is None else skipped,
                   getattr(source, "stitches", None))

    def resolve(self, name: str) -> str:
        """``name`` as the name of one of these pieces, skipped outlines or failed pieces: itself where
        one is so named, else the name of the one piece or skipped outline that has it among its
        aliases (:attr:`Piece.aliases`: an earlier release's name), else itself (unknown)."""
        if any(x.name == name for x in (*self, *self.skipped, *self.failed)):
            return name
        having = [x.name for x in (*self, *self.skipped) if name in (x.meta.get("aliases") or ())]
        return having[0] if len(having) == 1 else name

    def including(self, names: Sequence[str] | None, where: str = "") -> "Pieces":
        """These pieces plus the skipped outlines named in ``names`` (in file order of the skip
        list); :attr:`failed` is kept. A name that is neither a piece nor a skipped outline (nor a
        failed piece) is an InputError, and so is a skipped outline that cannot be gridded."""
        if not names:
            return self
        names = [self.resolve(n) for n in names]
        wanted = set(names)
        by_name = {s.name: s for s in self.skipped}
        bad = {f.name: f for f in self.failed}
        for n in names:
            if n in bad and n not in by_name:
                raise InputError(bad[n].message(where.rstrip().rstrip(":") or None))
        known = {p.name for p in self} | set(by_name)
        missing = [n for n in names if n not in known]
        if missing:
            listed = ", ".join(repr(s.name) for s in self.skipped[:20]) or "none"
            raise InputError(f"{where}no outline named {', '.join(map(repr, missing))} to include; "
                             f"the skipped outlines are {listed}")
        added: list[Piece] = []
        for s in self.skipped:
            if s.name in wanted:
                try:
                    piece = s.made()
                except InputError as exc:
                    raise InputError(f"{where}outline {s.name!r} cannot be gridded: {exc}") from None
                if piece is None:
                    raise InputError(f"{where}outline {s.name!r} cannot be gridded: {s.reason}")
                piece.meta["included"] = f"skipped as {s.kind}, included by name"
                piece.meta.setdefault("line", {"seam allowance": "cut", "sew line": "sew"}
                                      .get(s.kind, "outline"))
                added.append(piece)
        return Pieces.like(self, list(self) + added, skipped=[s for s in self.skipped if s.name not in wanted])


#: Two outline points closer than this (relative to the piece's size, and at least twice its sampling
#: tolerance) that are not neighbours along it pinch the outline: it is cut there into two pieces
#: (:func:`split_pinched`).
PINCH_REL = 1e-5
#: ... where each part is at least this fraction of the whole's area (a smaller one is a loop or a
#: spike of the line, left as it is).
PINCH_MIN_PART = 0.01


def pinch_pairs(outline: np.ndarray, tol: float) -> np.ndarray:
    """``(m, 2)`` outline indices ``i < j`` of points within ``tol`` of each other (each coordinate)
    whose distance along the outline, both ways round, is over ``4 tol``: where the outline pinches
    (two darts' tips drawn to one point). Near-linear: points meet only in shared cells of four
    grids of cell ``2 tol`` offset by ``tol``."""
    n = len(outline)
    if n < 6 or not tol > 0:
        return np.zeros((0, 2), dtype=np.int64)
    seg = np.hypot(*np.diff(np.vstack([outline, outline[:1]]), axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    per = arc[-1]
    found = set()
    for off in ((0.0, 0.0), (tol, 0.0), (0.0, tol), (tol, tol)):
        cell = np.floor((outline - outline.min(axis=0) + off) / (2 * tol)).astype(np.int64)
        order = np.lexsort((cell[:, 1], cell[:, 0]))
        c = cell[order]
        starts = np.flatnonzero(np.r_[True, (c[1:] != c[:-1]).any(axis=1)])
        ends = np.r_[starts[1:], len(c)]
        # runs of one cell whose points are not one stretch of the outline (a densely sampled curve
        # puts neighbours in one cell: those runs are passed over without a look at their pairs)
        span = np.maximum.reduceat(order, starts) - np.minimum.reduceat(order, starts)
        look = (ends - starts > 1) & (span != ends - starts - 1)
        for a0, b0 in zip(starts[look], ends[look]):
            run = order[a0:min(b0, a0 + 64)]
            for x in range(len(run)):
                for y in range(x + 1, len(run)):
                    i, j = sorted((int(run[x]), int(run[y])))
                    along = arc[j] - arc[i]
                    if min(along, per - along) > 4 * tol and (np.abs(outline[i] - outline[j]) <= tol).all():
                        found.add((i, j))
    return np.array(sorted(found), dtype=np.int64).reshape(-1, 2)


def split_pinched(piece: Piece) -> list[Piece]:
    """``piece``, or the parts its outline makes where it pinches (:func:`pinch_pairs` at
    :data:`PINCH_REL`): a drafting program's bodice block whose waist and shoulder darts are drawn to
    one apex point is two lobes that meet there, and no grid of one block can pass through a point.
    Each part is a piece named ``NAME-part1``, ``NAME-part2`` (cut again where it pinches too), with a
    note; parts under :data:`PINCH_MIN_PART` of the area leave the piece as it is."""
    o = piece.outline
    n = len(o)
    tol = max(PINCH_REL * piece.size, 2.0 * piece.tolerance)
    pairs = pinch_pairs(o, tol)
    for i, j in pairs:
        idx = (np.arange(i, j), np.r_[np.arange(j, n), np.arange(0, i)])
        areas = [abs(signed_area(o[k])) for k in idx]
        if min(areas) < PINCH_MIN_PART * abs(piece.area):
            continue
        at = o[i]
        parts = []
        for k, rows in enumerate(idx):
            where = {int(v): m for m, v in enumerate(rows)}
            keep = lambda ind: np.array([where[int(v)] for v in ind if int(v) in where], dtype=np.int64)  # noqa: E731
            name = f"{piece.name}-part{k + 1}"
            meta = {key: v for key, v in piece.meta.items() if key not in ("aliases", "fold_line")}
            parts.append(piece_from_polygon(
                name, o[rows], vertices=keep(piece.vertices), turn_points=keep(piece.turn_points),
                grain_line=piece.grain_line, units=piece.units, source=piece.source, tolerance=piece.tolerance,
                notes=piece.notes + (f"piece {piece.name!r} was cut in two where its outline pinches, at "
                                     f"({at[0]:.6g}, {at[1]:.6g}) mm (two of its points "
                                     f"{float(np.hypot(*(o[i] - o[j]))):.2g} mm apart: darts drawn to one "
                                     "point); a grid of one block cannot pass through a point",),
                meta={**meta, "split_from": piece.name}))
        return [q for part in parts for q in split_pinched(part)]
    return [piece]


#: A cut count above this is no cut instruction (a number that happens to follow "Cut")
MAX_CUT_COUNT = 1000

_CUT_SAYS = re.compile(r"^\s*cut\s+(?P<n>\d+)\s*(?:x\b|times\b|pieces?\b)?(?P<rest>.*)$", re.IGNORECASE)
_TIMES = re.compile(r"^\s*(?P<n>\d+)\s*x\s*(?P<rest>.*)$", re.IGNORECASE)
_MIRRORED = re.compile(r"\b(mirrored|mirror|pairs?|reversed|flipped)\b", re.IGNORECASE)
_ON_FOLD = re.compile(r"\b(cut\s+)?on\s+(the\s+)?fold\b", re.IGNORECASE)


def cut_instructions(text: str) -> list[dict[str, Any]]:
    """What a pattern's text says to cut of a piece, as ``[{"count", "material", "mirrored",
    "on_fold"}, ...]`` (one entry a material), or ``[]`` where it says no such thing.

    FreeSewing 3 and 4: ``Cut 2 mirrored from main fabric``, ``Cut 1 on the fold from main fabric``,
    ``Cut 1 from plugin-annotations:ribbing`` (a translation key: ``ribbing``); FreeSewing 2:
    ``2x from main fabric, 2x from interfacing``, ``1x main, 1x lining Cut on fold``; others:
    ``Cut 2 Fabric``.
    """
    text = " ".join(str(text).split())
    on_fold = bool(_ON_FOLD.search(text))
    parts: list[tuple[int, str]] = []
    m = _CUT_SAYS.match(text)
    if m:
        parts.append((int(m["n"]), m["rest"]))
    else:
        for chunk in text.split(","):
            t = _TIMES.match(chunk)
            if not t:
                return []
            parts.append((int(t["n"]), t["rest"]))
    out = []
    for n, rest in parts:
        if not 0 < n <= MAX_CUT_COUNT:
            return []
        mirrored = bool(_MIRRORED.search(rest))
        material = _ON_FOLD.sub(" ", _MIRRORED.sub(" ", rest))
        material = re.sub(r"^\s*(from|of|in)\b", " ", material.strip(), flags=re.IGNORECASE)
        material = " ".join(material.split(":")[-1].split()) or None
        out.append({"count": n, "material": material, "mirrored": mirrored, "on_fold": on_fold})
    return out


def outline_box(prims: Any) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """The bounding box ``((x0, y0), (x1, y1))`` of an outline that could not be made into a piece
    (its primitives' end points, or an ``(n, 2)`` point array), for
    :func:`~clothgrid.patterns.annotations.classify` to tell a tiny glyph from a broken piece; None
    where there is no point or a point is not finite (an outline reaching infinity is no glyph)."""
    try:
        if isinstance(prims, np.ndarray):
            pts = np.asarray(prims, dtype=np.float64).reshape(-1, prims.shape[-1])[:, :2]
        else:
            pts = np.array([np.asarray(q.start, dtype=np.float64)[:2] for q in prims]
                           + [np.asarray(q.end, dtype=np.float64)[:2] for q in prims])
    except (TypeError, ValueError, AttributeError, IndexError):
        return None
    if not len(pts) or not np.isfinite(pts).all():
        return None
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return (float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1]))


def piece_failure(name: str, exc: BaseException, where: str = "", stage: str = "read",
                  labels: Sequence[str] = ()) -> PieceFailure:
    """A :class:`PieceFailure` from an error about piece ``name``: the message's leading file and
    piece names (``where``, then ``piece 'NAME'`` or one of ``labels``) are taken off."""
    text = str(exc)
    where = where.rstrip()
    for head in (where, where.rstrip(":")):
        if head and text.startswith(head):
            text = text[len(head):].lstrip(": ")
            break
    for label in (f"piece {name!r}", f"panel {name!r}", *labels):
        if text.startswith(label):
            text = text[len(label):].lstrip(": ")
            break
    return PieceFailure(name, text or type(exc).__name__, stage, exc)


def pattern_pieces(pieces: Sequence[Piece], failed: Sequence[PieceFailure], where: str,
                   none: str | None = None, skipped: Sequence[Any] = ()) -> Pieces:
    """The reader's answer: the good pieces and the failed ones, or a :class:`PiecesError` (an
    InputError) when no piece could be made (the one failure's message, or every failure's reason)."""
    if pieces:
        return Pieces(pieces, failed, skipped)
    if not failed:
        raise InputError(none or f"{where}: no pattern piece found")
    if len(failed) == 1:
        raise PiecesError(failed[0].message(where), failed, where)
    raise PiecesError(f"{where}: none of its {len(failed)} pieces could be read: "
                      + "; ".join(f.message() for f in failed), failed, where)


#: Most area (fraction of the piece's) that the small self-crossing loops cut off an outline
#: may add up to (:func:`clothgrid.geometry.untie_loops`); outlines of more points than
#: :data:`UNTIE_MAX_POINTS` are not searched (the boundary check still finds a crossing).
UNTIE_AREA = 0.01
UNTIE_MAX_POINTS = 20_000


def _untied(pts: np.ndarray, verts: np.ndarray, turns: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """``pts`` with the small loops of lines running past a corner cut off, indices carried over.

    Called only for an outline that :func:`_self_crossing` found crossing itself.
    The crossing points are new vertices (and turn points, where the piece has
    any): they are the corners the lines meant. An outline that crosses itself
    in earnest is returned as it is (:func:`_check_simple` names the crossing).
    """
    out = untie_loops(pts, UNTIE_AREA * abs(signed_area(pts)))
    if out is None or (len(out) == len(pts) and np.array_equal(out, pts)):
        return pts, verts, turns, 0
    at = {(float(x), float(y)): k for k, (x, y) in enumerate(out)}
    old = {(float(x), float(y)) for x, y in pts}
    crossings = {k for k, (x, y) in enumerate(out) if (float(x), float(y)) not in old}

    def carry(idx: np.ndarray) -> np.ndarray:
        moved = {at.get((float(pts[i, 0]), float(pts[i, 1]))) for i in idx}
        return np.array(sorted((moved - {None}) | crossings), dtype=np.int64)

    return (np.ascontiguousarray(out), carry(verts), carry(turns) if len(turns) else turns,
            len(crossings))


def _check_primitives(prims: list[Primitive], label: str) -> None:
    """InputError unless every control point is finite and within :data:`MAX_COORDINATE`."""
    from .sampling import Bezier

    if len(prims) > MAX_OUTLINE_POINTS:
        raise InputError(f"{label}: {len(prims):,} curves, more than the limit of {MAX_OUTLINE_POINTS:,} "
                         "points per outline")
    pts = [p.ctrl if isinstance(p, Bezier) else
           np.array([p.center, p.center + p.a, p.center + p.b]) for p in prims]
    allp = np.concatenate(pts)
    if not np.isfinite(allp).all():
        raise InputError(f"{label}: a non-finite coordinate (NaN or inf)")
    if np.abs(allp).max() > MAX_COORDINATE:
        raise InputError(f"{label}: a coordinate of {np.abs(allp).max():.3g} mm, beyond the limit of "
                         f"{MAX_COORDINATE:.0e} in size")


def _self_crossing(pts: np.ndarray) -> tuple[np.ndarray, tuple[int, int, np.ndarray]] | None:
    """Where the closed outline crosses or touches itself: ``(kept points, (k, m, where))``, or None.

    ``kept`` are the indices of the points left after near-duplicates (zero-length
    segments) are dropped; ``k``, ``m`` index the kept segments that meet.
    """
    from ..boundary import CORNER_TOL, _find_self_intersection

    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    tol = max(CORNER_TOL * size, np.finfo(np.float64).tiny)
    keep = np.flatnonzero(np.linalg.norm(pts - roll(pts, 1), axis=1) > tol)
    if len(keep) < 3:
        return None
    if _clearly_convex(pts[keep], tol):
        return None
    found = _find_self_intersection(pts[keep], tol)
    return None if found is None else (keep, found)


def _clearly_convex(q: np.ndarray, tol: float) -> bool:
    """Whether the closed polygon ``q`` is strictly convex, turning once round, and far from
    degenerate (every edge times the sine of the smallest corner angle above ``1000 tol``):
    then no two of its segments meet, and the pairwise search is skipped (a one-rectangle
    piece of a 10^5-piece file spent a quarter of its time in that search)."""
    e = roll(q, -1) - q
    f = roll(e, -1)
    cross = e[:, 0] * f[:, 1] - e[:, 1] * f[:, 0]
    if not ((cross > 0).all() or (cross < 0).all()):
        return False
    turn = np.arctan2(cross, (e * f).sum(axis=1))
    if abs(abs(float(turn.sum())) - 2 * np.pi) > 1e-6:
        return False
    length = np.hypot(e[:, 0], e[:, 1])
    sine = np.abs(cross) / (length * roll(length, -1))
    return float(length.min()) * float(sine.min()) > 1e3 * tol


def _check_simple(pts: np.ndarray, label: str) -> None:
    """InputError if the closed outline crosses or touches itself (which segments, where)."""
    crossing = _self_crossing(pts)
    if crossing is None:
        return
    keep, (k, m, where) = crossing
    n = len(keep)
    place = f"({where[0]:.6g}, {where[1]:.6g}) mm"
    if k == m:
        raise InputError(f"{label}: the outline folds back onto itself at outline point "
                         f"{int(keep[(k + 1) % n])}, near {place}")
    raise InputError(f"{label}: the outline crosses or touches itself near {place} (its segments "
                     f"from point {int(keep[k])} and from point {int(keep[m])}); a self-intersecting "
                     "outline (a bow-tie, a figure eight) cannot be gridded")


def unique_name(name: str, used: dict[str, int]) -> str:
    """``name``, or where ``used`` (the names given so far, each with how often it was asked for) has
    it, ``name-2``, ``name-3``, ... (the first not given); the name returned is recorded in ``used``."""
    if name not in used:
        used[name] = 1
        return name
    used[name] += 1
    return unique_name(f"{name}-{used[name]}", used)


def _sorted_unique(a: np.ndarray) -> np.ndarray:
    """``np.unique`` of integers by sorting (NumPy 2's hashing ``unique`` takes a second on 10^6)."""
    a = np.sort(np.asarray(a, dtype=np.int64))
    return a[np.concatenate(([True], a[1:] != a[:-1]))] if len(a) else a


def piece_from_polygon(name: str, points: np.ndarray, *, vertices: np.ndarray | None = None,
                       turn_points: np.ndarray | None = None, where: str = "",
                       **kwargs: Any) -> Piece:
    """Validate and orient a closed outline (mm) and build a :class:`Piece`.

    Consecutive duplicate points (and a last point equal to the first) are
    dropped, so are zero-width spikes (:func:`clothgrid.geometry.spike_points`,
    at most :data:`SPIKE_WIDTH` of the size wide; a note says where), the
    outline is made counter-clockwise, and ``vertices`` /
    ``turn_points`` (indices into ``points``) are carried along.

    Raises
    ------
    InputError
        Non-finite coordinates, fewer than 3 distinct points (:data:`MIN_POINTS`;
        a triangle is a piece: a godet, a gusset), or zero area.
    """
    label = f"{where}piece {name!r}"
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or not np.isfinite(pts).all():
        raise InputError(f"{label}: a non-finite or malformed coordinate")
    if len(pts) > MAX_OUTLINE_POINTS:
        raise InputError(f"{label}: {len(pts):,} outline points, more than the limit of "
                         f"{MAX_OUTLINE_POINTS:,} points per outline")
    if len(pts) and np.abs(pts).max() > MAX_COORDINATE:
        raise InputError(f"{label}: a coordinate of {np.abs(pts).max():.3g} mm, beyond the limit of "
                         f"{MAX_COORDINATE:.0e} in size")
    n0 = len(pts)
    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) if n0 else 0.0
    eps = 1e-12 * size
    # drop points equal to their predecessor (cyclically), remembering where each went
    if n0:
        gap = np.linalg.norm(pts - roll(pts, 1), axis=1)
        keep = gap > eps
        if not keep.any():
            keep[0] = True
    else:
        keep = np.zeros(0, bool)
    new_index = np.cumsum(keep) - 1           # index of the kept point each point merged into
    new_index = np.where(new_index < 0, int(keep.sum()) - 1, new_index)
    pts = pts[keep]
    # zero-width spikes (a slit or a notch mark drawn into the line) are not cloth
    for _ in range(8):                        # taking a spike off may leave a step back: again
        spikes = spike_points(pts, SPIKE_WIDTH * size)
        if not spikes.any() or (~spikes).sum() < MIN_POINTS:
            break
        at = pts[spikes].mean(axis=0)
        kept = ~spikes
        again = np.cumsum(kept) - 1
        again = np.where(again < 0, int(kept.sum()) - 1, again)
        new_index = again[new_index]
        pts = pts[kept]
        kwargs["notes"] = tuple(kwargs.get("notes", ())) + (
            f"removed {int(spikes.sum())} outline point{'s' if spikes.sum() != 1 else ''} on "
            f"zero-width spikes (slits or notch marks in the line) near "
            f"({at[0]:.6g}, {at[1]:.6g})",)
        # (a spike's points are consecutive duplicates no longer: nothing else to drop)
    n = len(pts)
    if n < MIN_POINTS:
        raise InputError(f"{label}: only {n} distinct point{'s' if n != 1 else ''}; a piece "
                         f"needs at least {MIN_POINTS} and must enclose an area")

    def remap(idx: np.ndarray | None) -> np.ndarray:
        if idx is None or len(idx) == 0:
            return np.zeros(0, dtype=np.int64)
        return _sorted_unique(new_index[np.asarray(idx, dtype=np.int64) % n0])

    verts, turns = remap(vertices), remap(turn_points)
    crossing = _self_crossing(pts)            # one near-linear search on the common path
    if crossing is not None and n <= UNTIE_MAX_POINTS:
        pts, verts, turns, crossings = _untied(pts, verts, turns)
        n = len(pts)
        if crossings:
            kwargs["notes"] = tuple(kwargs.get("notes", ())) + (
                f"{crossings} small loop{'s' if crossings != 1 else ''} where the line runs past a "
                f"corner and crosses itself cut off at the crossing",)
            crossing = _self_crossing(pts)
    area = signed_area(pts)
    if not abs(area) > 1e-12 * size * size:
        raise InputError(f"{label}: encloses no area (its outline runs back over itself)")
    if area < 0:                              # make it counter-clockwise, keeping point 0
        pts = roll(pts[::-1], 1)
        verts, turns = _sorted_unique((n - verts) % n), _sorted_unique((n - turns) % n)
    if crossing is not None:                  # named in the final numbering ('clothgrid pieces')
        _check_simple(pts, label)
    return Piece(name=name, outline=np.ascontiguousarray(pts), vertices=verts,
                 turn_points=turns, **kwargs)


def snap_to_outline(outline: np.ndarray, points: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The outline point nearest to each of ``points`` where one lies within ``tol``.

    Only points within ``tol`` count, so candidates come from a grid of cells of that size (the
    3 x 3 cells round each point), not all pairs (a panel may have 30,000 outline points) nor a
    k-d tree (SciPy's ``spatial``, whose import costs the command about 0.13 s).

    Parameters
    ----------
    outline : numpy.ndarray
        ``(n, 2)`` finite points.
    points : numpy.ndarray
        ``(m, 2)`` points to snap (non-finite ones never snap).
    tol : float
        Positive distance.

    Returns
    -------
    nearest : numpy.ndarray
        ``(m,)`` int64: the nearest outline point's index (the lowest of equally near ones), -1
        where none is within ``tol``.
    ok : numpy.ndarray
        ``(m,)`` bool: one is within ``tol``.
    """
    nearest = np.full(len(points), -1, dtype=np.int64)
    if not len(outline) or not len(points):
        return nearest, nearest >= 0
    origin = outline.min(axis=0) - tol               # cells counted from here: 1 .. span - 2 hold the outline
    span = np.floor((outline.max(axis=0) - origin) / tol) + 2.0
    cells = np.floor((outline - origin) / tol).astype(np.int64)
    width = int(span[1]) + 1                         # a row of cells, and one empty cell either side
    keys = cells[:, 0] * width + cells[:, 1]
    order = np.argsort(keys, kind="stable")          # equal keys keep the outline's order
    keys = keys[order]
    for k, p in enumerate(points):
        if not np.isfinite(p).all():
            continue
        c = np.floor((p - origin) / tol)
        if not (np.all(c >= 0.0) and np.all(c <= span)):
            continue                                     # beyond the outline's cells by more than one
        ci, cj = int(c[0]), int(c[1])
        cand = np.concatenate([order[np.searchsorted(keys, (ci + di) * width + cj - 1):
                                     np.searchsorted(keys, (ci + di) * width + cj + 1, side="right")]
                               for di in (-1, 0, 1)])
        if not len(cand):
            continue
        cand.sort()
        d = np.hypot(outline[cand, 0] - p[0], outline[cand, 1] - p[1])
        m = int(np.argmin(d))
        if d[m] <= tol:
            nearest[k] = cand[m]
    return nearest, nearest >= 0


def piece_from_primitives(name: str, prims: list[Primitive], *, rel_tol: float = DEFAULT_REL_TOL,
                          turn_points: list[np.ndarray] | None = None, where: str = "",
                          **kwargs: Any) -> Piece:
    """Sample a closed chain of curves (mm) into a :class:`Piece`.

    Parameters
    ----------
    name : str
        The piece's name.
    prims : list of Bezier or EllipseArc
        The closed chain (each primitive starts where the previous ends).
    rel_tol : float
        Chord tolerance relative to the piece's size (default ``1e-7``).
    turn_points : list of (2,) arrays, optional
        Points the file marks as corners; each is snapped to the nearest
        outline point (and must be within ``1e-6`` of the size of it).
    where : str
        Prefix for messages (the file name).
    """
    if not prims:
        raise InputError(f"{where}piece {name!r}: no curves")
    _check_primitives(prims, f"{where}piece {name!r}")
    size = loop_extent(prims)
    if not size > 0:
        raise InputError(f"{where}piece {name!r}: zero size")
    tol = rel_tol * size
    outline, starts = sample_loop(prims, tol)
    turns = None
    notes = list(kwargs.pop("notes", ()))
    if turn_points:
        tp = np.asarray(turn_points, dtype=np.float64).reshape(-1, 2)
        nearest, ok = snap_to_outline(outline, tp, 1e-6 * size)
        if not ok.all():
            notes.append(f"{int((~ok).sum())} turn point(s) not on the outline were ignored")
        turns = nearest[ok]
    return piece_from_polygon(name, outline, vertices=starts, turn_points=turns, where=where,
                              tolerance=tol, notes=tuple(notes), **kwargs)


def piece_from_points(name: str, points: Any, *, rel_tol: float = DEFAULT_REL_TOL, where: str = "",
                      **kwargs: Any) -> Piece:
    """A closed polygon (mm), every point a vertex, into a :class:`Piece`.

    The piece :func:`piece_from_primitives` makes of the polygon's straight
    segments (the same checks, tolerance and vertices), without a primitive
    per segment: an SVG ``<polygon>`` of 10^6 points takes a second, not
    minutes.

    Parameters
    ----------
    name : str
        The piece's name.
    points : array_like
        ``(n, 2)`` points in order; the last joins the first (a repeated first
        point is dropped as a duplicate).
    rel_tol : float
        Chord tolerance relative to the piece's size, kept as the piece's
        ``tolerance`` (straight segments need no more points).
    where : str
        Prefix for messages (the file name).
    """
    label = f"{where}piece {name!r}"
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) > MAX_OUTLINE_POINTS:
        raise InputError(f"{label}: {len(pts):,} points, more than the limit of {MAX_OUTLINE_POINTS:,} "
                         "points per outline")
    if not len(pts):
        raise InputError(f"{label}: no curves")
    if not np.isfinite(pts).all():
        raise InputError(f"{label}: a non-finite coordinate (NaN or inf)")
    big = float(np.abs(pts).max())
    if big > MAX_COORDINATE:
        raise InputError(f"{label}: a coordinate of {big:.3g} mm, beyond the limit of "
                         f"{MAX_COORDINATE:.0e} in size")
    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    if not size > 0:
        raise InputError(f"{label}: zero size")
    return piece_from_polygon(name, pts, vertices=np.arange(len(pts)), where=where,
                              tolerance=rel_tol * size, **kwargs)
