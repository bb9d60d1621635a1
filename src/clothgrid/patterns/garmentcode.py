"""Read pattern pieces from GarmentCode's pattern specification JSON.

The format of GarmentCode and its predecessor Garment-Pattern-Generator
(``*_specification.json``)::

    {"pattern": {"panels": {"front": {"vertices": [[x, y], ...],
                                      "edges": [{"endpoints": [0, 1]},
                                                {"endpoints": [1, 2],
                                                 "curvature": {"type": "cubic",
                                                               "params": [[0.3, 0.1], [0.7, 0.1]]}},
                                                ...],
                                      "translation": [x, y, z], "rotation": [rx, ry, rz]},
                            ...},
                 "stitches": [...]},
     "properties": {"units_in_meter": 100, "curvature_coords": "relative"}}

Every panel is a piece, named by its key, its edges forming one closed loop
(in any order; each edge may run either way). Edge curvature:

- absent: a straight edge;
- ``{"type": "quadratic", "params": [[u, v]]}`` or the legacy ``[u, v]``: a
  quadratic Bézier with that control point;
- ``{"type": "cubic", "params": [[u1, v1], [u2, v2]]}``: a cubic Bézier;
- ``{"type": "circle", "params": [radius, large_arc, right]}``: a circular arc
  as in SVG (``right`` is the sweep flag in the panel's y-up frame: the arc
  bulges to the right of the edge's direction when it is the short arc).

With ``"curvature_coords": "relative"`` (the default) a control point
``[u, v]`` is ``start + u (end - start) + v R90 (end - start)``, ``R90`` the
counter-clockwise quarter turn; with ``"absolute"`` it is a panel point.
``units_in_meter`` gives the units (100: centimetres, GarmentCode's default
when missing). The 2D panel outline is read in the panel's own frame;
``translation`` and ``rotation`` (its 3D placement) are kept in
:attr:`Piece.meta`. The panel vertices are the piece's turn points.
"""

from __future__ import annotations

import math
from pathlib import Path
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from ..limits import MAX_ENTITIES
from .piece import Piece, PieceFailure, Pieces, pattern_pieces, piece_failure, piece_from_primitives
from .sampling import DEFAULT_REL_TOL, Bezier, EllipseArc, Primitive

__all__ = ["read_garmentcode", "is_garmentcode", "read_garment_spec", "GarmentSpec", "SpecPanel",
           "SpecEdge", "SpecStitch"]


def is_garmentcode(data: Any) -> bool:
    """Does parsed JSON look like a GarmentCode pattern (a ``pattern`` with ``panels``)?"""
    return isinstance(data, dict) and isinstance(data.get("pattern"), dict) \
        and "panels" in data["pattern"]


def _point(v: Any, what: str) -> np.ndarray:
    if isinstance(v, (list, tuple)) and any(isinstance(x, (bool, str)) for x in v):
        raise InputError(f"{what} must be a point [x, y] of numbers, not {v!r:.60}")
    try:
        p = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a point [x, y], not {v!r}") from None
    if p.shape != (2,) or not np.isfinite(p).all():
        raise InputError(f"{what} must be a finite point [x, y], not {v!r}")
    return p


def _rel_to_abs(a: np.ndarray, b: np.ndarray, uv: np.ndarray) -> np.ndarray:
    d = b - a
    return a + uv[0] * d + uv[1] * np.array([-d[1], d[0]])


def _circle(a: np.ndarray, b: np.ndarray, params: Any, what: str) -> Primitive:
    if not isinstance(params, (list, tuple)) or len(params) != 3:
        raise InputError(f"{what}: circle params must be [radius, large_arc, right], not {params!r}")
    try:
        r = float(params[0])
    except (TypeError, ValueError):
        raise InputError(f"{what}: the circle radius must be a number, not {params[0]!r}") from None
    large, sweep = bool(params[1]), bool(params[2])
    chord = float(np.hypot(*(b - a)))
    if not (math.isfinite(r) and r > 0) or chord == 0:
        raise InputError(f"{what}: a circle edge needs a positive radius and distinct end points")
    r = max(r, chord / 2)                         # SVG rule: too small a radius is scaled up
    # SVG arc centre parametrisation (F.6.5) with rx = ry = r, no rotation
    mid = 0.5 * (a + b)
    half = 0.5 * (a - b)
    h = math.sqrt(max(r * r - half @ half, 0.0)) / math.sqrt(half @ half)
    sign = -1.0 if large == sweep else 1.0
    c = mid + sign * h * np.array([half[1], -half[0]])
    t0 = math.atan2(a[1] - c[1], a[0] - c[0])
    t1 = math.atan2(b[1] - c[1], b[0] - c[0])
    delta = t1 - t0
    if sweep and delta < 0:
        delta += 2 * math.pi
    elif not sweep and delta > 0:
        delta -= 2 * math.pi
    return EllipseArc(c, np.array([r, 0.0]), np.array([0.0, r]), t0, t0 + delta,
                      start_point=a, end_point=b)


def _edge(a: np.ndarray, b: np.ndarray, curv: Any, absolute: bool, what: str) -> Primitive:
    if curv is None:
        return Bezier(np.array([a, b]))

    def ctrl(p: Any, k: int) -> np.ndarray:
        q = _point(p, f"{what}: control point {k}")
        return q if absolute else _rel_to_abs(a, b, q)

    if isinstance(curv, list):                    # legacy: one quadratic control point
        return Bezier(np.array([a, ctrl(curv, 0), b]))
    if not isinstance(curv, dict):
        raise InputError(f"{what}: 'curvature' must be an object or [x, y], not {curv!r}")
    kind, params = curv.get("type"), curv.get("params")
    if kind == "quadratic":
        if not isinstance(params, list) or len(params) != 1:
            raise InputError(f"{what}: quadratic params must be one control point [[x, y]]")
        return Bezier(np.array([a, ctrl(params[0], 0), b]))
    if kind == "cubic":
        if not isinstance(params, list) or len(params) != 2:
            raise InputError(f"{what}: cubic params must be two control points [[x, y], [x, y]]")
        return Bezier(np.array([a, ctrl(params[0], 0), ctrl(params[1], 1), b]))
    if kind == "circle":
        return _circle(a, b, params, what)
    raise InputError(f"{what}: unknown curvature type {kind!r} (known: quadratic, cubic, circle)")


def _loop(edges: list[Any], nverts: int, what: str) -> list[tuple[int, int, Any, bool]]:
    """Order the edges into one loop: ``(start, end, edge, reversed)``."""
    items = []
    for k, e in enumerate(edges):
        if not isinstance(e, dict) or "endpoints" not in e:
            raise InputError(f"{what}: edge {k} must be an object with 'endpoints'")
        ep = e["endpoints"]
        if not isinstance(ep, list) or len(ep) != 2 or not all(
                isinstance(i, int) and not isinstance(i, bool) for i in ep):
            raise InputError(f"{what}: edge {k} 'endpoints' must be two vertex indices, not {ep!r}")
        if not all(0 <= i < nverts for i in ep) or ep[0] == ep[1]:
            raise InputError(f"{what}: edge {k} endpoints {ep} must be two different indices "
                             f"in 0..{nverts - 1}")
        items.append((ep[0], ep[1], e))
    if len(items) > MAX_ENTITIES:
        raise InputError(f"{what}: {len(items):,} edges, more than the limit of {MAX_ENTITIES:,}")
    # the edges at each vertex, in file order: the walk takes the first unused one (linear time)
    at: dict[int, list[int]] = {}
    for k, (s, t, _) in enumerate(items):
        at.setdefault(s, []).append(k)
        at.setdefault(t, []).append(k)
    pos = {v: 0 for v in at}
    used = [False] * len(items)
    used[0] = True
    loop = [(items[0][0], items[0][1], items[0][2], False)]
    for _ in range(len(items) - 1):
        cur = loop[-1][1]
        ks = at.get(cur, [])
        p = pos.get(cur, 0)
        while p < len(ks) and used[ks[p]]:
            p += 1
        pos[cur] = p
        if p == len(ks):
            raise InputError(f"{what}: the edges do not form one closed loop (no edge continues "
                             f"from vertex {cur})")
        k = ks[p]
        used[k] = True
        s, t, e = items[k]
        loop.append((s, t, e, False) if s == cur else (t, s, e, True))
    if loop[-1][1] != loop[0][0]:
        raise InputError(f"{what}: the edges do not close: the loop ends at vertex "
                         f"{loop[-1][1]}, not at its start {loop[0][0]}")
    return loop


def _reverse_curvature(curv: Any) -> Any:
    """The curvature of the same edge run from end to start (relative coordinates).

    Malformed curvature (strings, nulls) is returned as it is, for :func:`_edge` to report.
    """
    try:
        return _reversed_curvature(curv)
    except (TypeError, ValueError, IndexError, KeyError):
        return curv


def _reversed_curvature(curv: Any) -> Any:
    if curv is None:
        return None
    if isinstance(curv, list):
        return [1.0 - curv[0], -curv[1]] if len(curv) == 2 else curv
    if isinstance(curv, dict):
        kind, params = curv.get("type"), curv.get("params")
        if kind in ("quadratic", "cubic") and isinstance(params, list):
            rev = [[1.0 - p[0], -p[1]] if isinstance(p, list) and len(p) == 2 else p
                   for p in params]
            return {**curv, "params": rev[::-1]}
        if kind == "circle" and isinstance(params, list) and len(params) == 3:
            return {**curv, "params": [params[0], params[1], not bool(params[2])]}
    return curv


def _panel_names(pattern: dict[str, Any], panels: dict[str, Any], where: str) -> list[str]:
    """The panels' names in the file's ``panel_order``, then the others in file order.

    ``panel_order`` is optional; when given it must be a list of panel names
    (strings). A name that is not a panel is passed over (the order only sorts
    the panels), but an entry that is not a string (``[1]``, ``{"x": 2}``) is
    a malformed file.

    Raises
    ------
    InputError
        ``panel_order`` is not a list, or one of its entries is not a string.
    """
    order = pattern.get("panel_order")
    if order is None:
        order = []
    if not isinstance(order, list):
        raise InputError(f"{where}: pattern.panel_order must be a list of panel names, "
                         f"not {type(order).__name__}")
    for k, n in enumerate(order):
        if not isinstance(n, str):
            raise InputError(f"{where}: pattern.panel_order must be a list of panel names (strings); "
                             f"entry {k} is {_json_snippet(n)}")
    names = list(dict.fromkeys(n for n in order if n in panels))
    return names + [n for n in panels if n not in names]


def _json_snippet(value: Any, size: int = 40) -> str:
    """``value`` as short JSON text for a message."""
    import json

    try:
        text = json.dumps(value)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= size else text[:size] + "..."


def read_garmentcode(path: str | Path, *, units: str | None = None,
                     rel_tol: float = DEFAULT_REL_TOL, data: Any = None) -> Pieces:
    """Read every panel of a GarmentCode pattern JSON as a :class:`Piece` (mm).

    Parameters
    ----------
    path : str or Path
        The JSON file.
    units : str, optional
        Read the coordinates in these units instead of ``units_in_meter``.
    rel_tol : float
        Chord tolerance relative to each piece's size (default ``1e-7``).
    data : object, optional
        The already parsed JSON (the file is then not read again).

    Raises
    ------
    InputError
        Invalid JSON, no panels, a malformed panel or edge, edges that do not
        form a loop, bad units, in every panel (no panel could be made). A
        panel that cannot be made is listed in the answer's ``failed``.
    """
    from ..units import unit_to_mm

    path = Path(path)
    where = str(path)
    if data is None:
        from ..limits import read_json_file

        data = read_json_file(path)
    if not is_garmentcode(data):
        raise InputError(f"{where}: not a GarmentCode pattern (expected {{\"pattern\": "
                         "{\"panels\": {...}}}})")
    props = data.get("properties") or {}
    if not isinstance(props, dict):
        raise InputError(f"{where}: 'properties' must be an object")
    notes: list[str] = []
    if units is not None:
        scale, unit = unit_to_mm(units, what="--units"), units
        notes.append(f"units: {units} (given)")
    else:
        uim = props.get("units_in_meter")
        if uim is None:
            uim = 100
            notes.append("units: centimetres (no units_in_meter: GarmentCode's default)")
        else:
            notes.append(f"units: units_in_meter {uim}")
        if isinstance(uim, bool) or not isinstance(uim, (int, float)) or not (
                math.isfinite(uim) and uim > 0):
            raise InputError(f"{where}: properties.units_in_meter must be a positive number, "
                             f"not {uim!r}")
        scale = 1000.0 / float(uim)
        unit = {1000: "mm", 100: "cm", 10: "dm", 1: "m"}.get(float(uim), f"1/{uim:g} m")
    coords = props.get("curvature_coords", "relative")
    if coords not in ("relative", "absolute"):
        raise InputError(f"{where}: properties.curvature_coords must be 'relative' or "
                         f"'absolute', not {coords!r}")
    panels = data["pattern"]["panels"]
    if not isinstance(panels, dict) or not panels:
        raise InputError(f"{where}: the pattern has no panels")
    names = _panel_names(data["pattern"], panels, where)
    pieces: list[Piece] = []
    failed: list[PieceFailure] = []
    for name in names:
        panel = panels[name]
        what = f"{where}: panel {name!r}"
        if panel is None:
            continue
        try:
            if not isinstance(panel, dict):
                raise InputError(f"{what} must be an object with 'vertices' and 'edges'")
            verts = panel.get("vertices")
            edges = panel.get("edges")
            if not isinstance(verts, list) or not isinstance(edges, list) or not edges:
                raise InputError(f"{what} needs a list of 'vertices' and a non-empty list of 'edges'")
            V = np.array([_point(v, f"{what}: vertex {k}") for k, v in enumerate(verts)]) \
                if verts else np.zeros((0, 2))
            prims: list[Primitive] = []
            for s, t, e, rev in _loop(edges, len(V), what):
                curv = e.get("curvature")
                if rev:
                    if coords == "relative":
                        curv = _reverse_curvature(curv)
                    elif isinstance(curv, dict) and curv.get("type") in ("quadratic", "cubic"):
                        curv = {**curv, "params": list(curv.get("params") or [])[::-1]}
                    elif isinstance(curv, dict) and curv.get("type") == "circle":
                        curv = _reverse_curvature(curv)
                prims.append(_edge(V[s], V[t], curv, coords == "absolute",
                                   f"{what}: edge {e.get('endpoints')}"))
            prims_mm = []
            for p in prims:
                if isinstance(p, Bezier):
                    prims_mm.append(Bezier(p.ctrl * scale))
                else:
                    prims_mm.append(EllipseArc(p.center * scale, p.a * scale, p.b * scale, p.t0, p.t1,
                                               p.start_point * scale, p.end_point * scale))
            corner_pts = [V[s] * scale for s, *_ in _loop(edges, len(V), what)]
            meta = {k: panel[k] for k in ("translation", "rotation") if k in panel}
            # each spec edge's identity and direction in the chained loop (the outline may be
            # reversed afterwards to run counter-clockwise: see read_garment_spec for seams)
            pos = {id(e): k for k, e in enumerate(edges)}
            meta["edge_loop"] = [[pos[id(e)], bool(rev)] for _, _, e, rev in _loop(edges, len(V), what)]
            pieces.append(piece_from_primitives(
                str(name), prims_mm, rel_tol=rel_tol, turn_points=corner_pts, where=f"{where}: ",
                units=unit, source="garmentcode", notes=tuple(notes), meta=meta))
        except InputError as exc:
            failed.append(piece_failure(str(name), exc, where))
    return pattern_pieces(pieces, failed, where, f"{where}: the pattern has no panels")


# --------------------------------------------------------------------------- whole garments


@dataclass(frozen=True, eq=False)
class SpecEdge:
    """One edge of a GarmentCode panel, as the file gives it.

    ``index`` is its position in the panel's ``edges`` list (what stitches refer
    to); it runs from vertex ``start`` to vertex ``end`` (the ``endpoints``
    order), and ``curve`` is that curve in millimetres, in that direction.
    """

    index: int
    start: int
    end: int
    curve: Primitive
    label: str | None = None


@dataclass(frozen=True, eq=False)
class SpecPanel:
    """A GarmentCode panel with its edges kept as the file numbers and orients them.

    ``loop`` is the closed chain of the edges: ``(edge index, reversed)`` in
    chain order, starting with edge 0 in its own direction (the chain's
    direction is the panel's: its right side faces where GarmentCode's
    ``right side to right side`` stitching expects). ``vertices`` are in
    millimetres; ``translation`` in millimetres, ``rotation`` the XYZ Euler
    angles in degrees (``R = Rz Ry Rx``, pygarment ``rotation.euler_xyz_to_R``).
    """

    name: str
    vertices: np.ndarray
    edges: tuple[SpecEdge, ...]
    loop: tuple[tuple[int, bool], ...]
    translation: np.ndarray
    rotation: np.ndarray
    label: str | None = None


@dataclass(frozen=True)
class SpecStitch:
    """A stitch: edge ``a`` = ``(panel, edge index)`` sewn to edge ``b``.

    ``same_direction`` is False for GarmentCode's default (the edges are joined
    in opposite directions: ``a``'s end meets ``b``'s start) and True for a
    stitch that carries ``"right_wrong"`` (``a``'s start meets ``b``'s start).
    """

    index: int
    a: tuple[str, int]
    b: tuple[str, int]
    same_direction: bool = False

    @property
    def dart(self) -> bool:
        """Both edges on one panel."""
        return self.a[0] == self.b[0]


@dataclass(frozen=True, eq=False)
class GarmentSpec:
    """A GarmentCode (or Garment-Pattern-Generator) specification: panels and stitches (mm)."""

    path: Path
    panels: dict[str, SpecPanel]
    stitches: tuple[SpecStitch, ...]
    units: str
    mm_per_unit: float
    notes: tuple[str, ...] = field(default=())


def _stitch_side(side: Any, panels: dict[str, SpecPanel], what: str) -> tuple[str, int]:
    if not isinstance(side, dict) or "panel" not in side or "edge" not in side:
        raise InputError(f"{what} must be {{\"panel\": NAME, \"edge\": INDEX}}, not {side!r}")
    name, edge = side["panel"], side["edge"]
    if not isinstance(name, str) or name not in panels:
        raise InputError(f"{what}: no panel named {name!r}")
    if isinstance(edge, bool) or not isinstance(edge, int) or not 0 <= edge < len(panels[name].edges):
        raise InputError(f"{what}: panel {name!r} has no edge {edge!r} (it has "
                         f"{len(panels[name].edges)} edges, 0..{len(panels[name].edges) - 1})")
    return str(name), int(edge)


def _read_stitches(raw: Any, panels: dict[str, SpecPanel], where: str) -> tuple[SpecStitch, ...]:
    """GarmentCode's ``[A, B]`` / ``[A, B, "right_wrong"]`` and the older ``{"from": A, "to": B}``."""
    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise InputError(f"{where}: 'stitches' must be a list")
    out = []
    for k, st in enumerate(raw):
        what = f"{where}: stitch {k}"
        same = False
        if isinstance(st, dict) and "from" in st and "to" in st:
            a, b = st["from"], st["to"]
            same = bool(st.get("right_wrong", False))
        elif isinstance(st, (list, tuple)) and len(st) in (2, 3):
            a, b = st[0], st[1]
            if len(st) == 3:
                if st[2] != "right_wrong":
                    raise InputError(f"{what}: the third element must be \"right_wrong\", not {st[2]!r}")
                same = True
        else:
            raise InputError(f"{what} must be [A, B], [A, B, \"right_wrong\"] or "
                             f"{{\"from\": A, \"to\": B}}, not {st!r}")
        sa = _stitch_side(a, panels, f"{what}, first side")
        sb = _stitch_side(b, panels, f"{what}, second side")
        if sa == sb:
            raise InputError(f"{what} sews edge {sa[1]} of panel {sa[0]!r} to itself")
        out.append(SpecStitch(k, sa, sb, same))
    return tuple(out)


def read_garment_spec(path: str | Path, *, units: str | None = None) -> GarmentSpec:
    """Read a GarmentCode specification as a whole garment: panels, edges, stitches, placement.

    Unlike :func:`read_garmentcode` (one outline per panel) this keeps every
    edge's index and direction, the stitches and the panels' 3D placement.
    Any malformed panel or stitch is an :class:`InputError` (a garment needs
    them all).
    """
    from ..units import unit_to_mm

    path = Path(path)
    where = str(path)
    from ..limits import read_json_file

    data = read_json_file(path)
    if not is_garmentcode(data):
        raise InputError(f"{where}: not a GarmentCode specification (expected {{\"pattern\": "
                         "{\"panels\": {...}, \"stitches\": [...]}}})")
    props = data.get("properties") or {}
    if not isinstance(props, dict):
        raise InputError(f"{where}: 'properties' must be an object")
    notes: list[str] = []
    if units is not None:
        scale, unit = unit_to_mm(units, what="--units"), units
    else:
        uim = props.get("units_in_meter", 100)
        if isinstance(uim, bool) or not isinstance(uim, (int, float)) or not (math.isfinite(uim) and uim > 0):
            raise InputError(f"{where}: properties.units_in_meter must be a positive number, not {uim!r}")
        if "units_in_meter" not in props:
            notes.append("units: centimetres (no units_in_meter: GarmentCode's default)")
        scale = 1000.0 / float(uim)
        unit = {1000: "mm", 100: "cm", 10: "dm", 1: "m"}.get(float(uim), f"1/{uim:g} m")
    absolute = props.get("curvature_coords", "relative") == "absolute"
    raw_panels = data["pattern"]["panels"]
    if not isinstance(raw_panels, dict) or not raw_panels:
        raise InputError(f"{where}: the pattern has no panels")
    names = _panel_names(data["pattern"], raw_panels, where)
    panels: dict[str, SpecPanel] = {}
    for name in names:
        panel = raw_panels[name]
        what = f"{where}: panel {name!r}"
        if not isinstance(panel, dict):
            raise InputError(f"{what} must be an object with 'vertices' and 'edges'")
        verts, edges = panel.get("vertices"), panel.get("edges")
        if not isinstance(verts, list) or not isinstance(edges, list) or not edges:
            raise InputError(f"{what} needs a list of 'vertices' and a non-empty list of 'edges'")
        V = np.array([_point(v, f"{what}: vertex {k}") for k, v in enumerate(verts)]).reshape(-1, 2)
        chain = _loop(edges, len(V), what)
        ids = {id(e): k for k, e in enumerate(edges)}
        spec_edges = []
        for k, e in enumerate(edges):
            s, t = e["endpoints"]
            c = _edge(V[s], V[t], e.get("curvature"), absolute, f"{what}: edge {k}")
            c = Bezier(c.ctrl * scale, c.weights) if isinstance(c, Bezier) else EllipseArc(
                c.center * scale, c.a * scale, c.b * scale, c.t0, c.t1, c.start_point * scale,
                c.end_point * scale)
            label = e.get("label")
            spec_edges.append(SpecEdge(k, int(s), int(t), c, label if isinstance(label, str) else None))
        loop = tuple((ids[id(e)], bool(rev)) for _, _, e, rev in chain)
        if len(loop) != len(edges):
            raise InputError(f"{what}: the edges do not form one closed loop")

        def vec(key: str, default: list[float]) -> np.ndarray:
            v = panel.get(key, default)
            try:
                a = np.asarray(v, dtype=np.float64)
            except (TypeError, ValueError):
                a = np.zeros(0)
            if a.shape != (3,) or not np.isfinite(a).all():
                raise InputError(f"{what}: '{key}' must be three numbers, not {v!r}")
            return a

        panels[str(name)] = SpecPanel(str(name), V * scale, tuple(spec_edges), loop,
                                      vec("translation", [0.0, 0.0, 0.0]) * scale,
                                      vec("rotation", [0.0, 0.0, 0.0]),
                                      panel.get("label") if isinstance(panel.get("label"), str) else None)
    stitches = _read_stitches(data["pattern"].get("stitches"), panels, where)
    return GarmentSpec(path, panels, stitches, unit, scale, tuple(notes))
