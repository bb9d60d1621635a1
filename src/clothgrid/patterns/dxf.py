"""Read pattern pieces from a DXF file (plain CAD drawings and AAMA/ASTM D6673 patterns).

**AAMA/ASTM D6673** (the apparel industry's DXF): a file whose blocks hold
entities on layer ``1`` is read as one piece per block insert (``INSERT`` in
the model space, its transformation applied; a piece block that is never
inserted is read as it is). In each block, layer ``1`` is the piece
boundary (polylines, lines, arcs, splines, chained into one closed loop; an
open boundary is closed with a straight segment), layer ``2`` the turn
points (``POINT`` entities: the corner candidates), layer ``7`` the grain line
(a ``LINE``); the text ``Piece Name: ...`` names the piece (else the block's
name) and ``Size: ...`` tells graded copies apart. The text ``Units: METRIC``
(millimetres) or ``Units: ENGLISH`` (inches) gives the units; without it
``$INSUNITS``. Layer ``14`` is the sew line: with ``line="sew"`` (the
default) a piece that has one is gridded along it, else along its cut line
(layer 1, noted); ``line="cut"`` grids the cut line. ``Piece.meta["line"]``
says which. Internal lines (layer ``8``) are kept in
``Piece.meta["internal_lines"]`` (mm), not gridded. Curve points (layer 3),
notches and drill holes are not needed for meshing and are ignored.

**Plain DXF**: every closed ``LWPOLYLINE``/``POLYLINE`` (flagged closed or
ending at its start), ``SPLINE``, ``CIRCLE`` and full ``ELLIPSE`` in the model
space (also inside inserted blocks) is a piece; open ``LINE``, ``ARC``,
polylines, splines and elliptical arcs are joined end to end (gaps up to
``1e-6`` of the drawing's size) and every chain that closes is a piece, named
after the ``Piece Name:`` and ``Size:`` texts written on it (:func:`_named_by_texts`).
A ``Units:`` text, else ``$INSUNITS``, gives the units. The closed outlines are then sorted into
pieces and annotations (:func:`clothgrid.patterns.annotations.classify`):
layer names such as ``TEXT``, ``NOTCH``, ``DRILL``, ``DIM``, ``GRAIN`` mark
annotations, and geometry finds marks inside pieces and seam-allowance
outlines around them.

Curves are exact primitives: polyline bulges and arcs are circular arcs,
ellipses elliptical arcs, splines (rational or not) are split into Bézier
pieces by knot insertion; all are then sampled with a guaranteed chord
tolerance (:mod:`clothgrid.patterns.sampling`). A spline given only by fit
points is first interpolated by ezdxf, which need not match the drawing
program's interpolation exactly. Entities must lie in planes parallel to
the xy-plane (z is dropped).
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

from ..errors import InputError
from .. import limits
from ..limits import MAX_BULGE, MAX_COORDINATE, MAX_ENTITIES, check_input_file
from ..geometry import box_holds, points_in_polygon, signed_area
from .annotations import LINES, classified, structure_hint
from .fold import attach_fold_lines
from .chains import GAP_MM, GAP_REL, chain_loops, join_outlines, joined_note, largest_gap
from .piece import (Piece, PieceFailure, Pieces, outline_box, pattern_pieces, piece_failure,
                    piece_from_primitives, unique_name)
from .sampling import DEFAULT_REL_TOL, Bezier, EllipseArc, Primitive, bspline_to_beziers
from ..units import UNITS, unit_to_mm

__all__ = ["read_dxf", "count_records", "INSUNITS"]

#: $INSUNITS code -> unit name (see clothgrid.units.UNITS)
INSUNITS: dict[int, str] = {1: "in", 2: "ft", 4: "mm", 5: "cm", 6: "m", 8: "um", 9: "mil",
                            10: "yd", 13: "um", 14: "dm"}
_INSUNITS_NAMES = {0: "unitless", 3: "miles", 7: "km", 8: "microinches", 11: "angstroms",
                   12: "nanometers", 15: "decameters", 16: "hectometers", 17: "gigameters",
                   18: "astronomical units", 19: "light years", 20: "parsecs"}
_CURVES = {"LINE", "ARC", "CIRCLE", "ELLIPSE", "LWPOLYLINE", "POLYLINE", "SPLINE"}
_KEY = re.compile(r"\s*([A-Za-z][A-Za-z ]*?)\s*:\s*(.*?)\s*$")


def _xy(v: Any) -> np.ndarray:
    p = np.array([float(v[0]), float(v[1])])
    if not (np.isfinite(p).all() and np.abs(p).max() <= MAX_COORDINATE):
        raise InputError(f"a coordinate {tuple(p.tolist())} is not finite or beyond the limit of "
                         f"{MAX_COORDINATE:.0e} in size")
    return p


class _Ctx:
    def __init__(self, where: str):
        self.where = where
        self.notes: list[str] = []


def _check_flat(e: Any, ctx: _Ctx) -> None:
    ext = e.dxf.get("extrusion", (0.0, 0.0, 1.0))
    if abs(abs(float(ext[2])) - 1.0) > 1e-9:
        raise InputError(f"{ctx.where}: {e.dxftype()} {e.dxf.handle} does not lie in a plane "
                         f"parallel to the xy-plane (extrusion {tuple(ext)}); pattern pieces are 2D")


def _ocs_map(e: Any):
    """(point map, vector map) from the entity's OCS to 2D WCS."""
    ocs = e.ocs()

    def point(p) -> np.ndarray:
        return _xy(ocs.to_wcs((float(p[0]), float(p[1]), float(p[2]) if len(p) > 2 else 0.0)))

    origin = point((0.0, 0.0, 0.0))

    def vector(v) -> np.ndarray:
        return point((float(v[0]), float(v[1]), 0.0)) - origin

    return point, vector


def _bulge_arc(p0: np.ndarray, p1: np.ndarray, bulge: float) -> Primitive:
    """The circular arc of a polyline segment with ``bulge`` (OCS, + counter-clockwise)."""
    if not (math.isfinite(bulge) and abs(bulge) <= MAX_BULGE):
        raise InputError(f"a polyline bulge of {bulge!r}: a bulge (tan of a quarter of the arc's angle) "
                         f"must be finite and at most {MAX_BULGE:g} in size")
    theta = 4.0 * math.atan(bulge)
    c = p1 - p0
    chord = float(np.hypot(*c))
    if chord == 0.0 or theta == 0.0:
        return Bezier(np.array([p0, p1]))
    left = np.array([-c[1], c[0]]) / chord
    center = 0.5 * (p0 + p1) + (chord / (2.0 * math.tan(theta / 2.0))) * left
    r = chord / (2.0 * abs(math.sin(theta / 2.0)))
    a0 = math.atan2(p0[1] - center[1], p0[0] - center[0])
    return EllipseArc(center, np.array([r, 0.0]), np.array([0.0, r]), a0, a0 + theta,
                      start_point=p0, end_point=p1)


def _to_wcs(prim: Primitive, point, vector) -> Primitive:
    if isinstance(prim, Bezier):
        return Bezier(np.array([point((x, y, 0.0)) for x, y in prim.ctrl]), prim.weights)
    return EllipseArc(point((*prim.center, 0.0)), vector(prim.a), vector(prim.b), prim.t0, prim.t1,
                      None if prim.start_point is None else point((*prim.start_point, 0.0)),
                      None if prim.end_point is None else point((*prim.end_point, 0.0)))


def _polyline_prims(pts: list[tuple[float, float, float]], closed: bool, point, vector
                    ) -> tuple[list[Primitive], bool]:
    """Primitives of polyline vertices ``(x, y, bulge)`` in OCS; whether the loop is closed."""
    if len(pts) < 2:
        return [], False
    xy = [np.array([float(p[0]), float(p[1])]) for p in pts]
    bulges = [float(p[2]) for p in pts]
    if not closed and np.array_equal(xy[0], xy[-1]):
        closed = True
        xy, bulges = xy[:-1], bulges[:-1]
    n = len(xy)
    segs = n if closed else n - 1
    prims = [_bulge_arc(xy[i], xy[(i + 1) % n], bulges[i]) for i in range(segs)]
    prims = [p for p in prims if not (isinstance(p, Bezier) and np.array_equal(p.ctrl[0], p.ctrl[-1]))]
    return [_to_wcs(p, point, vector) for p in prims], closed


def _entity_prims(e: Any, ctx: _Ctx) -> tuple[list[Primitive], bool]:
    """The entity as exact primitives (2D WCS, file units) and whether it is closed.

    Raises
    ------
    InputError
        A malformed entity (a bulge or coordinate beyond the limits, not flat), the
        message naming the file, the entity and its handle and layer.
    """
    try:
        return _entity_prims_of(e, ctx)
    except InputError as exc:
        text = str(exc)
        if text.startswith(ctx.where):
            raise
        layer = e.dxf.get("layer", None)
        on = f" on layer {layer!r}" if layer not in (None, "") else ""
        raise InputError(f"{ctx.where}: {e.dxftype()} {e.dxf.get('handle', '?')}{on}: {text}") from None


def _entity_prims_of(e: Any, ctx: _Ctx) -> tuple[list[Primitive], bool]:
    kind = e.dxftype()
    if kind == "LINE":
        s, t = _xy(e.dxf.start), _xy(e.dxf.end)
        return ([] if np.array_equal(s, t) else [Bezier(np.array([s, t]))]), False
    if kind in ("ARC", "CIRCLE"):
        _check_flat(e, ctx)
        point, vector = _ocs_map(e)
        r = float(e.dxf.radius)
        if not r > 0:
            return [], False
        c = point(e.dxf.center)
        if kind == "CIRCLE":
            a0, a1, closed = 0.0, 2 * math.pi, True
        else:
            a0 = math.radians(float(e.dxf.start_angle))
            a1 = math.radians(float(e.dxf.end_angle))
            while a1 <= a0:
                a1 += 2 * math.pi
            closed = False
        return [EllipseArc(c, vector((r, 0.0)), vector((0.0, r)), a0, a1)], closed
    if kind == "ELLIPSE":
        _check_flat(e, ctx)
        t0, t1 = float(e.dxf.start_param), float(e.dxf.end_param)
        while t1 <= t0:
            t1 += 2 * math.pi
        closed = abs((t1 - t0) - 2 * math.pi) <= 1e-9
        if closed:
            t1 = t0 + 2 * math.pi
        return [EllipseArc(_xy(e.dxf.center), _xy(e.dxf.major_axis), _xy(e.minor_axis), t0, t1)], \
            closed
    if kind == "LWPOLYLINE":
        _check_flat(e, ctx)
        point, vector = _ocs_map(e)
        elev = float(e.dxf.get("elevation", 0.0))
        pts = [(x, y, b) for x, y, b in e.get_points("xyb")]
        return _polyline_prims([(x, y, b) for x, y, b in pts], bool(e.closed),
                               lambda p: point((p[0], p[1], elev)), vector)
    if kind == "POLYLINE":
        if e.is_polygon_mesh or e.is_poly_face_mesh:
            return [], False
        verts = [v for v in e.vertices if not (int(v.dxf.get("flags", 0)) & 16)]
        if e.is_2d_polyline:
            _check_flat(e, ctx)
            point, vector = _ocs_map(e)
            pts = [(v.dxf.location[0], v.dxf.location[1], float(v.dxf.get("bulge", 0.0)))
                   for v in verts]
            return _polyline_prims(pts, bool(e.is_closed), point, vector)
        pts = [(v.dxf.location[0], v.dxf.location[1], 0.0) for v in verts]
        zs = [float(v.dxf.location[2]) for v in verts]
        if zs and max(zs) - min(zs) > 1e-9 * (1.0 + max(abs(z) for z in zs)):
            raise InputError(f"{ctx.where}: 3D POLYLINE {e.dxf.handle} is not flat in z; "
                             "pattern pieces are 2D")
        return _polyline_prims(pts, bool(e.is_closed), lambda p: _xy(p), lambda v: _xy(v))
    if kind == "SPLINE":
        try:
            bs = e.construction_tool()
        except Exception as exc:                      # ezdxf raises several types
            raise InputError(f"{ctx.where}: SPLINE {e.dxf.handle} cannot be evaluated ({exc})") from None
        if not len(e.control_points) and len(e.fit_points):
            ctx.notes.append("a spline given by fit points was interpolated by ezdxf")
        ctrl = np.array([[float(p[0]), float(p[1]), float(p[2])] for p in bs.control_points])
        if len(ctrl) and np.ptp(ctrl[:, 2]) > 1e-9 * (1.0 + np.abs(ctrl[:, 2]).max()):
            raise InputError(f"{ctx.where}: SPLINE {e.dxf.handle} is not flat in z; pattern "
                             "pieces are 2D")
        weights = list(bs.weights()) if bs.is_rational else None
        prims: list[Primitive] = bspline_to_beziers(bs.degree, list(bs.knots()), ctrl[:, :2],
                                                    weights)
        closed = bool(prims) and np.allclose(prims[0].start, prims[-1].end, rtol=0.0,
                                             atol=1e-12 * (1.0 + np.abs(ctrl[:, :2]).max()))
        return prims, closed
    return [], False


def _scale(prims: list[Primitive], s: float) -> list[Primitive]:
    out: list[Primitive] = []
    for p in prims:
        if isinstance(p, Bezier):
            out.append(Bezier(p.ctrl * s, p.weights))
        else:
            out.append(EllipseArc(p.center * s, p.a * s, p.b * s, p.t0, p.t1,
                                  None if p.start_point is None else p.start_point * s,
                                  None if p.end_point is None else p.end_point * s))
    return out


def _texts(entities: Iterable[Any]) -> dict[str, str]:
    """``key -> value`` of ``TEXT``/``MTEXT`` entities written ``Key: value`` (keys lower case)."""
    out: dict[str, str] = {}
    for e in entities:
        kind = e.dxftype()
        if kind == "TEXT":
            text = str(e.dxf.get("text", ""))
        elif kind == "MTEXT":
            text = e.plain_text() if hasattr(e, "plain_text") else str(e.text)
        else:
            continue
        m = _KEY.match(text)
        if m:
            out.setdefault(m.group(1).strip().lower(), m.group(2).strip())
    return out


def _units(doc: Any, texts: dict[str, str], units: str | None, where: str,
           size: Callable[[], float] | None = None) -> tuple[float, str, str]:
    """(mm per drawing unit, unit name, how it was found). ``size()``: the largest piece's size in
    drawing units, for the error of a drawing without units (which units would make it a garment's)."""
    if units is not None:
        return unit_to_mm(units, what="--units"), units, f"{units} (given)"
    stated = texts.get("units")
    if stated:
        key = stated.strip().upper()
        if key == "METRIC":
            return 1.0, "mm", "Units: METRIC (millimetres)"
        if key == "ENGLISH":
            return UNITS["in"], "in", "Units: ENGLISH (inches)"
        raise InputError(f"{where}: unknown units {stated!r} in the AAMA/ASTM text 'Units:' (known: "
                         "METRIC, ENGLISH); give the units with --units")
    code = int(doc.header.get("$INSUNITS", 0) or 0)
    if code in INSUNITS:
        name = INSUNITS[code]
        return UNITS[name], name, f"$INSUNITS {code} ({name})"
    what = _INSUNITS_NAMES.get(code, "an unknown code")
    hint = ""
    largest = size() if size is not None else 0.0
    if largest > 0 and math.isfinite(largest):
        as_mm = ", ".join(f"{largest * UNITS[u] / 1000:.3g} m in {u}" for u in ("mm", "cm", "in"))
        hint = f"; its largest outline measures {largest:.4g} across ({as_mm})"
    raise InputError(f"{where}: the DXF does not give usable units ($INSUNITS is {code}, {what}){hint}; "
                     "give them with --units (mm, cm, in, ...)")


def _is_piece_block(block: Any) -> bool:
    if block.is_any_layout or block.name.startswith("*"):
        return False
    return any(e.dxf.get("layer", "") == "1" and e.dxftype() in _CURVES for e in block)


def _loop_area(prims: list[Primitive]) -> float:
    pts = np.concatenate([p.points(np.linspace(0, 1, 9)) if isinstance(p, Bezier)
                          else p.points(np.linspace(p.t0, p.t1, 9)) for p in prims])
    return abs(signed_area(pts))


def _extent(prims_list: list[list[Primitive]]) -> float:
    pts = [np.array([p.start, p.end]) for prims in prims_list for p in prims]
    if not pts:
        return 0.0
    allp = np.concatenate(pts)
    return float(np.hypot(*np.ptp(allp, axis=0)))


def _layer_curves(ents: list[Any], layer: str, ctx: _Ctx) -> tuple[list[list[Primitive]], list[list[Primitive]]]:
    """(open chains, closed entities) of the curves on ``layer``, each as its primitives."""
    chains, closed = [], []
    for e in ents:
        if e.dxf.get("layer", "") != layer or e.dxftype() not in _CURVES:
            continue
        prims, is_closed = _entity_prims(e, ctx)
        if prims:
            (closed if is_closed else chains).append(prims)
    return chains, closed


def _layer_loops(ents: list[Any], layer: str, ctx: _Ctx) -> tuple[list[list[Primitive]], list[list[Primitive]]]:
    """(closed loops, open chains left) of the curves on ``layer``."""
    chains, closed = _layer_curves(ents, layer, ctx)
    tol = 1e-6 * _extent(chains + closed)
    loops, _ = chain_loops(chains, tol)
    return loops + closed, chains


def _polylines(ents: list[Any], layer: str, ctx: _Ctx, scale: float) -> list[list[list[float]]]:
    """The curves on ``layer`` as point lists (mm): their end points and vertices."""
    out = []
    for e in ents:
        if e.dxf.get("layer", "") != layer or e.dxftype() not in _CURVES:
            continue
        prims, closed = _entity_prims(e, ctx)
        if prims:
            pts = [prims[0].start] + [p.end for p in prims]
            out.append([[float(x) * scale, float(y) * scale] for x, y in pts])
    return out


def _max_gap(a: Piece, b: Piece) -> float:
    """Largest distance of ``a``'s outline from ``b``'s (mm)."""
    from .annotations import outline_distance, _sub

    return float(outline_distance(_sub(a.outline), _sub(b.outline, 4000)).max())


def _reason(exc: InputError, name: str) -> str:
    """An error's text without the file and piece prefix (``FILE: piece 'NAME': ``)."""
    text = str(exc)
    marker = f"piece {name!r}: "
    return text.split(marker, 1)[1] if marker in text else text


def _read_aama(doc: Any, ctx: _Ctx, units: str | None, rel_tol: float, line: str = "sew") -> Pieces:
    msp = doc.modelspace()
    blocks = {b.name: b for b in doc.blocks if _is_piece_block(b)}
    texts = _texts(msp)
    for b in blocks.values():
        for k, v in _texts(b).items():
            if k == "units":
                texts.setdefault(k, v)
    scale, unit, how = _units(doc, texts, units, ctx.where)
    inserts = [e for e in msp.query("INSERT") if e.dxf.name in blocks]
    jobs: list[tuple[str, list[Any], dict[str, str], str | None]] = []
    inserted = {e.dxf.name for e in inserts}
    for ins in inserts:
        try:
            ents = list(ins.virtual_entities())
        except Exception as exc:                      # ezdxf raises several types
            raise InputError(f"{ctx.where}: cannot place block {ins.dxf.name!r} ({exc})") from None
        jobs.append((ins.dxf.name, ents, _texts(blocks[ins.dxf.name]), ins.dxf.handle))
    for name, b in blocks.items():
        if name not in inserted:
            jobs.append((name, list(b), _texts(b), None))
    names = [(t.get("piece name") or bname) for bname, _, t, _ in jobs]
    dup = {n for n in names if names.count(n) > 1}
    used: dict[str, int] = {}
    pieces: list[Piece] = []
    failed: list[PieceFailure] = []
    for (bname, ents, t, handle), pname in zip(jobs, names):
        where = f"{ctx.where}: block {bname!r}"
        notes: list[str] = [f"units: {how}"]
        size = t.get("size")
        if pname in dup and size:
            pname = f"{pname}_{size}"
        pname = unique_name(pname, used)
        try:
            chains, closed = _layer_curves(ents, "1", ctx)
            tol = 1e-6 * _extent(chains + closed)
            loops, _ = chain_loops(chains, tol)
            if not loops and not closed and chains:
                # the standard's boundary is closed by definition: close the gap with a line
                joined, _ = chain_loops(chains, float("inf"))
                if joined:
                    chain = joined[0]
                    chain.append(Bezier(np.array([chain[-1].end, chain[0].start])))
                    loops = [chain]
                    notes.append("the open boundary was closed with a straight segment")
            loops += closed
            if not loops:
                raise InputError(f"{where}: no closed boundary on layer 1")
            if len(loops) > 1:
                notes.append(f"{len(loops) - 1} smaller closed loop(s) on layer 1 were ignored")
            boundary = max(loops, key=_loop_area)
            turn = [_xy(e.dxf.location) * scale for e in ents
                    if e.dxftype() == "POINT" and e.dxf.get("layer", "") == "2"]
            grain = None
            for e in ents:
                if e.dxftype() == "LINE" and e.dxf.get("layer", "") == "7":
                    grain = np.array([_xy(e.dxf.start), _xy(e.dxf.end)]) * scale
                    break
            meta = {"block": bname, "insert": handle, "size": size,
                    **{k: v for k, v in t.items() if k in ("quantity", "material", "category",
                                                           "annotation")}}
            internal = _polylines(ents, "8", ctx, scale)
            if internal:
                meta["internal_lines"] = internal       # layer 8: kept for later, not gridded
            common = dict(rel_tol=rel_tol, turn_points=turn, where=f"{ctx.where}: ", grain_line=grain,
                          units=unit, source="aama-dxf")
            cut = piece_from_primitives(pname, _scale(boundary, scale),
                                        notes=tuple(notes + ctx.notes), meta=dict(meta), **common)
            sew_loops, sew_open = _layer_loops(ents, "14", ctx)
            sew, sew_failed = None, None
            if sew_loops:
                try:
                    sew = piece_from_primitives(pname, _scale(max(sew_loops, key=_loop_area), scale),
                                                notes=tuple(notes + ctx.notes), meta=dict(meta),
                                                **common)
                except InputError as exc:          # a sew line that is no outline (one that
                    sew = None                     # crosses itself, ...): use the cut line
                    sew_failed = (f"its sew line (layer 14) cannot be gridded ({_reason(exc, pname)}), "
                               "so the cut line (layer 1) is gridded")
            if sew is not None:
                gap = _max_gap(cut, sew)
                sew.meta["cut_line_gap_mm"] = cut.meta["cut_line_gap_mm"] = gap
            if line == "sew" and sew is not None:
                piece = sew
                extra = [f"line: sew (layer 14); the cut line (layer 1) lies up to {gap:.3g} mm outside"]
                line_used = "sew"
            elif line == "sew":
                piece = cut
                why = sew_failed or ("its sew line (layer 14) does not close" if sew_open and not sew_loops
                                  else "no sew line (layer 14) in this piece")
                extra = [f"line: cut (layer 1): {why}"]
                line_used = "cut"
            else:
                piece = cut
                extra = ["line: cut (layer 1), as asked" + (
                    f"; the sew line (layer 14) lies up to {gap:.3g} mm inside" if sew is not None else "")]
                line_used = "cut"
            piece.meta["line"] = line_used
            mirror = _polylines(ents, "6", ctx, scale)       # layer 6: the mirror line (cut on the fold)
            if mirror:
                piece = attach_fold_lines([piece], mirror)[0]
                if piece.meta.get("fold_line") is None:
                    extra.append("its mirror line (layer 6) runs along no edge of the gridded line: ignored")
            pieces.append(replace(piece, notes=piece.notes + tuple(extra)))
        except InputError as exc:
            failed.append(piece_failure(pname, exc, ctx.where, labels=(f"block {bname!r}",)))
    return pattern_pieces(pieces, failed, ctx.where)


def _flatten(entities: Iterable[Any], ctx: _Ctx, depth: int = 0, kinds: frozenset | set = _CURVES) -> Iterable[Any]:
    """The entities of ``kinds`` (curves by default), those of inserted blocks placed."""
    for e in entities:
        if e.dxftype() == "INSERT":
            if depth > 16:
                raise InputError(f"{ctx.where}: blocks nested more than 16 deep")
            try:
                yield from _flatten(e.virtual_entities(), ctx, depth + 1, kinds)
            except InputError:
                raise
            except Exception as exc:                  # ezdxf raises several types
                raise InputError(f"{ctx.where}: cannot place block {e.dxf.name!r} ({exc})") from None
        elif e.dxftype() in kinds:
            yield e


#: The ``Key: value`` texts of a plain drawing that describe the piece they are written on (the AAMA
#: texts, which pattern programs also write in their flat exports: Optitex's graded ``Basic Tee``
#: draws every size on a layer of its own, each piece labelled ``Piece Name: Front``, ``Size: XS``)
_PIECE_KEYS = ("piece name", "size", "quantity", "material", "category", "annotation")


def _labels(entities: Iterable[Any], ctx: _Ctx, scale: float) -> list[tuple[str, str, str, np.ndarray]]:
    """``(layer, key, value, anchor in mm)`` of the drawing's ``TEXT`` and ``MTEXT`` written ``Key: value``
    with a key of :data:`_PIECE_KEYS`; at most :data:`MAX_LABELS`."""
    out = []
    for e in _flatten(entities, ctx, kinds={"TEXT", "MTEXT"}):
        if len(out) >= MAX_LABELS:
            break
        got = _texts([e])
        key = next((k for k in got if k in _PIECE_KEYS), None)
        try:
            at = np.asarray(e.dxf.insert, dtype=np.float64)[:2] * scale
        except (AttributeError, TypeError, ValueError):
            continue
        if key is not None and got[key] and np.isfinite(at).all():
            out.append((str(e.dxf.get("layer", "")), key, got[key], at))
    return out


#: At most this many ``Key: value`` texts are placed on a plain drawing's pieces (each a point-in-polygon
#: test against every outline around it)
MAX_LABELS = 20000


#: A text beside the outlines of its layer is measured against the outlines nearest to it by their boxes
_NEAR = 8


def _nested(a: np.ndarray, b: np.ndarray) -> bool:
    """Two lines of one piece, by their bounding boxes ``(x0, y0, x1, y1)``: either box holds the other
    (within 2 % of the larger's size), and neither is under half the other's size (a mark drawn
    inside is no line of it)."""
    sa, sb = float(np.hypot(*(a[2:] - a[:2]))), float(np.hypot(*(b[2:] - b[:2])))
    if min(sa, sb) < 0.5 * max(sa, sb):
        return False
    tol = 0.02 * max(sa, sb)
    return box_holds(b[:2], b[2:], a[:2], a[2:], tol) or box_holds(a[:2], a[2:], b[:2], b[2:], tol)


def _named_by_texts(pieces: list[Piece], labels: list[tuple[str, str, str, np.ndarray]],
                    taken: set[str]) -> list[Piece]:
    """``pieces`` renamed after the ``Piece Name:`` text written on them, with the other texts of
    :data:`_PIECE_KEYS` in ``meta``. An outline's texts: those on its own layer inside it, or beside
    it (outside every outline of the layer, within the outline's size and less than half as far from
    it and the outlines nested with it as from any other: Optitex writes a neck binding's texts beside
    the strip), where one of them names it; else those of any layer inside it where they name one
    piece in one size (a graded file's sizes drawn on top of each other, with their texts on one
    layer, name none). A name that comes in several sizes gets the size (``Front_XS``, as AAMA graded
    blocks). Of the outlines one text names (a piece's cut and sew lines), the smallest gets the
    name, the others ``-2``, ``-3`` (``meta["group_base"]``: the one gridded takes it,
    :func:`~.annotations.classify`); the old ``pieceN`` stays an alias. ``taken``: names in use by
    outlines not renamed."""
    if not labels or not pieces:
        return pieces
    from .annotations import outline_distance

    points = np.array([at for *_, at in labels])
    boxes = np.array([[*p.outline.min(axis=0), *p.outline.max(axis=0)] for p in pieces])
    inside: list[np.ndarray] = []
    for p, box in zip(pieces, boxes):
        near = np.flatnonzero(np.all((points >= box[:2]) & (points <= box[2:]), axis=1))
        inside.append(near[points_in_polygon(points[near], p.outline)] if len(near) else near)
    # a text on a layer whose outlines it lies outside of (written beside a narrow strip): the
    # outline of its layer nearest to it and those nested with it (its cut and sew lines), where the
    # text is within that outline's size of it and less than half as far from it as from any other
    beside: list[list[int]] = [[] for _ in pieces]
    held = np.zeros(len(labels), dtype=bool)
    for k, p in enumerate(pieces):
        held[[i for i in inside[k] if labels[i][0] == p.meta.get("layer")]] = True
    by_layer: dict[str, list[int]] = {}
    for k, p in enumerate(pieces):
        by_layer.setdefault(p.meta.get("layer"), []).append(k)
    for i in np.flatnonzero(~held):
        ks = np.array(by_layer.get(labels[i][0], []), dtype=np.int64)
        if not len(ks):
            continue
        # the true distance of the NEAR outlines nearest by their boxes (a lower bound of it); the
        # rest are at least as far as the first box left out
        gap = np.maximum(np.maximum(boxes[ks, :2] - points[i], points[i] - boxes[ks, 2:]), 0.0)
        order = np.argsort(np.hypot(gap[:, 0], gap[:, 1]), kind="stable")
        lower = np.hypot(gap[:, 0], gap[:, 1])[order]
        near = ks[order[:_NEAR]]
        d = np.array([float(outline_distance(points[i:i + 1], pieces[k].outline)[0]) for k in near])
        first = int(near[int(np.argmin(d))])
        group = [int(k) for k in near if _nested(boxes[k], boxes[first])]
        others = [dk for k, dk in zip(near, d) if int(k) not in group] + list(lower[_NEAR:_NEAR + 1])
        if d.min() <= pieces[first].size and (not others or d.min() < 0.5 * min(others)):
            for k in group:
                beside[k].append(int(i))
    found: list[dict[str, str] | None] = []
    for k, p in enumerate(pieces):
        layer = p.meta.get("layer")
        own = [i for i in inside[k] if labels[i][0] == layer] + beside[k]
        pick = own if any(labels[i][1] == "piece name" for i in own) else list(inside[k])
        values: dict[str, set[str]] = {}
        for i in pick:
            values.setdefault(labels[i][1], set()).add(labels[i][2])
        names, sizes = values.get("piece name", set()), values.get("size", set())
        ok = len(names) == 1 and len(sizes) <= 1
        found.append({key: sorted(v)[0] for key, v in values.items() if len(v) == 1} if ok else None)
    sizes_of: dict[str, set[str]] = {}
    for f in found:
        if f is not None:
            sizes_of.setdefault(f["piece name"], set()).add(f.get("size", ""))
    order = sorted((k for k, f in enumerate(found) if f is not None), key=lambda k: pieces[k].area)
    out = list(pieces)
    used = set(taken) | {p.name for p, f in zip(pieces, found) if f is None}
    for k in order:                       # smallest first: a piece's sew line before its cut line
        f = found[k]
        assert f is not None
        base = f["piece name"]
        if len(sizes_of[base]) > 1 and f.get("size"):
            base = f"{base}_{f['size']}"
        name, n = base, 1
        while name in used:
            n += 1
            name = f"{base}-{n}"
        used.add(name)
        p = pieces[k]
        said = ", ".join(f"{key.title()}: {v}" for key, v in f.items())
        out[k] = replace(p, name=name, notes=p.notes + (f"named after the texts written inside it ({said})",),
                         meta={**p.meta, "group_base": base, "aliases": [p.name],
                               **{key: v for key, v in f.items() if key != "piece name"}})
    return out


def _read_plain(doc: Any, ctx: _Ctx, units: str | None, rel_tol: float, line: str = "sew") -> Pieces:
    msp = doc.modelspace()
    closed: list[tuple[list[Primitive], Any]] = []
    chains: list[list[Primitive]] = []
    for e in _flatten(msp, ctx):
        prims, is_closed = _entity_prims(e, ctx)
        if not prims:
            continue
        if is_closed:
            closed.append((prims, e))
        else:
            chains.append(prims)
    scale, unit, how = _units(doc, _texts(msp), units, ctx.where,
                              lambda: max((_extent([p]) for p, _ in closed), default=_extent(chains)))
    extent = _extent([p for p, _ in closed] + chains)
    # lines and curves that meet end to end (ends within 1e-6 of the drawing; a second pass up to
    # GAP_MM apart where some are left: a drawing made by hand), around construction lines; last,
    # straight lines that cross near their ends (corners drafted with overshoots), cut where they cross
    chains = [c for c in chains if np.isfinite(c[0].start).all() and np.isfinite(c[-1].end).all()]
    found = (join_outlines(chains, 1e-6 * extent, min(GAP_MM / scale, GAP_REL * extent), mm=scale)
             if extent > 0 else [])
    loops = [f.prims for f in found]
    left_open = len(chains) - len({k for f in found for k in f.members + f.inner})
    if not closed and not loops:
        extra = (f" ({left_open} open line{'s' if left_open != 1 else ''} and curves did not close)"
                 if left_open else "")
        raise InputError(f"{ctx.where}: no closed polyline, spline, circle or chain of lines "
                         f"and arcs found, so no pattern piece{extra}")
    notes = [f"units: {how}"]
    if left_open:
        notes.append(f"{left_open} open line(s) and curves were ignored")
    pieces: list[Piece] = []
    used: dict[str, int] = {}
    items = [(p, {"layer": e.dxf.get("layer", ""), "handle": e.dxf.handle, "entity": e.dxftype()})
             for p, e in closed] + [(p, {"entity": "chain"}) for p in loops]
    joined = {len(closed) + k: f for k, f in enumerate(found)}
    unmade: list[tuple[PieceFailure, dict]] = []
    for k, (prims, meta) in enumerate(items, start=1):
        layer = meta.get("layer")
        if layer is not None:
            meta.update(group=layer, look=layer, structure=structure_hint([layer]))
        name = unique_name(f"piece{k}", used)
        own = []
        outline = joined.get(k - 1)
        if outline is not None:
            gap = largest_gap(prims) * scale
            own.append(joined_note(outline, gap, ("open line or curve", "lines and curves")))
            if outline.bridged:
                meta["gap_mm"] = gap
        try:
            pieces.append(piece_from_primitives(
                name, _scale(prims, scale), rel_tol=rel_tol,
                where=f"{ctx.where}: ", units=unit, source="dxf", notes=tuple(notes + own + ctx.notes),
                meta=meta))
        except InputError as exc:          # fewer than 3 points, no area: failed or skipped
            if outline is not None and outline.bridged:    # a sliver only the gap made: no outline
                continue
            unmade.append((piece_failure(name, exc, ctx.where), {**meta, "box": outline_box(_scale(prims, scale))}))
    pieces = _named_by_texts(pieces, _labels(msp, ctx, scale), {f.name for f, _ in unmade})
    return classified(pieces, unmade, ctx.where, line=line)


def count_records(path: str | Path, stop: int) -> int | None:
    """The records of an ASCII DXF file (its ``0`` group tags), counted up to ``stop + 1``.

    A DXF file is pairs of lines, a group code and a value; every entity,
    polyline vertex, table and block entry starts with code ``0``. The count
    streams the file (constant memory, about 3 x 10^6 lines a second) and stops
    once it passes ``stop``, so that a file too big for ezdxf is refused before
    ezdxf spends minutes reading it.

    Returns
    -------
    int or None
        The count (``stop + 1`` when there are more); None for a binary DXF,
        which is not counted here.
    """
    with open(path, "rb") as f:
        if f.read(18) == b"AutoCAD Binary DXF":
            return None
        f.seek(0)
        count = 0
        for code, _value in zip(f, f):
            if code.strip() == b"0":
                count += 1
                if count > stop:
                    break
    return count


def utf8_text(path: str | Path) -> bool:
    """Whether an ASCII DXF file (:func:`count_records` tells a binary one) has non-ASCII text that
    is valid UTF-8 throughout. ezdxf decodes a
    file without a ``$DWGCODEPAGE`` (or before R2007) as cp1252 by default, which turns the UTF-8
    of names written by many exporters into mojibake (a real ET export's Chinese piece names);
    valid UTF-8 with multi-byte characters hardly occurs by chance in a single-byte code page."""
    import codecs

    decoder = codecs.getincrementaldecoder("utf-8")()
    wide = False
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            if not wide and max(chunk) < 0x80:
                continue
            wide = True
            try:
                decoder.decode(chunk)
            except UnicodeDecodeError:
                return False
    if not wide:
        return False
    try:
        decoder.decode(b"", final=True)
    except UnicodeDecodeError:
        return False
    return True


_HIGH_RUN = re.compile(rb"[\x80-\xff]+")
_GB2312_PAIRS = re.compile(rb"(?:[\xa1-\xf7][\xa1-\xfe])+")
_CODEPAGE = re.compile(rb"\$DWGCODEPAGE[ \t]*\r?\n[ \t]*3[ \t]*\r?\n[ \t]*([^\r\n]*)")


def gb2312_text(path: str | Path) -> bool:
    """Whether an ASCII DXF file that is not UTF-8 (:func:`utf8_text`) has non-ASCII text that is
    GB2312 throughout (every run of bytes above 0x7F a run of two-byte characters, both bytes in
    0xA1-0xFE, at least one a Chinese character), and names no code page but ANSI_1252 (ezdxf's
    default for a file that names none): Chinese pattern CAD systems write their piece names in
    GBK. Single-byte text hardly passes: an accented letter between ASCII ones is a run of one."""
    chinese, carry = False, b""
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            data = carry + chunk
            cut = len(data)
            while cut > 0 and data[cut - 1] >= 0x80:      # a run that may go on in the next chunk
                cut -= 1
            data, carry = data[:cut], data[cut:]
            page = _CODEPAGE.search(data)
            if page and page.group(1).strip().upper() not in (b"ANSI_1252", b""):
                return False
            for run in _HIGH_RUN.findall(data):
                if not _GB2312_PAIRS.fullmatch(run):
                    return False
                chinese = chinese or max(run[0::2]) >= 0xB0
    if carry and not _GB2312_PAIRS.fullmatch(carry):
        return False
    return chinese or bool(carry and max(carry[0::2]) >= 0xB0)


def text_encoding(path: str | Path) -> str | None:
    """The encoding to read an ASCII DXF file's text in where ezdxf's own choice would garble it:
    ``"utf-8"`` (:func:`utf8_text`), ``"gbk"`` (:func:`gb2312_text`), else None (ezdxf's)."""
    if utf8_text(path):
        return "utf-8"
    return "gbk" if gb2312_text(path) else None


def _damage(exc: Exception) -> str:
    """What a DXF error from ezdxf's reader most likely means, for the message: an entity written
    without the subclass markers (``100`` group codes) that DXF R13 and later require, as hand-made
    or old R12-style files have them, or else a damaged or cut-off file."""
    if "subclass" in str(exc):
        return ("an entity lacks the subclass markers DXF R13 and later require, as in a hand-written or "
                "R12-style file: export it again from the CAD program")
    return "damaged or truncated?"


def read_dxf(path: str | Path, *, units: str | None = None,
             rel_tol: float = DEFAULT_REL_TOL, line: str = "sew") -> Pieces:
    """Read the pattern pieces of a DXF file (AAMA/ASTM or plain), in millimetres.

    Parameters
    ----------
    path : str or Path
        The DXF file.
    units : str, optional
        Read the coordinates in these units, whatever the file says.
    rel_tol : float
        Chord tolerance relative to each piece's size (default ``1e-7``).
    line : "sew" or "cut"
        Grid the sew line (AAMA layer 14; the inner of an outline and its
        seam-allowance outline) where there is one, or the cut line.

    Returns
    -------
    Pieces
        The pieces; ``.skipped`` lists closed outlines taken for annotations
        (plain DXF only), ``.failed`` the pieces that cannot be made.

    Raises
    ------
    InputError
        Not a DXF, a malformed or truncated DXF, no units, no closed boundary,
        no piece that could be made, or curves outside the xy-plane. A piece that
        cannot be made (fewer than 3 distinct points, no area, no closed
        boundary in its block) is listed in the answer's ``failed`` instead.
    """
    import ezdxf
    from ezdxf.lldxf.const import DXFError

    path = Path(path)
    ctx = _Ctx(str(path))
    check_input_file(path)
    try:
        records = count_records(path, limits.MAX_DXF_RECORDS)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    if records is not None and records > limits.MAX_DXF_RECORDS:
        raise InputError(f"{path}: more than {limits.MAX_DXF_RECORDS:,} records (entities, polyline vertices, "
                         "table entries), the limit for a DXF file")
    try:
        # (records None: a binary DXF, whose text ezdxf decodes itself)
        doc = ezdxf.readfile(str(path), encoding=None if records is None else text_encoding(path))
    except DXFError as exc:
        raise InputError(f"{path}: not a valid DXF file ({_damage(exc)}): {exc}") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a valid DXF file ({exc})") from None
    except OSError as exc:
        if exc.strerror is None and "not a DXF" in str(exc):   # ezdxf's own check
            raise InputError(f"{path}: not a DXF file (no DXF header or section found)") from None
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    except (MemoryError, RecursionError):
        raise
    except Exception as exc:        # binary DXF garbage, bad group codes: ezdxf raises many types
        raise InputError(f"{path}: not a valid DXF file ({type(exc).__name__}: {str(exc)[:120]})") from None
    n_entities = len(doc.entitydb)
    if n_entities > MAX_ENTITIES:
        raise InputError(f"{path}: {n_entities:,} entities, more than the limit of {MAX_ENTITIES:,} "
                         "for a pattern file")
    if line not in LINES:
        raise InputError(f"--line {line!r}: use 'sew' or 'cut'")
    if any(_is_piece_block(b) for b in doc.blocks):
        return _read_aama(doc, ctx, units, rel_tol, line)
    return _read_plain(doc, ctx, units, rel_tol, line)
