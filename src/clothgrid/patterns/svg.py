"""Read pattern pieces from an SVG file: every closed (sub)path is a piece.

Paths (``<path>``) and the basic shapes ``<rect>``, ``<circle>``, ``<ellipse>``,
``<polygon>``, ``<polyline>`` and ``<line>`` are read, with the ``transform`` of
every element and its groups; ``<defs>``, ``<symbol>``, ``<clipPath>``,
``<mask>``, ``<marker>``, ``<pattern>`` and elements with ``display="none"``
are skipped unless a ``<use>`` draws them. A subpath is closed when it ends
with ``Z`` or at its start point. Open ones (open paths, polylines and lines)
that meet end to end (within :data:`JOIN_MM`) are joined into the outline
around them; the rest (grain lines, notches) are left out. Path data is
parsed by svgpathtools; lines, quadratic and cubic
Béziers and elliptical arcs are then sampled exactly (see
:mod:`clothgrid.patterns.sampling`).

Not every closed outline is a piece: text converted to paths, arrows, notches,
drill holes, marks drawn on a piece and the seam-allowance outline around a
piece are told apart by :func:`clothgrid.patterns.annotations.classify` (the
element's and its groups' ``class``, ``id``, ``inkscape:label`` and text cues
first, geometry second); :func:`read_svg` returns the pieces with the skipped
outlines in ``.skipped``.

Units: the outermost ``<svg>``'s ``width`` and ``height`` (``mm``, ``cm``,
``in``, ``pt``, ``pc``, ``px`` at 96 per inch, ``Q``, or no unit = ``px``) and
its ``viewBox`` (with ``preserveAspectRatio``) give the size of a user unit.
Without an absolute ``width``/``height`` a user unit is a CSS pixel (1/96
in), unless ``units`` says otherwise. Other units (``em``, ``ex``, ...) are an
error. The y axis is flipped (SVG's points down): pieces keep their drawn
shape, with the origin at the bottom-left of the page.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from functools import partial
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError
from ..geometry import box_holds, points_in_polygon
from ..limits import MAX_ENTITIES, MAX_NESTING, check_input_file
from .annotations import classified, marked_annotation, structure_hint
from .chains import GAP_MM, GAP_REL, Joined, join_outlines, joined_note, largest_gap
from .fold import attach_fold_lines
from .piece import (Piece, PieceFailure, Pieces, Skipped, cut_instructions, outline_box, piece_failure,
                    piece_from_points, piece_from_primitives, unique_name)
from .sampling import DEFAULT_REL_TOL, Bezier, EllipseArc, Primitive, control_box
from ..units import UNITS, unit_to_mm

__all__ = ["read_svg"]

_SVG_NS = "http://www.w3.org/2000/svg"
_INKSCAPE_LABEL = "{http://www.inkscape.org/namespaces/inkscape}label"
_XLINK_HREF = "{http://www.w3.org/1999/xlink}href"
_FONT = re.compile(r"font-(family|size)\s*:", re.IGNORECASE)
_SKIP = {"defs", "symbol", "clipPath", "mask", "marker", "pattern", "metadata", "title", "desc",
         "style", "script", "linearGradient", "radialGradient", "filter", "text", "foreignObject",
         "namedview"}
_SHAPES = {"path", "rect", "circle", "ellipse", "polygon", "polyline", "line"}
_PATH_CHARS = re.compile(r"[MmZzLlHhVvCcSsQqTtAa0-9eE.,+\-\s]*")
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_CSS_LENGTH = re.compile(r"\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z%]*)\s*")


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


#: The absolute CSS lengths an SVG may use (the project's units less those CSS does not know)
_CSS_UNITS = frozenset(UNITS) - {"um", "dm", "m", "ft", "yd", "mil"}


def _css_length(text: str | None, what: str, where: str) -> tuple[float, str] | None:
    """``(value, unit)`` of an SVG length; None if absent or a percentage."""
    if text is None or not text.strip():
        return None
    m = _CSS_LENGTH.fullmatch(text)
    if m is None:
        raise InputError(f"{where}: invalid {what} {text!r} on the <svg> element")
    value, unit = float(m.group(1)), m.group(2).lower() or "px"
    if unit == "%":
        return None
    if unit not in _CSS_UNITS:
        raise InputError(f"{where}: unknown unit {m.group(2)!r} in the <svg> {what} {text!r}: "
                         "use mm, cm, in, pt, pc, px or Q (an absolute length)")
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{where}: the <svg> {what} {text!r} must be positive")
    return value, unit


_PLAIN_NUMBERS = re.compile(r"[0-9eE.,+\-\s]*")


def _numbers(text: str, what: str, where: str) -> list[float]:
    """The numbers of an SVG number list (``points``, ``viewBox``), separated by spaces and/or commas.

    Plain lists (every number set apart, as exporters write them) are converted by
    NumPy in one go; compact forms (``1-2``, ``.5.5``) and errors go through the regex.
    """
    if _PLAIN_NUMBERS.fullmatch(text):
        try:
            return np.array(text.replace(",", " ").split(), dtype=np.float64).tolist()
        except ValueError:
            pass                                     # 1-2, .5.5, 1e, ...: read below
    stripped = re.sub(r"[\s,]+", " ", text).strip()
    nums = _NUMBER.findall(text)
    if stripped and re.sub(_NUMBER, "", stripped).replace(" ", ""):
        raise InputError(f"{where}: invalid {what} {text[:60]!r}")
    return [float(x) for x in nums]


_INKSCAPE_VERSION = "{http://www.inkscape.org/namespaces/inkscape}version"


def _px_per_inch(root: ET.Element, head: bytes) -> tuple[float, str]:
    """How many px make an inch in the file (``head``: its first bytes), from the program that wrote
    it: CSS says 96, and Inkscape 0.92 and later, browsers and most programs keep to it; Inkscape up to
    0.91 (and Sodipodi) used 90, as did FreeSewing's first (PHP) core, whose layouts scale
    millimetres by 3.54330709 px (their scale box, 10 by 5 cm inside, measures 9.375 by 4.6875 cm
    at 96); Adobe Illustrator uses 72 (1 px = 1 pt). Returns the count and why (empty for 96)."""
    if b"Adobe Illustrator" in head:
        return 72.0, "Adobe Illustrator wrote it: 72 px an inch"
    version = root.get(_INKSCAPE_VERSION)
    if version:
        m = re.match(r"\s*(\d+)\.(\d+)", version)
        if m and (int(m.group(1)), int(m.group(2))) < (0, 92):
            return 90.0, f"Inkscape {version.split()[0]} wrote it: 90 px an inch"
        return 96.0, ""
    if "freesewing" in (root.get("class") or "").split() or b"xmlns:freesewing" in head:
        return 90.0, "FreeSewing's first core wrote it: 90 px an inch"
    if b"sodipodi:version" in head or b"Sodipodi" in head:
        return 90.0, "Sodipodi wrote it: 90 px an inch"
    return 96.0, ""


def _view_box(el: ET.Element, where: str) -> list[float] | None:
    """An ``<svg>`` element's ``viewBox`` (min-x, min-y, width, height), None where it has none."""
    text = el.get("viewBox")
    if text is None or not text.strip():
        return None
    vb = _numbers(text, "viewBox", where)
    if len(vb) != 4 or not all(math.isfinite(v) for v in vb) or vb[2] <= 0 or vb[3] <= 0:
        raise InputError(f"{where}: invalid viewBox {text!r}: expected 4 numbers min-x min-y width height, "
                         "width and height positive")
    return vb


def _fit(el: ET.Element, vb: list[float], w: float, h: float) -> tuple[float, float, float, float]:
    """How an ``<svg>`` element's ``preserveAspectRatio`` fits its viewBox ``vb`` into ``w`` x ``h``:
    ``(sx, sy, tx, ty)``, a point ``(x, y)`` going to ``(tx + (x - vb_x) sx, ty + (y - vb_y) sy)``."""
    sx, sy = w / vb[2], h / vb[3]
    tx = ty = 0.0
    par = [q for q in (el.get("preserveAspectRatio") or "xMidYMid meet").split() if q != "defer"] or ["xMidYMid"]
    if par[0] != "none":
        sc = max(sx, sy) if len(par) > 1 and par[1] == "slice" else min(sx, sy)
        tx = {"xMin": 0.0, "xMid": 0.5, "xMax": 1.0}.get(par[0][:4], 0.5) * (w - vb[2] * sc)
        ty = {"YMin": 0.0, "YMid": 0.5, "YMax": 1.0}.get(par[0][4:], 0.5) * (h - vb[3] * sc)
        sx = sy = sc
    return sx, sy, tx, ty


def _viewport(root: ET.Element, where: str, units: str | None, head: bytes = b""
              ) -> tuple[np.ndarray, str, str]:
    """The 3x3 map from user units to mm with y up; the file's unit and how it was found. A px is
    1/96 in, or what the program that wrote the file used (:func:`_px_per_inch`)."""
    per_inch, why = _px_per_inch(root, head)
    px_mm = 25.4 / per_inch
    width = _css_length(root.get("width"), "width", where)
    height = _css_length(root.get("height"), "height", where)
    vb = _view_box(root, where)
    if vb is not None:
        if width is None and height is not None:
            width = (height[0] * vb[2] / vb[3], height[1])
        if height is None and width is not None:
            height = (width[0] * vb[3] / vb[2], width[1])
    if width is None or height is None:
        unit = units or "px"
        s = px_mm if units is None else unit_to_mm(unit, what="--units")
        how = (f"user units taken as {unit} (given)" if units else
               f"user units taken as px, 1/{per_inch:g} in (the SVG gives no absolute width and height"
               + (f"; {why})" if why else ")"))
        m = np.diag([s, -s, 1.0])
        if vb is not None:
            m[1, 2] = s * (vb[1] + vb[3])
        return m, unit, how
    w_mm = width[0] * (px_mm if width[1] == "px" else UNITS[width[1]])
    h_mm = height[0] * (px_mm if height[1] == "px" else UNITS[height[1]])
    unit = width[1] if width[1] == height[1] else "mm"
    how = f"from the <svg> width and height ({root.get('width')} x {root.get('height')})"
    if why and (vb is None or "px" in (width[1], height[1])):
        how += f"; {why}"
    if vb is None:
        s = px_mm                              # no viewBox: a user unit is a px
        return np.array([[s, 0, 0], [0, -s, h_mm], [0, 0, 1.0]]), unit, how
    sx, sy, tx, ty = _fit(root, vb, w_mm, h_mm)
    # x_mm = tx + (x - vbx) sx;  y_up = h - (ty + (y - vby) sy)
    m = np.array([[sx, 0.0, tx - vb[0] * sx],
                  [0.0, -sy, h_mm - ty + vb[1] * sy],
                  [0.0, 0.0, 1.0]])
    return m, unit, how


def _inner_length(text: str | None, whole: float, what: str, where: str) -> float:
    """A nested ``<svg>``'s ``x``, ``y``, ``width`` or ``height`` in its parent's user units: a number,
    an absolute length (96 px an inch, one px a user unit), or a percentage of ``whole``."""
    if text is None or not text.strip():
        return whole if what in ("width", "height") else 0.0
    m = _CSS_LENGTH.fullmatch(text)
    unit = (m.group(2).lower() if m else "") or "px"
    if m is None or not (unit == "%" or unit in _CSS_UNITS):
        raise InputError(f"{where}: invalid {what} {text!r} on a nested <svg> element")
    value = float(m.group(1))
    if unit == "%":
        return value / 100.0 * whole
    return value if unit == "px" else value * UNITS[unit] * 96.0 / 25.4


def _root_size(root: ET.Element, where: str) -> tuple[float, float]:
    """The outermost viewport's size in its user units (what a nested ``<svg>``'s percentages are of):
    its ``viewBox``'s, else its ``width`` and ``height`` (100 where absent or a percentage)."""
    vb = _view_box(root, where)          # (read by _viewport first: valid or absent)
    if vb is not None:
        return vb[2], vb[3]
    out = []
    for k in ("width", "height"):
        try:
            got = _inner_length(root.get(k), 100.0, k, where)
        except InputError:
            got = 100.0
        out.append(got if math.isfinite(got) and got > 0 else 100.0)
    return out[0], out[1]


def _nested_viewport(el: ET.Element, size: tuple[float, float], where: str
                     ) -> tuple[np.ndarray, tuple[float, float]]:
    """A nested ``<svg>``: the 3x3 map from its user units to its parent's (its ``x``, ``y``, and its
    ``viewBox`` fitted into its ``width`` x ``height`` as ``preserveAspectRatio`` says; no ``viewBox``:
    a shift), and its viewport's size in its own user units. ``size``: the parent's viewport."""
    x = _inner_length(el.get("x"), size[0], "x", where)
    y = _inner_length(el.get("y"), size[1], "y", where)
    w = _inner_length(el.get("width"), size[0], "width", where)
    h = _inner_length(el.get("height"), size[1], "height", where)
    shift = np.array([[1.0, 0.0, x], [0.0, 1.0, y], [0.0, 0.0, 1.0]])
    vb = _view_box(el, f"{where}: a nested <svg>")
    if vb is None:
        return shift, (w, h)
    if not (w > 0 and h > 0 and math.isfinite(w) and math.isfinite(h)):
        raise InputError(f"{where}: a nested <svg> with a viewBox must have a positive width and height")
    sx, sy, tx, ty = _fit(el, vb, w, h)
    fit = np.array([[sx, 0.0, tx - vb[0] * sx], [0.0, sy, ty - vb[1] * sy], [0.0, 0.0, 1.0]])
    return shift @ fit, (vb[2], vb[3])


def _transform(el: ET.Element, where: str) -> np.ndarray:
    text = el.get("transform")
    if not text:
        return np.eye(3)
    from svgpathtools.parser import parse_transform

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                m = parse_transform(text, strict=True)
            except TypeError:                         # svgpathtools < 1.7: no strict mode
                m = parse_transform(text)
            return np.asarray(m, dtype=np.float64)
    except (ValueError, TypeError, IndexError) as exc:
        raise InputError(f"{where}: invalid transform {text!r} on <{_local(el.tag)}> ({exc})") from None


def _hidden(el: ET.Element) -> bool:
    if el.get("display", "").strip() == "none":
        return True
    style = el.get("style", "")
    return bool(re.search(r"(^|;)\s*display\s*:\s*none", style))


def _attr(el: ET.Element, name: str, where: str, default: float | None = None) -> float:
    text = el.get(name)
    if text is None or not text.strip():
        if default is None:
            raise InputError(f"{where}: <{_local(el.tag)}> has no {name}")
        return default
    m = _CSS_LENGTH.fullmatch(text)
    if m is None or (m.group(2) or "px").lower() not in ("px", ""):
        raise InputError(f"{where}: <{_local(el.tag)}> {name}={text!r}: expected a number in "
                         "user units")
    return float(m.group(1))


def _polygon_points(el: ET.Element, m: np.ndarray, where: str) -> tuple[np.ndarray, bool] | None:
    """The points of a ``<polygon>`` or ``<polyline>`` (transformed by ``m``) and whether they close.

    None when there are fewer than 2 points (nothing drawn). A polygon is closed;
    a polyline when it ends at its start. Read without svgpathtools (one array,
    not a segment object per point): a polygon of 10^6 points takes a second.
    """
    tag = _local(el.tag)
    nums = _numbers(el.get("points", ""), "points", where)
    if len(nums) % 2:
        raise InputError(f"{where}: <{tag}> has an odd number of coordinates in 'points'")
    if len(nums) < 4:
        return None
    xy = np.asarray(nums, dtype=np.float64).reshape(-1, 2)
    with np.errstate(over="ignore", invalid="ignore"):
        pts = xy @ m[:2, :2].T + m[:2, 2]
    if tag == "polygon":
        return pts, True
    finite = pts[np.isfinite(pts).all(axis=1)]
    size = float(np.hypot(*np.ptp(finite, axis=0))) if len(finite) else 0.0
    return pts, size > 0 and float(np.linalg.norm(pts[-1] - pts[0])) <= 1e-9 * size


def _line_ends(el: ET.Element, m: np.ndarray, where: str) -> np.ndarray | None:
    """The two ends of a ``<line>`` (transformed by ``m``), or None where they are one point."""
    xy = np.array([[_attr(el, "x1", where, 0.0), _attr(el, "y1", where, 0.0)],
                   [_attr(el, "x2", where, 0.0), _attr(el, "y2", where, 0.0)]])
    if np.array_equal(xy[0], xy[1]):
        return None
    with np.errstate(over="ignore", invalid="ignore"):
        return xy @ m[:2, :2].T + m[:2, 2]


def _straight_prims(pts: np.ndarray) -> list[Primitive]:
    """The straight segments between consecutive points (an open polyline or a line)."""
    return [Bezier(pts[k:k + 2].copy()) for k in range(len(pts) - 1)]


def _rect_geometry(el: ET.Element, where: str) -> tuple[float, float, float, float, float, float] | None:
    """``(x, y, width, height, rx, ry)`` of a ``<rect>``, the radii as SVG clamps them (``auto``:
    the other one; at most half the side), or None when it draws nothing (no width or height)."""
    w, h = _attr(el, "width", where, 0.0), _attr(el, "height", where, 0.0)
    if w <= 0 or h <= 0:
        return None
    rx_t, ry_t = el.get("rx"), el.get("ry")
    rx = _attr(el, "rx", where, 0.0) if rx_t not in (None, "auto") else None
    ry = _attr(el, "ry", where, 0.0) if ry_t not in (None, "auto") else None
    rx, ry = (rx if rx is not None else ry or 0.0), (ry if ry is not None else rx or 0.0)
    x, y = _attr(el, "x", where, 0.0), _attr(el, "y", where, 0.0)
    return x, y, w, h, min(max(rx, 0.0), w / 2), min(max(ry, 0.0), h / 2)


def _rect_corners(el: ET.Element, m: np.ndarray, where: str) -> np.ndarray | None:
    """The four corners (transformed by ``m``) of a ``<rect>`` with square corners, or None
    (rounded corners: read as path data by :func:`_shape_d`; no width or height: nothing drawn).

    A polygon, not four line primitives: a file of 10^5 small rectangles is read in seconds.
    """
    g = _rect_geometry(el, where)
    if g is None:
        return None
    x, y, w, h, rx, ry = g
    if rx > 0 and ry > 0:
        return None
    xy = np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]])
    with np.errstate(over="ignore", invalid="ignore"):
        return xy @ m[:2, :2].T + m[:2, 2]


def _shape_d(el: ET.Element, where: str) -> str | None:
    """Path data of a ``<path>`` or a rounded ``<rect>`` (None if it draws nothing; polygons,
    polylines, square rects, circles and ellipses are read by :func:`_polygon_points`,
    :func:`_rect_corners` and :func:`_ellipse_prims`)."""
    tag = _local(el.tag)
    if tag == "path":
        return el.get("d") or None
    if tag == "rect":
        g = _rect_geometry(el, where)
        if g is None:
            return None
        x, y, w, h, rx, ry = g                 # rounded: square rects are _rect_corners'
        return (f"M{x + rx!r},{y!r} H{x + w - rx!r} A{rx!r},{ry!r} 0 0 1 {x + w!r},{y + ry!r} "
                f"V{y + h - ry!r} A{rx!r},{ry!r} 0 0 1 {x + w - rx!r},{y + h!r} H{x + rx!r} "
                f"A{rx!r},{ry!r} 0 0 1 {x!r},{y + h - ry!r} V{y + ry!r} "
                f"A{rx!r},{ry!r} 0 0 1 {x + rx!r},{y!r} Z")
    if tag in ("circle", "ellipse"):
        return None                       # handled as one exact ellipse primitive
    return None


def _ellipse_prims(el: ET.Element, m: np.ndarray, where: str) -> list[Primitive] | None:
    tag = _local(el.tag)
    cx, cy = _attr(el, "cx", where, 0.0), _attr(el, "cy", where, 0.0)
    if tag == "circle":
        rx = ry = _attr(el, "r", where, 0.0)
    else:
        rx_t, ry_t = el.get("rx"), el.get("ry")
        rx = _attr(el, "rx", where, 0.0) if rx_t not in (None, "auto") else None
        ry = _attr(el, "ry", where, 0.0) if ry_t not in (None, "auto") else None
        rx, ry = (rx if rx is not None else ry or 0.0), (ry if ry is not None else rx or 0.0)
    if rx <= 0 or ry <= 0:
        return None
    A = m[:2, :2]
    c = A @ [cx, cy] + m[:2, 2]
    a, b = A @ [rx, 0.0], A @ [0.0, ry]
    return [EllipseArc(c, a, b, 0.0, 2 * math.pi)]


def _segment_prims(seg, m: np.ndarray) -> Primitive:
    from svgpathtools import Arc, CubicBezier, Line, QuadraticBezier

    A, t = m[:2, :2], m[:2, 2]

    def pt(z: complex) -> np.ndarray:
        return A @ [z.real, z.imag] + t

    if isinstance(seg, Line):
        return Bezier(np.array([pt(seg.start), pt(seg.end)]))
    if isinstance(seg, QuadraticBezier):
        return Bezier(np.array([pt(seg.start), pt(seg.control), pt(seg.end)]))
    if isinstance(seg, CubicBezier):
        return Bezier(np.array([pt(seg.start), pt(seg.control1), pt(seg.control2), pt(seg.end)]))
    if isinstance(seg, Arc):
        rot = complex(math.cos(math.radians(seg.rotation)), math.sin(math.radians(seg.rotation)))
        av, bv = rot * seg.radius.real, rot * 1j * seg.radius.imag
        c = pt(seg.center)
        t0 = math.radians(seg.theta)
        t1 = math.radians(seg.theta + seg.delta)
        return EllipseArc(c, A @ [av.real, av.imag], A @ [bv.real, bv.imag], t0, t1,
                          start_point=pt(seg.start), end_point=pt(seg.end))
    raise InputError(f"unsupported path segment {type(seg).__name__}")


#: Words that name a part of a garment (a piece), and words that name a garment: a text drawn on an
#: unnamed piece names it when it holds one (:func:`_label_score`); part words count double, so that a
#: sleeve labelled "SLEEVE" and "WOVEN BODICE BLOCK" is the sleeve.
_PART_WORDS = frozenset(
    "front back sleeve collar cuff yoke pocket facing waistband gusset hood placket leg bib strap flap "
    "lapel panel dos devant manche col poignet ceinture empiècement poche".split())
_GARMENT_WORDS = frozenset(
    "bodice skirt trouser trousers pants dress shirt blouse jacket coat vest corset hoodie jumpsuit shorts top "
    "tee tshirt jupe pantalon robe chemise veste".split())


#: More texts naming garment pieces than this in one file, and no piece is named after one (a sheet of
#: lettering, not labels): each text is tested against the outlines of the pieces around it.
MAX_LABELS = 2000


def _label_score(text: str) -> int:
    """How strongly a text names a garment piece: 2 a part word, 1 a garment word (module data)."""
    words = re.findall(r"[^\W\d_]+", text.lower())
    return 2 * sum(w in _PART_WORDS for w in words) + sum(w in _GARMENT_WORDS for w in words)


def _text_anchor(el: ET.Element, m: np.ndarray, where: str) -> tuple[str, np.ndarray] | None:
    """A ``<text>`` element's words (its ``<tspan>`` elements' too, spaces collapsed) and its anchor point
    (its own ``x``, ``y``, else its first ``<tspan>``'s, transformed), whatever they say (a label
    naming a piece: :func:`_label_score`; cut instructions), or None where it has no words, more
    than 80 characters, or no readable place."""
    content = " ".join("".join(el.itertext()).split())
    if not content or len(content) > 80:
        return None
    place = el
    if el.get("x") is None and el.get("y") is None:
        place = next((t for t in el.iter() if _local(t.tag) == "tspan" and (t.get("x") or t.get("y"))), el)
    try:
        mt = m @ _transform(el, where)
        xy = [float(v[0]) if (v := _NUMBER.findall(place.get(k) or "0")) else 0.0 for k in ("x", "y")]
    except (InputError, ValueError):
        return None
    point = mt[:2, :2] @ xy + mt[:2, 2]
    return (content, point) if np.isfinite(point).all() else None


def _named_by_labels(pieces: list[Piece], unnamed: set[str], labels: list[tuple[str, np.ndarray]],
                     unique) -> list[Piece]:
    """``pieces`` with those of ``unnamed`` names (no id, label or group name) renamed after the text
    drawn on them that names a garment piece best (:func:`_label_score`, then the shorter): a
    text belongs to the smallest piece around its anchor among those of at least 5 % of the largest's
    area (an arrowhead or a dart drawn closed takes none)."""
    if not unnamed or not labels or not pieces or len(labels) > MAX_LABELS:
        return pieces
    largest = max(p.area for p in pieces)
    big = sorted((k for k, p in enumerate(pieces) if p.area >= 0.05 * largest), key=lambda k: pieces[k].area)
    if not any(pieces[k].name in unnamed for k in big):
        return pieces
    points = np.array([pt for _, pt in labels])
    owner = np.full(len(labels), -1)
    for k in big:                                   # smallest first: a text takes the first around it
        free = owner < 0
        if not free.any():
            break
        inside = np.zeros(len(labels), dtype=bool)
        todo = np.flatnonzero(free)
        for c in range(0, len(todo), 256):           # points x edges at a time: bounded memory
            part = todo[c:c + 256]
            inside[part] = points_in_polygon(points[part], pieces[k].outline)
        owner[inside] = k
    out = list(pieces)
    for k in big:
        if pieces[k].name not in unnamed:
            continue
        texts = [labels[i][0] for i in np.flatnonzero(owner == k)]
        if not texts:
            continue
        best = min(texts, key=lambda t: (-_label_score(t), len(t)))
        old = pieces[k].meta.get("aliases", [])
        meta = {key: v for key, v in pieces[k].meta.items() if key != "group_base"}    # no longer its group's
        out[k] = replace(pieces[k], name=unique(best),
                         notes=pieces[k].notes + (f"named after the text {best!r} drawn on it "
                                                  f"(it had no id or label: {pieces[k].name})",),
                         meta={**meta, "label": best,
                               "aliases": old + [pieces[k].name] if pieces[k].name not in old else old})
    return out


def _shared_group_names(pieces: list[Piece]) -> set[str]:
    """The names of the outlines named after a group (``meta["group_base"]``) that holds several
    pieces side by side: outlines of it whose bounding boxes do not hold one another (a layer
    ``Pattern`` holding a front and a back). A part's sew and cut lines (FreeSewing's), one inside the
    other, are one piece."""
    by: dict[str, list[Piece]] = {}
    for p in pieces:
        if p.meta.get("group_base"):
            by.setdefault(p.meta["group_base"], []).append(p)
    out: set[str] = set()
    for group in by.values():
        if len(group) < 2:
            continue
        boxes = [(p.outline.min(axis=0), p.outline.max(axis=0), 0.01 * p.size) for p in group]
        tops = [a for a, (alo, ahi, _) in enumerate(boxes)
                if not any(b != a and box_holds(blo, bhi, alo, ahi, t) for b, (blo, bhi, t) in enumerate(boxes))]
        if len(tops) >= 2:
            out |= {p.name for p in group}
    return out


def _without_word(name: str, word: str) -> str:
    """``name`` without its word ``word`` (any case; words split at anything but letters and
    digits) and the separators left at its ends: ``A.seamline`` -> ``A``; ``name`` itself where
    nothing else is left."""
    parts = re.split(r"([^A-Za-z0-9]+)", name)      # word, separator, word, ...
    pairs = [("" if k == 0 else parts[k - 1], parts[k]) for k in range(0, len(parts), 2)]
    kept = [(sep, w) for sep, w in pairs if w and w.lower() != word]
    out = "".join(w if k == 0 else sep + w for k, (sep, w) in enumerate(kept))
    return out if out and len(kept) < len([w for _, w in pairs if w]) else name


def _name(el: ET.Element, group: str | None, fallback: str) -> str:
    """The element's name: its ``inkscape:label``; its ``id``, unless a drawing program made it up
    (:data:`_MADE_UP_ID`); (not SVG, but what some pattern programs write on each piece's path:
    ``name="sleeve-front-left"``) its ``name``; its ``group``'s name; its made-up id; else
    ``fallback``."""
    return _own_name(el) or group or (el.get("id") or "").strip() or fallback


def _own_name(el: ET.Element) -> str:
    """The name the element gives itself (:func:`_name`), or "": its ``inkscape:label``, its ``id``
    unless made up, its ``name``."""
    own = (el.get("id") or "").strip()
    for name in (el.get(_INKSCAPE_LABEL), "" if _MADE_UP_ID.match(own) else own, el.get("name")):
        if name and name.strip():
            return name.strip()
    return ""


def _former_names(el: ET.Element, name: str) -> tuple[str, ...]:
    """The element's made-up id (:data:`_MADE_UP_ID`) where ``name`` is not it: what earlier
    releases named the piece (FreeSewing's ``4``, Inkscape's ``path1234``), kept as an alias so
    that ``--piece 4`` and stitches files written for it still find it."""
    own = (el.get("id") or "").strip()
    return (own,) if own and own != name and _MADE_UP_ID.match(own) else ()


#: A group key a drawing program made up (Inkscape's ``g123``, ``layer1`` and its layers' default
#: labels ``Layer 1``, ``Calque 1``, ``Ebene 1``, ``Capa 1``, ``Livello 1``; Illustrator's ``Layer_1``;
#: FreeSewing's ``fs-container``), which names no piece.
_MADE_UP = re.compile(r"^(((g|layer|group|svg|path|calque|ebene|capa|livello)[ _-]?)?\d*|fs-container)$",
                      re.IGNORECASE)


#: An element id a drawing program made up (Inkscape's ``path1234``, ``rect56-3``; FreeSewing 2's
#: running numbers ``4``, ``24``; FreeSewing 3 and 4's ``fs-12``): it yields to the piece's group name,
#: and a piece so named may take the name of the text drawn on it (:func:`_named_by_labels`).
_MADE_UP_ID = re.compile(r"^((path|rect|circle|ellipse|polygon|polyline|line)\d+(-\d+)*|\d+|fs-\d+)$", re.IGNORECASE)


def _group_name(group: str) -> str | None:
    """The nearest of a group path's (``/a/b/c``) keys that is not made up (:data:`_MADE_UP`): the
    name of an outline that has none of its own (Seamly2D's export puts a piece's lines in a group
    with the piece's name, ``Dos``, and no id on the lines)."""
    for key in reversed(group.split("/")):
        if key.strip() and not _MADE_UP.match(key.strip()):
            return _part_name(key.strip())
    return None


#: FreeSewing 3 and 4's groups: ``fs-stack-huey.back`` holding ``fs-stack-huey.back-part-huey.back``
#: (design ``huey``, part ``back``), ``fs-container`` around them all; FreeSewing 2.x betas' ``fs-part-pants``.
_FREESEWING_GROUP = re.compile(r"^fs-(stack-(?P<stack>.+?)(-part-(?P<part>.+))?|part-(?P<only>.+))$")


def _part_name(key: str) -> str:
    """The piece name a group key gives: FreeSewing's ``fs-stack-huey.back-part-huey.back`` is
    ``back`` (the part without its design), ``fs-part-pants`` is ``pants``; any other key itself."""
    m = _FREESEWING_GROUP.match(key)
    if m is None:
        return key
    part = m.group("part") or m.group("only") or m.group("stack")
    return part.split(".", 1)[1] if "." in part.strip(".") else part


_NO_FILL = re.compile(r"(^|;)\s*fill\s*:\s*none\s*(;|$)")


def _text_cue(el: ET.Element) -> bool:
    """Does the element look like text (converted to paths)? An ``aria-label``, an Inkscape
    ``text123`` id, or font attributes (or a font in its style) on an element that is not drawn
    unfilled: Qt's SVG writer (Seamly2D's and Valentina's exports) puts the painter's font on every
    group, the seam lines' (``fill="none"``) as well as the labels' glyphs (filled)."""
    if el.get("aria-label") is not None:
        return True
    style = el.get("style", "") or ""
    if el.get("font-family") or el.get("font-size") or _FONT.search(style):
        if not ((el.get("fill") or "").strip() == "none" or _NO_FILL.search(style)):
            return True
    from .annotations import _TEXT_ID

    return bool(_TEXT_ID.match(el.get("id") or ""))


def _look(el: ET.Element) -> str:
    """How the element is drawn (class, fill, stroke, dashes): marks are drawn unlike pieces."""
    style = dict(kv.split(":", 1) for kv in (el.get("style") or "").split(";") if ":" in kv)
    style = {k.strip(): v.strip() for k, v in style.items()}
    keys = ("fill", "stroke", "stroke-dasharray")
    return ";".join([el.get("class") or ""] + [style.get(k) or el.get(k) or "" for k in keys])


def _tree_size(root: ET.Element) -> tuple[int, int]:
    """(deepest nesting, number of elements) of the tree, without recursion."""
    deepest, count = 0, 0
    stack = [(root, 1)]
    while stack:
        el, d = stack.pop()
        count += 1
        deepest = max(deepest, d)
        stack.extend((c, d + 1) for c in el)
    return deepest, count


def _parse_xml(path: Path) -> ET.Element:
    """The root element of an XML file, parsed in one feed.

    ``ET.parse`` feeds expat 64 KiB at a time, and expat before 2.6 parses a token
    cut by a chunk boundary again from its start with every chunk: quadratic in the
    size of one attribute (10 s for a ``<polygon>`` of 10^6 points, 20 MB). Fed
    whole (the file is at most :data:`~clothgrid.limits.MAX_FILE_BYTES`), it takes
    0.2 s.
    """
    parser = ET.XMLParser()
    parser.feed(path.read_bytes())
    return parser.close()


def read_svg(path: str | Path, *, units: str | None = None,
             rel_tol: float = DEFAULT_REL_TOL, line: str = "sew") -> Pieces:
    """Read the closed paths of an SVG file: the pieces (mm), and the annotations skipped.

    Parameters
    ----------
    path : str or Path
        The SVG file.
    units : str, optional
        Size of a user unit when the file has no absolute ``width``/``height``
        (default ``"px"``, the CSS pixel).
    rel_tol : float
        Chord tolerance relative to each piece's size (default ``1e-7``).
    line : "sew" or "cut"
        Of a piece drawn twice, sew line inside its seam-allowance (cut)
        outline, which to grid (default ``"sew"``).

    Returns
    -------
    Pieces
        The pieces (a list of :class:`Piece`); ``.skipped`` lists the closed
        outlines taken for annotations, with reasons; ``.failed`` the paths
        that would be pieces but cannot be made (:class:`PieceFailure`).

    Raises
    ------
    InputError
        Unreadable or malformed XML (e.g. truncated), not an SVG, invalid path
        data, unknown units, no closed path, or no piece that could be made.
        A path that cannot be made into a piece (fewer than 3 distinct points,
        no area, bad path data) is listed in the answer's ``failed`` instead,
        or in its ``skipped`` when the file marks it as an annotation (a
        degenerate outline of class ``note``, a text glyph, ...).
    """
    path = Path(path)
    where = str(path)
    check_input_file(path)
    try:
        root = _parse_xml(path)
    except ET.ParseError as exc:
        raise InputError(f"{where}: not a well-formed SVG file (truncated?): {exc}") from None
    except OSError as exc:
        raise InputError(f"{where}: cannot read the file ({exc.strerror or exc})") from None
    if _local(root.tag) != "svg":
        raise InputError(f"{where}: not an SVG file (the root element is <{_local(root.tag)}>, "
                         "not <svg>)")
    with open(path, "rb") as f:
        head = f.read(8192)                  # the comments and root of the file: who wrote it
    view, unit, how = _viewport(root, where, units, head)
    root_size = _root_size(root, where)

    pieces: list[Piece] = []
    unmade: list[tuple[PieceFailure, dict]] = []     # (why, meta): failed, or skipped if marked
    names: dict[str, int] = {}
    open_paths = 0
    counter = 0
    opened: list[_Open] = []                         # open subpaths (and lines drawn closed)
    marked: list[Skipped] = []                       # outlines the structure marks as annotations
    drawn: dict[int, _Open] = {}                     # lines drawn closed, by their subpath
    pending: list[tuple] = []                        # closed outlines to make, and failures, in file order
    made_as = {"where": f"{where}: ", "units": unit, "source": "svg", "notes": (f"units: {how}",)}   # every piece's
    labels: list[tuple[str, np.ndarray]] = []        # texts that may name a piece, and their places
    folds: list[np.ndarray] = []                     # the ends of "cut on fold" marks (mm)
    cuts: list[tuple[list, str, np.ndarray]] = []    # cut instructions ("Cut 2 mirrored"), their texts and places
    unnamed: set[str] = set()                        # pieces named by a fallback (piece3, outline)

    def unique(name: str) -> str:
        return unique_name(name, names)

    depth, count = _tree_size(root)
    if depth > MAX_NESTING:
        raise InputError(f"{where}: elements nested {depth} deep, more than the limit of {MAX_NESTING}")
    if count > MAX_ENTITIES:
        raise InputError(f"{where}: {count:,} elements, more than the limit of {MAX_ENTITIES:,}")

    ids = {k: e for e in root.iter() if (k := e.get("id"))}
    fold_paths = _fold_text_paths(root)       # paths whose text says "cut on fold" (FreeSewing 2)
    embedded = _metadata_seams(root)          # <metadata><seams> (a nester's export): the parts' vertices
    corners_of: dict[str, np.ndarray] = {}    # their paths' vertices (mm), by the part's name
    using: set[int] = set()             # the elements a <use> is drawing (a <use> of its own group: a cycle)
    drawn_uses = 0

    def visit(el: ET.Element, m: np.ndarray, around: tuple[str, ...] = (), text: bool = False,
              group: str = "", use: str | None = None, ref: bool = False,
              size: tuple[float, float] = root_size) -> None:
        nonlocal open_paths, counter, drawn_uses
        tag = _local(el.tag)
        if tag == "text" and not _hidden(el):       # a label, perhaps a piece's name (_named_by_labels)
            got = _text_anchor(el, m, where)
            if got is not None and _label_score(got[0]):
                labels.append(got)
            if got is not None:             # cut instructions, a line (a <tspan>) at a time
                cut = [c for line in _text_lines(el) for c in cut_instructions(line)]
                if cut:
                    cuts.append((cut, got[0], got[1]))
            return
        if (tag in _SKIP and not (ref and tag == "symbol")) or _hidden(el):
            return
        m = m @ _transform(el, where)
        if tag == "svg" and el is not root:         # a nested viewport: its x, y, width, height, viewBox
            inner, size = _nested_viewport(el, size, where)
            m = m @ inner
        text = text or _text_cue(el)
        if tag == "use":        # draws the element it names (in <defs>, or anywhere), moved by x, y
            name = (el.get("href") or el.get(_XLINK_HREF) or "").strip().removeprefix("#")
            target = ids.get(name)
            if target is None or id(target) in using:
                return
            drawn_uses += 1
            if drawn_uses > MAX_ENTITIES:
                raise InputError(f"{where}: <use> elements draw more than {MAX_ENTITIES:,} elements")
            shift = np.array([[1.0, 0.0, _attr(el, "x", where, 0.0)], [0.0, 1.0, _attr(el, "y", where, 0.0)],
                              [0.0, 0.0, 1.0]])
            own = tuple(t for t in (el.get(_INKSCAPE_LABEL), el.get("id"), el.get("class")) if t)
            using.add(id(target))
            visit(target, m @ shift, around + own, text, group, use or name, ref=True, size=size)
            using.discard(id(target))
            return
        if tag in _SHAPES:
            if tag == "line":       # (not counted: lines, read since, leave the shapes' fallback names as they were)
                fallback = "line"
            else:
                counter += 1
                fallback = f"piece{counter}"
            hint = structure_hint([el.get("class")], around, text, (el.get("id"), el.get(_INKSCAPE_LABEL)))
            # an outline the file marks as an annotation (a logo, a button) keeps its made-up id
            gname = None if hint.get("annotation") else _group_name(group)
            base = _name(el, gname, fallback)
            former = _former_names(el, base)
            # named after its group: of two outlines so named, the one gridded keeps the name (classify)
            named = {"aliases": list(former)} if former else {}
            if gname is not None and base == gname and not _own_name(el):
                named["group_base"] = base
            label = f"<{tag}> {base!r}"
            nameless = base == fallback or bool(_MADE_UP_ID.match(base))
            loops: list[list[Primitive] | np.ndarray] = []     # curves, or a polygon's points
            try:
                if tag in ("polygon", "polyline"):
                    poly = _polygon_points(el, m, f"{where}: {label}")
                    if poly is not None and poly[1]:
                        loops.append(poly[0])
                    elif poly is not None:           # open: joined with others end to end, if they meet
                        opened.append(_Open(_straight_prims(poly[0]), base, el, around, text, group,
                                            nameless=nameless))
                elif tag == "line":
                    ends = _line_ends(el, m, f"{where}: {label}")
                    if ends is not None:
                        opened.append(_Open(_straight_prims(ends), base, el, around, text, group, nameless=nameless))
                elif tag == "rect" and (quad := _rect_corners(el, m, f"{where}: {label}")) is not None:
                    loops.append(quad)
                elif tag in ("circle", "ellipse"):
                    prims = _ellipse_prims(el, m, f"{where}: {label}")
                    if prims:
                        loops.append(prims)
                else:
                    d = _shape_d(el, f"{where}: {label}")
                    if d and (_fold_mark(el) or el.get("id") in fold_paths):   # "cut on fold": its ends on the fold
                        ends = _fold_ends(d, m)
                        if ends is not None:
                            folds.append(ends)
                        return
                    if d:
                        for sub in _parsed(d, f"{where}: {label}").continuous_subpaths():
                            if len(sub) == 0:
                                continue
                            prims = [_segment_prims(seg, m) for seg in sub]
                            if embedded and el.get("name") and el.get("name") not in corners_of:
                                corners_of[el.get("name")] = np.array([p.start for p in prims])
                            ends = np.array([p.start for p in prims] + [prims[-1].end])
                            size = float(np.hypot(*np.ptp(ends, axis=0)))
                            gap = float(np.linalg.norm(prims[-1].end - prims[0].start))
                            if not size > 0 or gap > 1e-9 * size:      # counted once joined
                                opened.append(_Open(prims, base, el, around, text, group, nameless=nameless,
                                                    meta=element_meta(tag, el, group, hint, use, named)))
                                continue
                            if _drawn_line(prims, size):       # M a L b z: a line, drawn closed
                                # a failed piece, unless it joins open paths into an outline
                                drawn[id(prims)] = _Open(prims[:1], base, el, around, text, group, True)
                                opened.append(drawn[id(prims)])
                            loops.append(prims)
            except InputError as exc:                  # bad path data: a failure, whatever it is
                pending.append((piece_failure(unique(base), exc, where, labels=(label,)),
                                {"element": tag, "id": el.get("id")}))
                return
            if hint.get("hint") == "sew" and loops:
                # TauMeta's "A.seamline" is piece "A" (its cut line keeps "A.cuttingline")
                if (short := _without_word(base, hint["why"])) != base:
                    named["aliases"] = named.get("aliases", []) + [base]
                    base = short
            for k, prims in enumerate(loops):
                name = unique(base if len(loops) == 1 else f"{base}-{k + 1}")
                if nameless:
                    unnamed.add(name)
                meta = element_meta(tag, el, group, hint, use, named)
                make = piece_from_points if isinstance(prims, np.ndarray) else piece_from_primitives
                if hint.get("annotation"):      # skipped whatever its shape: made only if included
                    box = outline_box(prims) if isinstance(prims, np.ndarray) else control_box(prims)
                    marked.append(marked_annotation(name, hint, meta, box, partial(
                        make, name, prims, rel_tol=rel_tol, meta=dict(meta), **made_as)))
                    continue
                pending.append((name, prims, make, meta))     # made once every outline's size is known
            return
        if el is not root:
            own = [el.get(_INKSCAPE_LABEL), el.get("id"), el.get("class")]
            around = around + tuple(t for t in own if t)
            if tag == "g":
                key = el.get(_INKSCAPE_LABEL) or el.get("id")
                group = f"{group}/{key}" if key else f"{group}/g"
        for child in el:
            visit(child, m, around, text, group, use, size=size)

    visit(root, view)
    # An outline under TINY_REL of the largest's size is a glyph, a notch or a mark (never a piece
    # that far under the smallest piece's share, MIN_AREA_FRACTION of the largest's area): it is
    # sampled to DRAFT_REL_TOL for the sorting, and again to rel_tol only if gridded or included.
    sizes = [_box_size(item[1]) if len(item) == 4 else 0.0 for item in pending]
    largest = max(sizes, default=0.0)
    drafts: dict[int, Any] = {}
    for item, size in zip(pending, sizes):
        if len(item) == 2:                       # bad path data
            unmade.append(item)
            continue
        name, prims, make, meta = item
        draft = make is piece_from_primitives and size < TINY_REL * largest and rel_tol < DRAFT_REL_TOL
        if draft:
            exact = partial(make, name, prims, rel_tol=rel_tol, meta=dict(meta), **made_as)
            meta["draft"] = len(drafts)
        try:
            pieces.append(make(name, prims, rel_tol=DRAFT_REL_TOL if draft else rel_tol, meta=meta, **made_as))
            if draft:                   # its maker at full tolerance, and how many notes it made itself
                drafts[meta["draft"]] = (exact, len(pieces[-1].notes))
        except InputError as exc:       # fewer than 3 points, no area: failed or skipped
            if draft:                   # so it is at its own tolerance too (the reason names it)
                meta.pop("draft")
                try:
                    pieces.append(exact())
                    continue
                except InputError as exc2:
                    exc = exc2
            unmade.append((piece_failure(name, exc, where), {**meta, "box": outline_box(prims)}))
            if id(prims) in drawn:
                drawn[id(prims)].failure = unmade[-1]
    wanted: dict[int, str] = {}          # joined outlines that did not get their name: which they wanted
    for name, prims, meta, note, bridged, nameless, used_paths in _joined(opened):
        try:
            piece = piece_from_primitives(name, prims, rel_tol=rel_tol, where=f"{where}: ", units=unit,
                                          source="svg", notes=(f"units: {how}", note), meta=meta)
        except InputError as exc:
            if bridged:                 # a sliver only the gap made: no outline, its paths open ones
                for o in used_paths:
                    o.joined = False
                continue
            unmade.append((piece_failure(unique(name), exc, where), meta))
            continue
        pieces.append(piece if (final := unique(name)) == name else replace(piece, name=final))
        if nameless:
            unnamed.add(final)
        elif final != name:
            wanted[len(pieces) - 1] = name
    boxes = _Boxes(pieces)
    for o in opened:       # a sew line left open along a cut line's straight edge (cut on the fold)
        if o.joined or o.line or o.meta is None:
            continue
        got_closed = _closed_along_cut(o, boxes)
        if got_closed is None:
            continue
        prims, cut, ends = got_closed
        base, meta = o.base, dict(o.meta)
        hint = meta.get("structure") or {}
        if hint.get("hint") == "sew" and (short := _without_word(base, hint["why"])) != base:
            meta["aliases"] = meta.get("aliases", []) + [base]     # as a closed sew line's (visit)
            base = short
        name = unique(base)
        note = (f"an open path closed along the straight edge of cut line {cut.name!r} from "
                f"{ends[0][0]:.6g},{ends[0][1]:.6g} to {ends[1][0]:.6g},{ends[1][1]:.6g} mm, where the cut "
                "line has no seam allowance (a fold or a finished edge)")
        try:
            piece = piece_from_primitives(name, prims, rel_tol=rel_tol, where=f"{where}: ", units=unit,
                                          source="svg", notes=(f"units: {how}", note),
                                          meta={**meta, "closed_along": [list(map(float, e)) for e in ends]})
        except InputError:
            continue
        o.joined = True
        pieces.append(piece)
    used = {id(o.failure) for o in opened if o.joined and o.failure is not None}
    freed = {u[0].name for u in unmade if id(u) in used}
    unmade = [u for u in unmade if id(u) not in used]     # lines drawn closed that close an outline
    for k, name in wanted.items():      # the name a line drawn closed took, which it closes (a side)
        if name in freed:
            freed.discard(name)
            unnamed.discard(pieces[k].name)
            pieces[k] = replace(pieces[k], name=name)
    open_paths += sum(1 for o in opened if not o.joined and not o.line)
    extra = (f" ({open_paths} open path{'s were' if open_paths != 1 else ' was'} skipped: a "
             "piece must be a closed path, ending with Z or at its start point)"
             if open_paths else "")
    # a group's name names no piece where the group holds several pieces side by side: they may take
    # the garment words drawn on them
    pieces = _named_by_labels(pieces, unnamed | _shared_group_names(pieces), labels, unique)
    got = classified(pieces, unmade, where, f"{where}: no closed path found, so no pattern piece{extra}",
                     line=line, marked=marked)
    got = _exact(got, drafts) if drafts else got
    if folds:                               # a piece cut on the fold: its fold line (fold.unfold)
        got = Pieces.like(got, attach_fold_lines(got, folds))
    if cuts:                                # how many to cut, of what: the text drawn on the piece
        got = Pieces.like(got, _with_cut_instructions(got, cuts))
    if embedded:                            # the file's own seams, as a stitches file would give them
        got.stitches = _embedded_stitches(embedded, corners_of, got, where)
    return got


#: At most this many seams are read from a file's ``<metadata><seams>``
MAX_EMBEDDED_SEAMS = 10_000


def _metadata_seams(root: ET.Element) -> list[list[tuple[str, int, int]]]:
    """The seams a file lists in ``<metadata><seams><seam><seampart><part>NAME</part><start>I</start>
    <end>J</end></seampart>...`` (Alienmiep's pattern-matching-nester exports GarmentCode patterns so):
    each seam its two parts, a part the ``name`` of a path and the indices of two of its vertices
    (segment end points in path order). Malformed seams are left out."""
    out: list[list[tuple[str, int, int]]] = []
    for meta in root.iter():
        if _local(meta.tag) != "metadata":
            continue
        for seam in meta.iter():
            if _local(seam.tag) != "seam" or len(out) >= MAX_EMBEDDED_SEAMS:
                continue
            parts = []
            for part in seam:
                if _local(part.tag) != "seampart":
                    continue
                got = {_local(c.tag): (c.text or "").strip() for c in part}
                try:
                    parts.append((got["part"], int(got["start"]), int(got["end"])))
                except (KeyError, ValueError):
                    break
            if len(parts) == 2 and all(p[0] for p in parts):
                out.append(parts)
    return out


def _embedded_stitches(seams: list[list[tuple[str, int, int]]], corners_of: dict[str, np.ndarray],
                       pieces: list[Piece], where: str) -> dict[str, Any] | None:
    """The file's seams (:func:`_metadata_seams`) as the data of a stitches file
    (:mod:`clothgrid.garment_stitches`), or None where a seam names a part that is no piece or a vertex
    its path does not have.

    A part's vertex ``k`` is the outline point at its path's ``k``-th vertex, and its range runs
    counter-clockwise. The file joins a part's end to the other's start along the paths as drawn (its
    seams' lengths and ends match so: the nester's skirt and trousers); a path drawn clockwise is a
    piece laid face down (the nester's backs), listed in ``"turned"``, so that it is sewn along its
    path's direction."""
    by = {p.name: p for p in pieces}
    turned: set[str] = set()
    ccw_of: dict[str, tuple[bool, np.ndarray]] = {}
    out = []
    for k, parts in enumerate(seams):
        sides = []
        for name, i, j in parts:
            piece, corners = by.get(name), corners_of.get(name)
            if piece is None or corners is None or not (0 <= i < len(corners) and 0 <= j < len(corners)) or i == j:
                return None
            if name not in ccw_of:
                o = piece.outline
                tol = max(1e-6 * piece.size, 4 * piece.tolerance)
                d = np.linalg.norm(o[None, :, :] - corners[:, None, :], axis=2)
                every = d.argmin(axis=1)             # each path vertex's outline point
                if not (d[np.arange(len(corners)), every] <= tol).all():
                    return None
                # counter-clockwise where the vertices come in the outline's order (rising, wrapping once)
                ccw_of[name] = (int((np.diff(np.r_[every, every[:1]]) < 0).sum()) <= 1, every)
            ccw, every = ccw_of[name]
            if not ccw:
                turned.add(name)
            a, b = (int(every[i]), int(every[j])) if ccw else (int(every[j]), int(every[i]))
            sides.append({"piece": name, "range": [a, b]})
        out.append({"a": sides[0], "b": sides[1], "label": f"seam {k + 1} of the file"})
    return {"clothgrid_stitches": 1, "seams": out, "turned": sorted(turned),
            "about": f"{where}: the seams of its <metadata>"}


def _text_lines(el: ET.Element) -> list[str]:
    """A ``<text>`` element's lines: a ``<tspan>`` placed on its own (``x``, ``y`` or ``dy``) starts
    one (FreeSewing 2 writes a title's lines so), an inline one goes on the line it is in."""
    lines = [[el.text or ""]]
    for child in el:
        if _local(child.tag) == "tspan" and any(child.get(k) for k in ("x", "y", "dy")):
            lines.append([])
        lines[-1].append("".join(child.itertext()))
        lines[-1].append(child.tail or "")
    return [t for t in (" ".join("".join(parts).split()) for parts in lines) if t]


def _with_cut_instructions(pieces: list[Piece], cuts: list[tuple[list, str, np.ndarray]]) -> list[Piece]:
    """``pieces`` with each cut instruction (:func:`~clothgrid.patterns.piece.cut_instructions`) in
    ``meta["cut"]`` of the smallest piece around its text's anchor (the first text of a piece)."""
    out = list(pieces)
    order = sorted(range(len(out)), key=lambda k: out[k].area)
    for cut, text, point in cuts:
        for k in order:
            if "cut" not in out[k].meta and points_in_polygon(point[None, :], out[k].outline)[0]:
                out[k] = replace(out[k], meta={**out[k].meta, "cut": cut, "cut_text": text})
                break
    return out


#: FreeSewing's "cut on fold" mark: a path drawn with these markers (``url(#cutonfoldFrom)``)
_FOLD_MARKERS = re.compile(r"cut-?on-?fold", re.IGNORECASE)


def _fold_mark(el: ET.Element) -> bool:
    """Whether ``el`` is a "cut on fold" mark (its markers, or its class, say so)."""
    return any(_FOLD_MARKERS.search(el.get(k) or "") for k in ("marker-start", "marker-end", "class", "style"))


_FOLD_TEXT = re.compile(r"\b(cut|place)\s+on\s+(the\s+)?fold\b", re.IGNORECASE)


def _fold_text_paths(root: ET.Element) -> set[str]:
    """The ids of the paths a ``<textPath>`` writes "Cut on fold" along (FreeSewing 2's mark: the
    grain line's bracket, its ends on the fold)."""
    out = set()
    for el in root.iter():
        if _local(el.tag) == "textPath" and _FOLD_TEXT.search("".join(el.itertext())):
            ref = (el.get("href") or el.get(_XLINK_HREF) or "").strip()
            if ref.startswith("#"):
                out.add(ref[1:])
    return out


def _parsed(d: str, label: str) -> Any:
    """Path data ``d`` parsed (an svgpathtools ``Path``); InputError naming ``label`` where it is
    invalid (a character no path command or number has, no leading moveto, what svgpathtools refuses)."""
    from svgpathtools import parse_path

    if not _PATH_CHARS.fullmatch(d):
        bad = re.sub(r"[MmZzLlHhVvCcSsQqTtAa0-9eE.,+\-\s]", "", d)[:10]
        raise InputError(f"{label}: invalid path data (unexpected {bad!r})")
    if not d.lstrip().startswith(("M", "m")):
        raise InputError(f"{label}: invalid path data (it must begin with a moveto, M or m: "
                         f"{d.strip()[:20]!r})")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return parse_path(d)
    except Exception as exc:                   # svgpathtools raises several types
        raise InputError(f"{label}: invalid path data ({exc})") from None


def _fold_ends(d: str, m: np.ndarray) -> np.ndarray | None:
    """The first and last points (mm) of a fold mark's path data ``d``, or None where it cannot be
    read (a mark, not a piece: it is then ignored)."""
    try:
        parsed = _parsed(d, "fold mark")
    except InputError:
        return None
    if len(parsed) == 0:
        return None
    ends = np.array([[parsed[0].start.real, parsed[0].start.imag, 1.0],
                     [parsed[-1].end.real, parsed[-1].end.imag, 1.0]]) @ m.T
    out = ends[:, :2]
    return out if np.isfinite(out).all() and np.hypot(*(out[1] - out[0])) > 0 else None


def _box_size(prims: Any) -> float:
    """The diagonal of an outline's control box (its points' box for a polygon): 0 where it has none."""
    box = outline_box(prims) if isinstance(prims, np.ndarray) else control_box(prims)
    return 0.0 if box is None else float(np.hypot(box[1][0] - box[0][0], box[1][1] - box[0][1]))


#: Outlines under this fraction of the largest outline's size (control boxes' diagonals) are sampled to
#: :data:`DRAFT_REL_TOL` first: slspencer/tmtp's ``SusanTrousersPlain.svg`` draws its lettering as
#: some 770 glyph outlines of at most 8.4 mm beside pieces of up to 1.17 m, which took 12.8 s of its
#: 13 s at the full tolerance and 2 s at 1e-4 (glyphs under 2 % of 1.17 m: 23 mm). An outline that
#: small is never a piece by its area (MIN_AREA_FRACTION, 0.5 % of the largest's area, is a box of
#: 7 % of its size) unless the file says so; what is gridded or included is sampled again at the
#: reader's tolerance.
TINY_REL = 0.02
DRAFT_REL_TOL = 1e-4


def _exact(got: Pieces, drafts: dict[int, Any]) -> Pieces:
    """``got`` with its draft-sampled outlines (``meta["draft"]``) made at the reader's tolerance: the
    pieces now (their names, notes of the sorting and meta kept), the skipped ones when included."""
    def exact_of(p: Piece) -> Piece:
        make, own = drafts[p.meta["draft"]]
        fine = make()
        meta = {k: v for k, v in p.meta.items() if k != "draft"}
        return replace(fine, name=p.name, notes=fine.notes + p.notes[own:], meta=meta)

    pieces = [exact_of(p) if "draft" in p.meta else p for p in got]
    skipped = []
    for s in got.skipped:
        if s.piece is not None and "draft" in s.piece.meta:
            draft = s.piece
            s = replace(s, piece=None, size=draft.extent, make=lambda d=draft: exact_of(d),
                        meta={k: v for k, v in s.meta.items() if k != "draft"})
        skipped.append(s)
    return Pieces.like(got, pieces, skipped=skipped)


@dataclass
class _Open:
    """An open subpath of an SVG file (or a line drawn as a closed path), to be joined."""

    prims: list[Primitive]
    base: str
    el: ET.Element
    around: tuple[str, ...]
    text: bool
    group: str
    line: bool = False                        # a line drawn closed (also tried as a piece)
    joined: bool = False
    failure: tuple | None = None              # that piece's failure, dropped if joined
    nameless: bool = False                    # base is the element's fallback name (no id, label, group)
    meta: dict | None = None                  # what a piece made of it alone records (_closed_along_cut)


#: An open path is closed along a closed outline's straight edge (:func:`_closed_along_cut`) where its
#: ends and that edge lie within this share of the outline's size of the outline (and
#: :data:`ALONG_CUT_MM`), and the edge is at least :data:`ALONG_CUT_MIN` of its size long.
ALONG_CUT_REL = 1e-3
ALONG_CUT_MM = 0.5
ALONG_CUT_MIN = 0.1


class _Boxes:
    """The pieces' sizes and boxes (widened by the tolerance :func:`_closed_along_cut` allows), once."""

    def __init__(self, pieces: list[Piece]):
        self.pieces = list(pieces)
        if self.pieces:
            lo = np.array([p.outline.min(axis=0) for p in self.pieces])
            hi = np.array([p.outline.max(axis=0) for p in self.pieces])
        else:
            lo = hi = np.zeros((0, 2))
        self.size = np.hypot(*(hi - lo).T)
        self.tol = np.maximum(ALONG_CUT_REL * self.size, np.minimum(ALONG_CUT_MM, 1e-2 * self.size))
        self.lo, self.hi = lo - self.tol[:, None], hi + self.tol[:, None]

    def around(self, box: tuple[np.ndarray, np.ndarray], chord: float) -> np.ndarray:
        """The pieces whose widened box holds ``box`` and whose size is at most ``chord`` over
        :data:`ALONG_CUT_MIN`."""
        ok = ((self.lo <= box[0]).all(axis=1) & (self.hi >= box[1]).all(axis=1)
              & (chord >= ALONG_CUT_MIN * self.size))
        return np.flatnonzero(ok)


def _closed_along_cut(o: "_Open", boxes: _Boxes) -> tuple[list[Primitive], Piece, np.ndarray] | None:
    """``o``'s primitives closed by the straight line from its end back to its start, where that line
    runs along the outline of one of ``pieces`` (its ends and points along it on that outline, within
    :data:`ALONG_CUT_REL` of its size or :data:`ALONG_CUT_MM`) and the path lies inside it: a sew line
    drawn open where the piece is cut on the fold or along a finished edge (TauMeta/tmtp's seam lines
    of pieces cut on the fold), the cut line having no seam allowance there. Returns ``(the closed
    primitives, the piece, the line's two ends)``, or None."""
    from ..geometry import points_in_polygon
    from .annotations import outline_distance
    from .sampling import sample_loop

    e0, e1 = o.prims[0].start, o.prims[-1].end
    chord = float(np.hypot(*(e1 - e0)))
    if not np.isfinite(chord) or chord <= 0:
        return None
    closing = Bezier(np.array([e1, e0]))
    loop = list(o.prims) + [closing]
    for k in boxes.around(control_box(loop), chord):
        p, size, tol = boxes.pieces[k], float(boxes.size[k]), float(boxes.tol[k])
        along = e0 + np.linspace(0.0, 1.0, 33)[:, None] * (e1 - e0)
        if outline_distance(along, p.outline).max() > tol:
            continue
        pts, _ = sample_loop(loop, 1e-3 * size)
        off = outline_distance(pts, p.outline) > tol
        if off.any() and not points_in_polygon(pts[off], p.outline).all():
            continue
        return loop, p, np.array([e0, e1])
    return None


def element_meta(tag: str, el: ET.Element, group: str, hint: dict, use: str | None, named: dict) -> dict:
    """What a piece made of element ``el`` records of it (closed, or an open path closed later)."""
    return {"element": tag, "id": el.get("id"), "class": el.get("class"), "group": group or None,
            "structure": hint, "look": _look(el), "part": group or None, **({"use": use} if use else {}),
            **named}


def _drawn_line(prims: list[Primitive], size: float) -> bool:
    """Whether a closed subpath is a line drawn closed (``M a L b z``): straight, two distinct points."""
    if not all(isinstance(p, Bezier) and len(p.ctrl) == 2 for p in prims):
        return False
    ends = np.array([p.start for p in prims])
    return len(np.unique(np.round(ends / (1e-9 * size)), axis=0)) <= 2


def _joined(opened: list[_Open]) -> list["_Outline"]:
    """Closed outlines made of open subpaths that meet end to end, each group on its own.

    A pattern program may draw a piece as several open paths (FreeSewing draws a
    cap brim as its two curves and the two short lines between them). Within
    one group (``<g>``) and of one ``class``, subpaths whose ends meet (within
    ``1e-6`` of their extent, or :data:`JOIN_MM`) are joined
    (:func:`~clothgrid.patterns.chains.join_outlines`): a chain of them that
    closes without a fork is an outline, named after its group (else its first
    named path); where paths fork (a panel drawn as its edges and a waist line
    across it), the outline is the boundary around them, and the paths inside
    it are inner lines. Where subpaths are left over, the group is joined again
    with ends up to :data:`~clothgrid.patterns.chains.GAP_MM` apart (and at most
    :data:`~clothgrid.patterns.chains.GAP_REL` of its
    extent): a block drawn by hand in Adobe Illustrator as separate lines and
    curves has its ends a fraction of a millimetre apart. The subpaths used are
    marked ``joined``. Returns an :class:`_Outline` each (the gap in the
    drawing's units, 0 where the ends meet).
    """
    groups: dict[tuple[str, str], list[_Open]] = {}
    for o in opened:
        groups.setdefault((o.group, o.el.get("class") or ""), []).append(o)
    out = []
    for (group, _), paths in groups.items():
        # (a path with a non-finite end joins nothing: it would make the tolerance infinite)
        paths = [o for o in paths if np.isfinite(o.prims[0].start).all() and np.isfinite(o.prims[-1].end).all()]
        if not paths:
            continue
        box = control_box([p for o in paths for p in o.prims])       # the group's size (one path's too)
        extent = float(np.hypot(box[1][0] - box[0][0], box[1][1] - box[0][1])) if box else 0.0
        if not np.isfinite(extent) or not extent > 0:
            continue
        found = join_outlines([o.prims for o in paths], max(1e-6 * extent, JOIN_MM), min(GAP_MM, GAP_REL * extent),
                              mm=1.0)
        out += [_joined_outline(group, paths, f) for f in found]
    return out


class _Outline(NamedTuple):
    """An outline :func:`_joined` made of open paths."""

    name: str
    prims: list[Primitive]
    meta: dict
    note: str                     # how it was joined (chains.joined_note)
    bridged: bool                 # made only across gaps (chains.Joined)
    nameless: bool                # named by a fallback or a made-up id (may take a label's name)
    paths: list["_Open"]          # the paths used (members and inner lines)


def _joined_outline(group: str, paths: list["_Open"], joined: Joined) -> _Outline:
    """:func:`_joined`'s answer for an outline ``joined`` of ``paths`` (its members and inner lines
    are marked ``joined``): named after its group (else its first path), its class the first
    path's, its structure from the paths' classes and groups."""
    prims, mem, inner = joined.prims, joined.members, joined.inner
    for k in mem + inner:
        paths[k].joined = True
    first = paths[mem[0]]
    classes = [paths[k].el.get("class") for k in mem]
    hint = structure_hint([c for c in classes if c][:1], first.around, any(paths[k].text for k in mem))
    key = group.rsplit("/", 1)[-1] if group else ""
    # unnamed <line>s all fall back to "line": the first member with a name of its own, or a shape's
    name = _part_name(key) if key and key != "g" else next((paths[k].base for k in mem if paths[k].base != "line"),
                                                           "outline")
    nameless = not (key and key != "g") and all(paths[k].nameless for k in mem)
    said = [_own_name(o.el) or (o.el.get("id") or "").strip() or o.base for o in paths]    # in notes: ids, not groups
    meta = {"element": "path", "id": first.el.get("id"), "class": first.el.get("class"),
            "group": group or None, "structure": hint, "look": _look(first.el),
            "part": group or None, "joined": [said[k] for k in mem]}
    if name != "outline" and key and key != "g":
        meta["group_base"] = name
    if inner:
        meta["inner_lines"] = [said[k] for k in inner]
    gap = largest_gap(prims)
    if joined.bridged:
        meta["gap_mm"] = gap
    note = joined_note(joined, gap, ("open path", "open paths"), _names([said[k] for k in mem]),
                       _names([said[k] for k in inner]))
    return _Outline(name, prims, meta, note, joined.bridged, nameless, [paths[k] for k in mem + inner])


def _names(names: list[str], most: int = 10) -> str:
    """``names`` quoted, at most ``most`` of them and a count of the rest."""
    shown = ", ".join(repr(m) for m in names[:most])
    return shown + (f", and {len(names) - most} more" if len(names) > most else "")


#: Open SVG paths whose ends are this close (in mm) meet, whatever the drawing's size: a hand-drawn
#: corset panel's edges (Inkscape) end up to a micrometre apart.
JOIN_MM = 0.01

