"""Pieces, not drawings: tell the pattern pieces of a file from its annotations.

Pattern files draw more closed outlines than pieces: text converted to paths,
arrows, notches, drill holes, marks drawn on a piece, and the seam-allowance
(cut) outline drawn around a piece's sew line. :func:`classify` sorts the
closed outlines a reader found into pieces and :class:`Skipped` annotations,
each with a reason, using the structure the file gives first (SVG classes,
ids and labels such as FreeSewing's ``fabric``, ``sa``, ``note``, ``mark``,
``help``; text groups; DXF layer names) and geometry second (outlines inside
other outlines, outlines of nearly the same shape around another, relative
size, circles, arrows, dashed outlines across a piece). The readers return a
:class:`~.piece.Pieces` list: the pieces, with the skipped outlines in
:attr:`Pieces.skipped` and the pieces that
could not be made in :attr:`Pieces.failed`; a skipped outline is gridded when
asked for by name (:meth:`Pieces.including`, ``--include NAME`` or ``--piece NAME``).

An outline that cannot be made into a piece (fewer than 3 distinct points, no
area) is skipped when the file's structure marks it as an annotation (a class,
id, label or group such as ``note``, ``mark``, ``notch``, or a text cue), and
is a failure otherwise: it would be a piece, so the file has a piece that
cannot be gridded (``clothgrid generate`` exits with code 4).

See ``docs/patterns.md``, sections "Annotations" and "Sew line or cut line".
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from typing import Any, Iterable, Sequence

import numpy as np

from ..errors import InputError
from ..geometry import box_holds, points_in_polygon, roll
from .piece import Piece, PieceFailure, Pieces, Skipped, pattern_pieces

__all__ = ["Pieces", "Skipped", "classify", "classified", "structure_hint", "LINES", "MIN_AREA_FRACTION"]

#: the outline a seam-allowance pair grids: ``"sew"`` (inner, default) or ``"cut"`` (outer)
LINES = ("sew", "cut")
#: a free-standing outline under this fraction of the largest piece's area is an annotation
MIN_AREA_FRACTION = 0.005
#: an outline around another is its seam allowance when their Hausdorff distance is at most
#: this fraction of the inner outline's size (bounding-box diagonal) and at most SA_MAX_MM
SA_REL = 0.25
SA_MAX_MM = 100.0

# Words (class names, ids, labels, DXF layer names, split at non-letters) -> what they mean.
_ANNOTATION_WORDS = {
    "text": "text", "texts": "text", "title": "text", "label": "text", "labels": "text",
    "font": "text", "glyph": "text", "glyphs": "text", "lettering": "text",
    "arrow": "arrow", "arrows": "arrow",
    "notch": "notch", "notches": "notch",
    "drill": "drill hole", "drillhole": "drill hole", "hole": "drill hole", "holes": "drill hole",
    "punch": "drill hole",
    "button": "button", "buttons": "button", "buttonhole": "button", "snap": "button",
    "note": "mark", "notes": "mark", "mark": "mark", "marks": "mark", "marker": "mark",
    "help": "mark", "hidden": "mark", "dimension": "mark", "dimensions": "mark", "dim": "mark",
    "leader": "mark", "grainline": "mark", "grain": "mark", "logo": "mark", "scalebox": "mark",
    "annotation": "mark", "annotations": "mark", "comment": "mark", "comments": "mark",
    "defpoints": "mark",
}
_PIECE_WORDS = {"fabric", "lining", "interfacing", "canvas", "contrast", "various", "piece",
                "pieces", "panel", "panels", "pattern"}
_CUT_WORDS = {"sa", "cut", "cutline", "cutting", "cuttingline", "allowance", "seamallowance"}
_SEW_WORDS = {"sew", "sewline", "seam", "seamline", "stitch", "stitchline"}
_TEXT_ID = re.compile(r"^(text|flowroot|tspan)[-_]?\d*$", re.IGNORECASE)


def _words(text: str | None) -> list[str]:
    return [w for w in re.split(r"[^a-z0-9]+", (text or "").lower()) if w]


def structure_hint(own: Iterable[str | None], around: Iterable[str | None] = (),
                   text: bool = False, named: Iterable[str | None] = ()) -> dict[str, Any]:
    """What the file's structure says about an outline.

    ``own``: the outline's own class names / layer name; ``around``: those of
    its groups (ids, labels, classes); ``text``: a text cue (an ``aria-label``
    or font attributes on the outline or a group, an Inkscape ``text123`` id);
    ``named``: the outline's own id and label, which count only where they
    name its line (a cut or sew line): then the groups' annotation words do not
    make it an annotation (a TauMeta file's layer ``Label-pattern`` holds every
    piece's ``A.seamline`` and ``A.cuttingline``).
    Returns ``{"hint": "piece" | "cut" | "sew" | None, "annotation": kind or
    None, "why": the word that decided}``.
    """
    own_w = [w for t in own for w in _words(t)]
    around_w = [w for t in around for w in _words(t)]
    out: dict[str, Any] = {"hint": None, "annotation": None, "why": None}
    if text:
        out.update(annotation="text", why="text")
        return out
    for w in own_w:
        if w in _ANNOTATION_WORDS:
            out.update(annotation=_ANNOTATION_WORDS[w], why=w)
            return out
    for w in (w for t in named for w in _words(t)):
        for words, hint in ((_CUT_WORDS, "cut"), (_SEW_WORDS, "sew")):
            if w in words:
                out.update(hint=hint, why=w)
                return out
    for w in around_w:
        if w in _ANNOTATION_WORDS:
            out.update(annotation=_ANNOTATION_WORDS[w], why=w)
            return out
    for w in own_w + around_w:
        if w in _CUT_WORDS:
            out.update(hint="cut", why=w)
            return out
    for w in own_w + around_w:
        if w in _SEW_WORDS:
            out.update(hint="sew", why=w)
            return out
    for w in own_w + around_w:
        if w in _PIECE_WORDS:
            out.update(hint="piece", why=w)
            return out
    return out


# --------------------------------------------------------------------------- geometry


#: Point-segment pairs from which :func:`outline_distance` takes the Numba kernel (the same bits;
#: below it NumPy, which needs no compiled code loaded: a reader may run without the grid solver).
KERNEL_PAIRS = 1 << 15


def outline_distance(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each point to the closed polyline ``poly``."""
    if len(points) * len(poly) >= KERNEL_PAIRS:
        from .distance_kernels import dist_to_polyline

        return dist_to_polyline(np.ascontiguousarray(points, dtype=np.float64),
                                np.ascontiguousarray(poly, dtype=np.float64))
    a = poly
    b = roll(poly, -1)
    ab = b - a
    L2 = (ab * ab).sum(axis=1)
    L2 = np.where(L2 > 0, L2, 1.0)
    best = np.full(len(points), np.inf)
    for chunk in range(0, len(points), 256):
        p = points[chunk:chunk + 256, None, :]
        t = np.clip(((p - a) * ab).sum(axis=2) / L2, 0.0, 1.0)
        d = np.linalg.norm(p - (a + t[..., None] * ab), axis=2).min(axis=1)
        best[chunk:chunk + 256] = d
    return best


def _sub(points: np.ndarray, n: int = 400) -> np.ndarray:
    if len(points) <= n:
        return points
    return points[np.linspace(0, len(points) - 1, n).astype(int)]


def _coarse(points: np.ndarray, n: int = 2000) -> np.ndarray:
    return _sub(points, n)


def _circle_like(p: Piece) -> bool:
    per = p.perimeter
    return per > 0 and 4 * math.pi * p.area / per ** 2 > 0.85


#: A frame (an axis-aligned rectangle around the pieces) holds at least two outlines of at least this
#: fraction of its area each.
FRAME_CONTENT = 0.05


def _rectangle(p: Piece) -> bool:
    """Four outline points, the sides along the axes (within 1e-6 of its size)."""
    q = p.outline
    if len(q) != 4:
        return False
    d = np.abs(roll(q, -1) - q)
    return bool((np.minimum(d[:, 0], d[:, 1]) <= 1e-6 * p.size).all())


def _arrow_like(p: Piece) -> bool:
    """A straight-edged 7-gon with two reflex corners: a block arrow."""
    if len(p.outline) != 7 or len(p.vertices) != 7:
        return False
    q = p.outline
    d0 = q - roll(q, 1)
    d1 = roll(q, -1) - q
    cross = d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0]
    return int((cross < 0).sum()) == 2


@dataclass
class _Item:
    piece: Piece
    lo: np.ndarray
    hi: np.ndarray
    sub: np.ndarray
    poly: np.ndarray
    kind: str | None = None
    reason: str | None = None
    of: str | None = None


#: A point of an outline within this fraction of another's size (bounding-box diagonal) from that
#: one's line counts as inside it (:func:`_contains`): a piece cut on the fold has its seam line and
#: its cut line on one edge, the fold (a real Seamly2D export's backs and fronts: 2 of 64 points
#: 1e-15 mm outside, so the pair was not seen).
ON_LINE_REL = 1e-9


def _contains(outer: _Item, inner: _Item) -> bool:
    tol = ON_LINE_REL * float(np.hypot(*(outer.hi - outer.lo)))
    if not box_holds(outer.lo, outer.hi, inner.lo, inner.hi, tol):
        return False
    inside = points_in_polygon(inner.sub, outer.poly)
    if not inside.all():                        # points on the outer line count as inside it
        inside[~inside] = outline_distance(inner.sub[~inside], outer.poly) <= tol
    return bool(inside.mean() > 0.98)


def _hausdorff(a: _Item, b: _Item) -> float:
    return float(max(outline_distance(a.sub, b.poly).max(), outline_distance(b.sub, a.poly).max()))


def _fmt_pct(x: float) -> str:
    return f"{100 * x:.2g} %" if x < 0.01 else f"{100 * x:.1f} %"


def dashed(look: str | None) -> bool:
    """Whether an outline's ``meta["look"]`` (``class;fill;stroke;stroke-dasharray``, the SVG
    reader's) draws it dashed."""
    if not look:
        return False
    dashes = look.rsplit(";", 1)[-1].strip().lower()
    return dashes not in ("", "none") and any(float(v) > 0 for v in re.findall(r"[0-9.]+(?:e-?[0-9]+)?", dashes)
                                               if v.strip(".") != "")


def classify(pieces: Sequence[Piece], unmade: Sequence[tuple[PieceFailure, dict]] = (), *,
             line: str = "sew", marked: Sequence[Skipped] = ()) -> Pieces:
    """Sort closed outlines into pieces and skipped annotations.

    Parameters
    ----------
    pieces : sequence of Piece
        Every closed outline a reader found, in file order. Each one's
        ``meta["structure"]`` (from :func:`structure_hint`), ``meta["group"]``
        (the group it is drawn in), ``meta["part"]`` (the part of the pattern:
        two outlines the file calls pieces in different parts are never one
        the other's mark or seam allowance) and ``meta["look"]`` (how it is
        drawn) are used when present.
    unmade : sequence of (PieceFailure, meta)
        Closed outlines that could not be made into a :class:`Piece` (fewer
        than 3 distinct points, no area), with their ``meta`` as above. One the
        file's structure marks as an annotation is skipped (``piece`` None);
        the others would be pieces: they are the answer's ``failed``.
    line : "sew" or "cut"
        Of an outline and the seam-allowance outline around it, which to grid.
    marked : sequence of Skipped
        Outlines the reader skipped as the file's structure marks them
        (:func:`marked_annotation`: not sampled); listed after the outlines made.

    Returns
    -------
    Pieces
        The pieces in file order; ``.skipped`` the rest with reasons, ``.failed``
        the outlines of ``unmade`` that are no annotation. Every
        piece's ``meta["line"]`` says which line it is (``sew``, ``cut`` or
        ``outline`` when the file draws only one) and its notes say so when
        a choice was made.
    """
    if line not in LINES:
        raise InputError(f"--line {line!r}: use 'sew' or 'cut'")
    items = []
    for p in pieces:
        lo, hi = p.outline.min(axis=0), p.outline.max(axis=0)
        items.append(_Item(p, lo, hi, _sub(p.outline), _coarse(p.outline)))
    notes: dict[int, list[str]] = {i: [] for i in range(len(items))}
    lines: dict[int, str] = {}
    hints = [(it.piece.meta.get("structure") or {}) for it in items]

    # 1. structure: what the file says an outline is
    for it, h in zip(items, hints):
        if h.get("annotation"):
            it.kind = h["annotation"]
            it.reason = f"{h['annotation']} (the file marks it {h.get('why')!r})"
    cand = [i for i, it in enumerate(items) if it.kind is None]
    is_piece_class = {i: hints[i].get("hint") in ("piece", "cut", "sew") for i in cand}

    def same_part(i: int, j: int) -> bool:
        # two outlines of different sizes (a graded file's, drawn on top of each other) are different
        # pieces; so are two outlines the file calls pieces, in different parts
        a, b = items[i].piece.meta.get("size"), items[j].piece.meta.get("size")
        if a and b and a != b:
            return False
        if is_piece_class[i] and is_piece_class[j]:
            return items[i].piece.meta.get("part") == items[j].piece.meta.get("part")
        return True

    # containment among the remaining outlines
    order = sorted(cand, key=lambda i: -items[i].piece.area)
    containers: dict[int, list[int]] = {i: [] for i in cand}
    lo = np.array([items[i].lo for i in order]).reshape(-1, 2)
    hi = np.array([items[i].hi for i in order]).reshape(-1, 2)
    by_x = np.argsort(lo[:, 0], kind="stable")      # boxes by their left edge
    left = lo[by_x, 0]                               # (sorted once: per outline it was quadratic)
    for a, i in enumerate(order):
        # only the later (smaller) outlines whose box lies in this one's (near-linear for
        # outlines side by side: the left edges in [lo, hi] are found by bisection)
        first = np.searchsorted(left, lo[a, 0], side="left")
        last = np.searchsorted(left, hi[a, 0], side="right")
        js = by_x[first:last]
        js = np.sort(js[(js > a) & (hi[js, 0] <= hi[a, 0]) & (lo[js, 1] >= lo[a, 1])
                        & (hi[js, 1] <= hi[a, 1])])
        for b in js:
            j = order[int(b)]
            if same_part(i, j) and _contains(items[i], items[j]):
                containers[j].append(i)           # larger first

    # 2. seam allowance: a top-level outline around another of nearly the same shape
    paired: dict[int, int] = {}
    innermost: dict[int, list[int]] = {}           # outline -> those it is the smallest container of
    for j in order:
        if containers[j]:
            innermost.setdefault(containers[j][-1], []).append(j)
    for i in order:
        if containers[i] or i in paired.values():
            continue
        inner = innermost.get(i, [])
        best = None
        for j in inner:                         # largest first
            if hints[j].get("hint") == "cut":
                continue
            size = items[j].piece.size
            hd = _hausdorff(items[i], items[j])
            if hints[i].get("hint") == "cut" or hints[j].get("hint") == "sew" or (
                    hd <= SA_REL * size and hd <= SA_MAX_MM):
                best = (j, hd)
                break
        if best is None:
            continue
        j, hd = best
        paired[i] = j
        outer, inner_p = items[i], items[j]
        if line == "sew":
            _keep_group_name(inner_p, outer)
            outer.kind, outer.of = "seam allowance", inner_p.piece.name
            outer.reason = (f"seam-allowance outline around piece {inner_p.piece.name!r} (its cut "
                            f"line, up to {hd:.3g} mm outside; --line cut grids it instead)")
            lines[j] = "sew"
            notes[j].append(f"line: sew (the inner of two outlines; the cut line "
                            f"{outer.piece.name!r} lies up to {hd:.3g} mm outside)")
        else:
            _keep_group_name(outer, inner_p)
            inner_p.kind, inner_p.of = "sew line", outer.piece.name
            inner_p.reason = (f"sew line inside piece {outer.piece.name!r} (up to {hd:.3g} mm "
                              "inside; --line sew grids it instead)")
            lines[i] = "cut"
            notes[i].append(f"line: cut (the outer of two outlines; the sew line "
                            f"{inner_p.piece.name!r} lies up to {hd:.3g} mm inside)")

    # 2b. frames: an axis-aligned rectangle holding several outlines side by side, not all of them
    # rectangles (a plot's frame or page background around the pieces: OpenPattern's matplotlib
    # drawings; a page border), is no piece, and what it holds is not drawn on it
    holds: dict[int, list[int]] = {}              # outline -> the outlines it holds, largest first
    for j in order:
        for i in containers[j]:
            holds.setdefault(i, []).append(j)
    for i in order:
        it = items[i]
        if (len(holds.get(i, ())) < 2 or it.kind not in (None, "seam allowance") or is_piece_class[i]
                or not _rectangle(it.piece)):
            continue
        held = [j for j in holds[i] if items[j].kind is None and not _rectangle(items[j].piece)
                and items[j].piece.area >= FRAME_CONTENT * it.piece.area]
        held = [j for j in held if not any(k in held for k in containers[j])]          # top level
        if len(held) < 2:
            continue
        it.kind, it.of = "frame", None
        it.reason = (f"frame around {len(held)} outlines side by side (a page border or a drawing's "
                     "frame, not a piece)")
        j = partner.get(i) if (partner := {**paired, **{v: k for k, v in paired.items()}}) else None
        if j is not None:                              # the same rectangle drawn twice: both frames
            items[j].kind, items[j].of, items[j].reason = "frame", None, it.reason
            paired.pop(i, None), paired.pop(j, None), lines.pop(i, None), lines.pop(j, None)
            notes[i], notes[j] = [], []
    for j in cand:                                     # what a frame holds is not inside it
        containers[j] = [i for i in containers[j] if items[i].kind != "frame"]

    alive = [i for i in cand if items[i].kind is None]
    if alive:
        largest = max(items[i].piece.area for i in alive)
    else:
        largest = max((it.piece.area for it in items), default=0.0)

    partner = {**paired, **{v: k for k, v in paired.items()}}

    # 3. dashed outlines across the outline of a larger piece drawn solid: construction, fold or
    # stitch lines (a bust radius drawn as a dashed circle around the bust point reaches over the
    # dart's mouth). One inside a piece is a mark drawn on it (5.).
    for j in cand:
        it = items[j]
        if (it.kind is not None or j in partner or is_piece_class[j] or containers[j]
                or not dashed(it.piece.meta.get("look"))):
            continue
        for i in order:                            # the largest host first
            h = items[i]
            if (i == j or h.kind is not None or h.piece.area < it.piece.area or dashed(h.piece.meta.get("look"))
                    or not same_part(i, j) or np.any(it.hi < h.lo) or np.any(it.lo > h.hi)):
                continue
            if points_in_polygon(it.sub, h.poly).any():
                it.kind, it.of = "dashed line", h.piece.name
                it.reason = (f"dashed outline across the outline of piece {h.piece.name!r} (a construction, fold or "
                             "stitch line)")
                break

    # 4. small outlines across a piece's outline: notches
    alive = [i for i in cand if items[i].kind is None or i in paired]
    al = np.array(alive, dtype=np.int64)
    a_area = np.array([items[i].piece.area for i in alive])
    a_lo = np.array([items[i].lo for i in alive]).reshape(-1, 2)
    a_hi = np.array([items[i].hi for i in alive]).reshape(-1, 2)
    a_free = np.array([items[i].kind is None for i in alive], dtype=bool)
    a_pos = {i: k for k, i in enumerate(alive)}
    # a host is at least 50 times the notch's area: the hosts are a prefix of the outlines by
    # decreasing area (not all outlines for each one: 10^5 small outlines took minutes)
    by_area = np.argsort(-a_area, kind="stable")
    neg_area = -a_area[by_area]                     # ascending
    for j in cand:
        it = items[j]
        if it.kind is not None or j in partner or is_piece_class[j]:
            continue
        # the prefix, a little generous (rounding of the division); the exact test follows
        reach = int(np.searchsorted(neg_area, -(it.piece.area / 0.02) * (1 - 1e-9), side="right"))
        if reach == 0:
            continue
        k = by_area[:reach]
        # the hosts that can take it (vectorised: larger, at most 2 % of area, boxes overlap)
        ok = (a_free[k] & (al[k] != j) & (a_area[k] > it.piece.area) & (it.piece.area <= 0.02 * a_area[k])
              & (a_lo[k, 0] <= it.hi[0]) & (a_lo[k, 1] <= it.hi[1])
              & (a_hi[k, 0] >= it.lo[0]) & (a_hi[k, 1] >= it.lo[1]))
        for i in al[np.sort(k[ok])]:                # in file order, as before
            i = int(i)
            h = items[i]
            frac = it.piece.area / h.piece.area
            if frac > 0.02 or np.any(it.hi < h.lo) or np.any(it.lo > h.hi):
                continue
            ins = points_in_polygon(it.sub, h.poly)
            if ins.any() and not ins.all():
                it.kind, it.of = "notch", h.piece.name
                it.reason = f"notch on the outline of piece {h.piece.name!r} ({_fmt_pct(frac)} of its area)"
                if j in a_pos:
                    a_free[a_pos[j]] = False
                break

    # 5. outlines inside a piece: marks drawn on it
    for j in cand:
        it = items[j]
        if it.kind is not None or j in partner:
            continue
        hosts = [i for i in containers[j] if partner.get(j) != i and items[i].kind != "dashed line"]
        if not hosts:
            continue
        host = hosts[-1]                          # the smallest outline around it
        h = items[host]
        name = h.piece.name
        if h.kind in ("seam allowance",) and h.of:
            where = f"on the seam allowance of piece {h.of!r}"
            name = h.of
        elif h.kind == "sew line" and h.of:
            name = h.of
            where = f"inside piece {name!r}"
        else:
            where = f"inside piece {name!r}"
        frac = it.piece.area / max(h.piece.area, 1e-300)
        look = it.piece.meta.get("look")
        if frac >= 0.05 and look is not None and look == h.piece.meta.get("look"):
            # drawn like the piece around it and not small: pieces laid over each other
            notes[j].append(f"drawn over piece {h.piece.name!r} (drawn alike, so taken for a piece)")
            continue
        if frac >= 0.5:
            notes[j].append(f"drawn inside piece {h.piece.name!r}")
            continue
        if _circle_like(it.piece) and frac < 0.01:
            it.kind, it.reason = "drill hole", f"drill hole {where} ({_fmt_pct(frac)} of its area)"
        elif _arrow_like(it.piece):
            it.kind, it.reason = "arrow", f"arrow {where}"
        else:
            it.kind, it.reason = "inside", f"{where} (a mark drawn on it, {_fmt_pct(frac)} of its area)"
        it.of = name

    # 6. free-standing outlines: circles, arrows, glyph groups, too small
    alive = [i for i in cand if items[i].kind is None]
    largest = max((items[i].piece.area for i in alive), default=largest)
    small = [i for i in alive if not is_piece_class[i] and items[i].piece.area < 0.02 * largest]
    groups: dict[Any, list[int]] = {}
    for i in small:
        groups.setdefault(items[i].piece.meta.get("group"), []).append(i)
    for g, members in groups.items():
        if len(members) < 3:
            continue
        heights = np.array([items[i].piece.extent[1] for i in members])
        med = float(np.median(heights))
        glyphs = [i for i, hgt in zip(members, heights) if med / 2.5 <= hgt <= med * 2.5]
        if len(glyphs) >= 3:
            for i in glyphs:
                items[i].kind = "text"
                items[i].reason = (f"text (one of {len(glyphs)} glyph-sized outlines in group "
                                   f"{g!r})")
    for i in alive:
        it = items[i]
        if it.kind is not None or is_piece_class[i]:
            continue
        frac = it.piece.area / max(largest, 1e-300)
        if frac >= 1.0:
            continue
        if _circle_like(it.piece) and frac < 0.01:
            it.kind, it.reason = "drill hole", f"drill hole or dot ({_fmt_pct(frac)} of the largest piece's area)"
        elif _arrow_like(it.piece) and frac < 0.05:
            it.kind, it.reason = "arrow", "arrow (a 7-sided block arrow)"
        elif frac < MIN_AREA_FRACTION:
            it.kind, it.reason = "small", f"too small against the largest piece ({_fmt_pct(frac)} of its area)"

    # the pieces, with the line they are
    out: list[Piece] = []
    skipped: list[tuple[int, Skipped]] = []
    for i, it in enumerate(items):
        p = it.piece
        meta = _public_meta(p.meta)
        if it.kind is not None:
            skipped.append((i, Skipped(p.name, it.kind, it.reason or it.kind, p, it.of, meta)))
            continue
        hint = hints[i].get("hint")
        if i in lines:
            used = lines[i]
        elif hint == "cut":
            used = "cut"
            if line == "sew":
                notes[i].append("line: cut (no sew line found inside this outline, which the file "
                                "marks as a cut line)")
        else:
            used = meta.get("line") or "outline"
        p.meta.clear()
        p.meta.update(meta, line=used)
        extra = tuple(n for n in notes[i] if n not in p.notes)
        if extra:
            from dataclasses import replace

            p = replace(p, notes=p.notes + extra)
        out.append(p)
    # outlines that could not be made: skipped if the file marks them as annotations, or if the
    # square on their bounding box's longer side is too small against the largest piece (the
    # glyphs of lettering drawn as filled paths, whose tiny curves touch themselves; a flat or
    # two-point outline as long as a piece's side is still a failed piece), else failed
    k = len(items)
    failed: list[PieceFailure] = []
    for f, meta in unmade:
        h = meta.get("structure") or {}
        kept = _public_meta(meta)
        box = meta.get("box")
        side = max(box[1][0] - box[0][0], box[1][1] - box[0][1]) if box else None
        frac = side * side / largest if side is not None and largest > 0 else None
        if h.get("annotation"):
            skipped.append((k, Skipped(
                f.name, h["annotation"],
                f"{h['annotation']} (the file marks it {h.get('why')!r}); a degenerate outline: {f.reason}",
                None, None, kept)))
            k += 1
        elif frac is not None and frac < MIN_AREA_FRACTION and h.get("hint") not in ("piece", "cut", "sew"):
            skipped.append((k, Skipped(
                f.name, "small", f"too small against the largest piece (the square on its longer side "
                f"{_fmt_pct(frac)} of its area), and not an outline that can be gridded: {f.reason}",
                None, None, kept)))
            k += 1
        else:
            failed.append(f)
    skipped.sort(key=lambda t: t[0])
    made = [s for k, s in skipped if k < len(items)]              # then the marked, then the unmade
    return Pieces(out, failed, made + list(marked) + [s for k, s in skipped if k >= len(items)])


def _public_meta(meta: dict[str, Any]) -> dict[str, Any]:
    """A reader's ``meta`` without what only :func:`classify` reads (the structure's hint, how the
    outline is drawn, its part, the box of an outline that could not be made, the group name it
    was named after)."""
    return {k: v for k, v in meta.items() if k not in ("structure", "look", "part", "box", "group_base")}


def _keep_group_name(gridded: _Item, other: _Item) -> None:
    """Of two lines of one piece both named after their group (``meta["group_base"]``: FreeSewing
    draws a part's sew and cut lines in its group, with made-up ids), the one gridded takes the
    group's name where the other had it (being first in the file), and the other its name."""
    base = gridded.piece.meta.get("group_base")
    if base and base == other.piece.meta.get("group_base") and other.piece.name == base != gridded.piece.name:
        gridded.piece, other.piece = replace(gridded.piece, name=base), replace(other.piece, name=gridded.piece.name)


def marked_annotation(name: str, hint: dict[str, Any], meta: dict[str, Any], box: Any, make: Any) -> Skipped:
    """The :class:`Skipped` entry of an outline whose structure ``hint`` (:func:`structure_hint`)
    marks it as an annotation, which :func:`classify` would skip whatever its shape: made only
    if included by name (``make``), its size from ``box`` (:func:`~.piece.outline_box`: its points'
    bounding box, None if it has none). Hundreds of logo and button glyphs drawn through SVG
    ``<use>`` took 2 s to sample and check."""
    kept = _public_meta(meta)
    size = None if box is None else (box[1][0] - box[0][0], box[1][1] - box[0][1])
    return Skipped(name, hint["annotation"], f"{hint['annotation']} (the file marks it {hint.get('why')!r})",
                   None, None, kept, make, size)


def classified(pieces: Sequence[Piece], unmade: Sequence[tuple[PieceFailure, dict]], where: str,
               none: str | None = None, *, line: str = "sew", marked: Sequence[Skipped] = ()) -> Pieces:
    """A reader's answer: :func:`classify` the outlines made and not made (and those ``marked``);
    when none was made or marked, the error of :func:`~.piece.pattern_pieces` (``none`` when there
    was nothing at all)."""
    if not pieces and not marked:
        return pattern_pieces([], [f for f, _ in unmade], where, none)   # raises
    return classify(pieces, unmade, line=line, marked=marked)
