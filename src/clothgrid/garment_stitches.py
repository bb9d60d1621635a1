"""Seams for SVG and DXF patterns: a small JSON stitches file read into a :class:`GarmentSpec`.

SVG and DXF pattern files carry no stitches. ``clothgrid garment PATTERN
--stitches FILE`` takes them from a JSON file (``docs/garment.md``)::

    {"clothgrid_stitches": 1,
     "seams": [
       {"a": {"piece": "4", "range": [1336, 1906]},
        "b": {"piece": "24", "range": [1040, 1623]},
        "right_wrong": true, "label": "side seam"},
       ...],
     "pieces": ["4", "24"],
     "unfold": ["24"],
     "placement": {"24": {"translation": [0, 0, -200], "rotation": [0, 180, 0]}}}

A side ``{"piece": NAME, "range": [I, J]}`` is the part of the piece's outline
from outline point ``I`` to outline point ``J``, counter-clockwise (the
outline's own order, wrapping past the last point): the indices
``clothgrid pieces FILE --candidates`` prints (same reading options). The two
sides of a seam are joined as GarmentCode joins a stitch: ``a``'s end meets
``b``'s start, or start meets start with ``"right_wrong": true``. Both ranges
of one piece (a dart) may share an end (the dart's tip). ``"unfold"`` (``true``, or a
list of piece names) makes the pieces cut on the fold whole first
(:func:`clothgrid.patterns.fold.unfold`); their ranges are then those of
``clothgrid pieces FILE --unfold --candidates``. ``"turned"`` lists pieces drawn face down
(their stitches read along the outline run clockwise, their quads reversed). Without a stitches
file, an SVG that lists its seams in ``<metadata><seams>`` is sewn by them
(:func:`clothgrid.patterns.svg` ``_embedded_stitches``). ``"copies"`` (``{NAME: {"of": PIECE,
"mirrored": true}}``) adds a second piece cut from one of the pattern's, its mirror image by
default (the other sleeve): outline point ``k`` of the piece is point ``(n - k) % n`` of its
mirror image, so a range ``[I, J]`` on the piece is ``[(n - J) % n, (n - I) % n]`` on it.

Each piece becomes one :class:`~clothgrid.patterns.garmentcode.SpecPanel`
whose edges are :class:`Polyline` parts of its outline, cut at the seams'
ends, at the grid corners :func:`~clothgrid.patterns.choose_corners` picks for
the piece (as ``clothgrid generate`` does) and at its sharp vertices (turns of
30 degrees or more, not inside a seam and not closer than half the edge length
to another cut); every seam is one edge, so a seam's nodes are sampled along
it as in the GarmentCode path. A grid corner inside a seam is carried across to
the other side (at the matching arc-length fraction). Without ``placement``
the pieces stay where the file draws them (``points`` = ``rest`` with z = 0).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError
from .garment_seams import Polyline
from .patterns.garmentcode import GarmentSpec, SpecEdge, SpecPanel, SpecStitch

__all__ = ["Polyline", "StitchedPattern", "read_stitched_pattern", "STITCHES_FORMAT"]

#: the ``clothgrid_stitches`` version this reader understands
STITCHES_FORMAT = 1
#: outline vertices turning at least this much (degrees) stay grid nodes (``boundary.SHARP_TURN_DEG``)
SHARP_TURN_DEG = 30.0


@dataclass(frozen=True, eq=False)
class StitchedPattern:
    """An SVG / DXF pattern with its stitches file, as a garment spec.

    Attributes
    ----------
    spec : GarmentSpec
        Panels (one per piece named in the stitches file), their polyline edges
        and the seams as stitches (``index`` = position in the file's ``seams``).
    corners : dict
        Panel name -> the four grid corners bottom-left, bottom-right, top-right,
        top-left, each ``(edge index, fraction of that edge)``.
    """

    spec: GarmentSpec
    corners: dict[str, list[tuple[int, float]]]


def _load(path: Path) -> dict:
    from .limits import read_json_file

    data = read_json_file(path, "stitches")
    if not isinstance(data, dict) or not isinstance(data.get("seams"), list) or not data["seams"]:
        raise InputError(f"{path}: a stitches file is an object with a non-empty list \"seams\" "
                         "(docs/garment.md: \"Seams of SVG and DXF patterns\")")
    version = data.get("clothgrid_stitches", STITCHES_FORMAT)
    if version != STITCHES_FORMAT:
        raise InputError(f"{path}: clothgrid_stitches {version!r} is not a version this clothgrid reads "
                         f"({STITCHES_FORMAT})")
    return data


def _unfolded(pieces: dict[str, Any], unfold: Any, path: Path, resolve: Any) -> dict[str, Any]:
    """``pieces`` with those the stitches file's ``"unfold"`` names made whole (``true``: every piece
    the pattern marks cut on the fold; a list: these pieces, each of which must have a fold line)."""
    from .patterns.fold import unfold as whole

    if unfold is False:
        return pieces
    if unfold is True:
        names = [n for n, p in pieces.items() if p.meta.get("fold_line") is not None]
    elif isinstance(unfold, list) and all(isinstance(x, str) for x in unfold):
        names = [resolve(x) for x in unfold]
        for n in names:
            if n not in pieces:
                raise InputError(f"{path}: 'unfold': the pattern has no piece {n!r} (its pieces: "
                                 f"{', '.join(map(repr, pieces))})")
            if pieces[n].meta.get("fold_line") is None:
                raise InputError(f"{path}: 'unfold': piece {n!r} has no fold line (the pattern does not "
                                 "mark it cut on the fold)")
    else:
        raise InputError(f"{path}: 'unfold' must be true, false or a list of piece names, not {unfold!r}")
    out = dict(pieces)
    for n in names:
        try:
            out[n] = whole(pieces[n])
        except InputError as exc:
            raise InputError(f"{path}: 'unfold': {exc}") from None
    return out


#: Copies a stitches file may ask for (a garment has tens of pieces; each copy holds its outline)
MAX_COPIES = 100


def _copies(pieces: dict[str, Any], copies: Any, path: Path, resolve: Any) -> dict[str, Any]:
    """``pieces`` and the copies the stitches file's ``"copies"`` asks for: ``{NAME: {"of": PIECE,
    "mirrored": true}}``, a second piece cut from the pattern's one, its mirror image by default
    (:func:`clothgrid.patterns.fold.mirrored`: outline point ``k`` of the piece is point ``(n - k)
    % n`` of the mirror image) or the same with ``"mirrored": false``."""
    from dataclasses import replace

    from .patterns.fold import mirrored

    if not isinstance(copies, dict):
        raise InputError(f"{path}: 'copies' must be an object {{NAME: {{\"of\": PIECE, \"mirrored\": true}}}}, "
                         f"not {copies!r}")
    if len(copies) > MAX_COPIES:
        raise InputError(f"{path}: {len(copies):,} copies, more than the limit of {MAX_COPIES}")
    out = dict(pieces)
    for name, spec in copies.items():
        what = f"{path}: copy {name!r}"
        if not isinstance(spec, dict) or not isinstance(spec.get("of"), str):
            raise InputError(f"{what} must be {{\"of\": PIECE, \"mirrored\": true}}, not {spec!r}")
        flip = spec.get("mirrored", True)
        if not isinstance(flip, bool):
            raise InputError(f"{what}: 'mirrored' must be true or false, not {flip!r}")
        if name in out or resolve(name) in pieces:
            raise InputError(f"{what}: the pattern already has a piece of that name")
        of = resolve(spec["of"])
        if of not in pieces:
            raise InputError(f"{what}: the pattern has no piece {of!r} (its pieces: "
                             f"{', '.join(map(repr, pieces))})")
        try:
            out[name] = mirrored(pieces[of], name) if flip else replace(
                pieces[of], name=name, meta={**pieces[of].meta, "copy_of": of})
        except InputError as exc:
            raise InputError(f"{what}: {exc}") from None
    return out


def _turned(turned: Any, names: list[str], path: Path, resolve: Any) -> set[str]:
    """The pieces the stitches file's ``"turned"`` lists: drawn face down (the mirror image of how
    they are worn, as a nester lays out a back), so each is sewn along its outline run clockwise
    and its grid's quads are reversed (as a GarmentCode panel whose loop runs clockwise)."""
    if not isinstance(turned, list) or not all(isinstance(x, str) for x in turned):
        raise InputError(f"{path}: 'turned' must be a list of piece names, not {turned!r}")
    out = {resolve(x) for x in turned}
    unknown = sorted(out - set(names))
    if unknown:
        raise InputError(f"{path}: 'turned': no sewn piece {', '.join(map(repr, unknown))} (the sewn pieces: "
                         f"{', '.join(map(repr, names))})")
    return out


def _side(side: Any, pieces: dict[str, Any], what: str, resolve: Any = str) -> tuple[str, int, int]:
    if not isinstance(side, dict) or "piece" not in side or "range" not in side:
        raise InputError(f"{what} must be {{\"piece\": NAME, \"range\": [START, END]}}, not {side!r}")
    name, rng = resolve(str(side["piece"])), side["range"]
    if name not in pieces:
        raise InputError(f"{what}: the pattern has no piece {name!r} (its pieces: "
                         f"{', '.join(map(repr, pieces))})")
    n = len(pieces[name].outline)
    if not (isinstance(rng, list) and len(rng) == 2
            and all(isinstance(i, int) and not isinstance(i, bool) for i in rng)):
        raise InputError(f"{what}: 'range' must be two outline point indices [START, END], not {rng!r}")
    if not all(-n <= i < n for i in rng):
        raise InputError(f"{what}: range {rng} is out of range: piece {name!r} has {n} outline points "
                         f"(0..{n - 1}; clothgrid pieces FILE --candidates lists them)")
    i, j = (x % n for x in rng)
    if i == j:
        raise InputError(f"{what}: range {rng} is empty (its start is its end)")
    return name, i, j


def _placement(data: dict, names: list[str], path: Path, resolve: Any = str) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    raw = data.get("placement") or {}
    if not isinstance(raw, dict):
        raise InputError(f"{path}: 'placement' must be an object PIECE -> {{\"translation\", \"rotation\"}}")
    out = {}
    for name, p in ((resolve(str(k)), v) for k, v in raw.items()):
        if name not in names:
            raise InputError(f"{path}: placement of {name!r}, which is not a piece of the garment "
                             f"({', '.join(map(repr, names))})")
        if not isinstance(p, dict):
            raise InputError(f"{path}: placement of {name!r} must be an object")
        vecs = []
        for key in ("translation", "rotation"):
            try:
                v = np.asarray(p.get(key, [0.0, 0.0, 0.0]), dtype=np.float64)
            except (TypeError, ValueError):
                v = np.zeros(0)
            if v.shape != (3,) or not np.isfinite(v).all():
                raise InputError(f"{path}: placement of {name!r}: '{key}' must be three numbers")
            vecs.append(v)
        out[name] = (vecs[0], vecs[1])
    return out


def _inside(i: int, a: int, b: int, n: int) -> bool:
    """Is outline index ``i`` strictly inside the counter-clockwise range ``a -> b``?"""
    return 0 < (i - a) % n < (b - a) % n


def read_stitched_pattern(pattern: str | Path, stitches: str | Path | None, *, edge_length: float,
                          units: str | None = None) -> StitchedPattern:
    """Read an SVG / DXF pattern and its stitches file as a garment spec (mm).

    Parameters
    ----------
    pattern : path
        The ``.svg`` or ``.dxf`` pattern.
    stitches : path or None
        The JSON stitches file (module docstring; ``docs/garment.md``); None: the seams the SVG
        lists in its own ``<metadata><seams>`` (Alienmiep's pattern-matching-nester exports), an
        InputError where it lists none.
    edge_length : float
        Target grid edge length (mm): sharp vertices closer than half of it to
        another cut are not kept as nodes.
    units : str, optional
        The pattern's coordinate units instead of what the file says.

    Raises
    ------
    InputError
        An unreadable or malformed stitches file, an unknown piece, a range out
        of the outline, overlapping ranges on one piece, a bad placement.
    """
    from .patterns import choose_corners
    from .patterns.corners import turn_angles
    from .readers import read_pieces

    pattern = Path(pattern)
    got = read_pieces(pattern, units=units)
    if stitches is None:                    # the seams the file itself lists (svg <metadata><seams>)
        data = getattr(got, "stitches", None)
        if not data:
            raise InputError(f"{pattern}: SVG and DXF patterns carry no stitches (this one lists none in "
                             "its <metadata> that names its pieces' vertices): give them in a JSON file "
                             "(--stitches FILE, stitches=...; docs/garment.md)")
        stitches = pattern
    else:
        stitches = Path(stitches)
        data = _load(stitches)
    # a name an earlier release gave (an alias: FreeSewing's "4", now "front") finds the piece
    resolve = got.resolve
    pieces = _unfolded({p.name: p for p in got}, data.get("unfold", False), stitches, resolve)
    pieces = _copies(pieces, data.get("copies", {}), stitches, resolve)
    seams = []
    for k, s in enumerate(data["seams"]):
        what = f"{stitches}: seam {k}"
        if not isinstance(s, dict) or "a" not in s or "b" not in s:
            raise InputError(f"{what} must be {{\"a\": SIDE, \"b\": SIDE, \"right_wrong\": false}}, not {s!r}")
        rw = s.get("right_wrong", False)
        if not isinstance(rw, bool):
            raise InputError(f"{what}: 'right_wrong' must be true or false, not {rw!r}")
        seams.append((_side(s["a"], pieces, f"{what}, side a", resolve), _side(s["b"], pieces, f"{what}, side b", resolve),
                      rw))
    extra = data.get("pieces", [])
    if not isinstance(extra, list) or not all(isinstance(x, str) for x in extra):
        raise InputError(f"{stitches}: 'pieces' must be a list of piece names")
    extra = [resolve(x) for x in extra]
    for x in extra:
        if x not in pieces:
            raise InputError(f"{stitches}: the pattern has no piece {x!r} (its pieces: "
                             f"{', '.join(map(repr, pieces))})")
    names = [n for n in pieces if n in extra or any(n in (a[0], b[0]) for a, b, _ in seams)]
    place = _placement(data, names, stitches, resolve)
    turned = _turned(data.get("turned", []), names, stitches, resolve)

    # ranges per piece; no two may overlap
    ranges: dict[str, list[tuple[int, int]]] = {n: [] for n in names}
    for a, b, _ in seams:
        for name, i, j in (a, b):
            n = len(pieces[name].outline)
            for (p, q) in ranges[name]:
                if (p, q) == (i, j) or _inside(i, p, q, n) or _inside(p, i, j, n) or (
                        _inside(j, p, q, n) and j != p) or (_inside(q, i, j, n) and q != i):
                    raise InputError(f"{stitches}: piece {name!r}: the ranges [{i}, {j}] and [{p}, {q}] "
                                     "overlap (a piece's seams may share an end, not a stretch)")
            ranges[name].append((i, j))

    panels: dict[str, SpecPanel] = {}
    corners: dict[str, list[tuple[int, float]]] = {}
    edge_of: dict[tuple[str, int, int], int] = {}      # (piece, range as in the file) -> edge
    for name in names:
        piece = pieces[name]
        choice = choose_corners(piece)
        outline = choice.outline
        keep = np.setdiff1d(np.arange(len(outline)), np.asarray(choice.inserted, dtype=np.int64))
        n = len(outline)
        rs = [(int(keep[i]), int(keep[j])) for i, j in ranges[name]]

        def stitched(i: int) -> bool:
            return any(_inside(i, p, q, n) for p, q in rs)

        cuts = {p for r in rs for p in r}
        cuts |= {int(c) for c in choice.corners if not stitched(int(c))}
        # sharp source vertices stay nodes (not inside a seam, not too close to another cut)
        s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(np.vstack([outline, outline[:1]]), axis=0).T))])
        per = s[-1]
        turn = np.degrees(np.abs(turn_angles(outline)))
        for v in sorted(int(keep[i]) for i in piece.vertices):
            if turn[v] >= SHARP_TURN_DEG and v not in cuts and not stitched(v):
                gap = min(min(abs(s[v] - s[c]), per - abs(s[v] - s[c])) for c in cuts)
                if gap >= 0.5 * edge_length:
                    cuts.add(v)
        cut = sorted(cuts)
        if len(cut) < 2:
            cut = sorted(cuts | {(cut[0] + n // 2) % n})
        verts = outline[cut]
        edges = []
        m = len(cut)
        for k, c in enumerate(cut):
            d = cut[(k + 1) % m]
            idx = np.arange(c, d + 1) if d > c else np.r_[np.arange(c, n), np.arange(0, d + 1)]
            if name in turned:      # drawn face down: its edges run clockwise, as the piece is sewn
                edges.append(SpecEdge(k, (k + 1) % m, k, Polyline(outline[idx[::-1] % n].copy())))
            else:
                edges.append(SpecEdge(k, k, (k + 1) % m, Polyline(outline[idx % n].copy())))
        loop = (((0, False),) + tuple((k, False) for k in range(m - 1, 0, -1)) if name in turned
                else tuple((k, False) for k in range(m)))
        t, r = place.get(name, (np.zeros(3), np.zeros(3)))
        panels[name] = SpecPanel(name, verts, tuple(edges), loop, t, r)
        # the grid corners as (edge, fraction): at a cut, or inside a seam's edge
        cs = []
        for c in choice.corners:
            c = int(c)
            if c in cuts:           # (turned: the start of the edge before it, which runs backwards)
                cs.append(((cut.index(c) - 1) % m, 0.0) if name in turned else (cut.index(c), 0.0))
                continue
            k = next(kk for kk, cc in enumerate(cut) if _inside(c, cc, cut[(kk + 1) % len(cut)], n))
            pts = edges[k].curve.points[::-1] if name in turned else edges[k].curve.points
            L = np.hypot(*np.diff(pts, axis=0).T)
            f = float(L[:(c - cut[k]) % n].sum() / L.sum())
            cs.append((k, 1.0 - f if name in turned else f))
        corners[name] = cs
        # map the ranges to edge indices (in this piece's kept-point numbering)
        for (i0, j0), (i, j) in zip(ranges[name], rs):
            k = cut.index(i)
            assert cut[(k + 1) % len(cut)] == j, "a seam's range is one edge"
            edge_of[(name, i0, j0)] = k
    st = tuple(SpecStitch(k, (a[0], edge_of[a]), (b[0], edge_of[b]), rw) for k, (a, b, rw) in enumerate(seams))
    notes = (f"stitches: {stitches}",)
    return StitchedPattern(GarmentSpec(pattern, panels, st, "mm", 1.0, notes), corners)

