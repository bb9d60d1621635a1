"""Tests of the pattern-file readers (:mod:`clothgrid.patterns`) and the CLI on them.

Every reader is checked end to end: the grid's boundary nodes must lie on the
piece's true outline (lines, circular arcs, cubic Béziers computed here
independently) within 1e-6 of the piece's size.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from clothgrid import InputError, generate
from clothgrid.cli import EXIT_PARTIAL, main
from clothgrid.patterns import (Piece, choose_corners, corner_candidates, nodes_for_edge_length,
                                parse_length, piece_boundary)
from clothgrid.readers import load_single_boundary, read_pieces
from clothgrid.patterns.piece import piece_from_polygon
from clothgrid.pipeline import generate_piece
from clothgrid.patterns.sampling import Bezier, EllipseArc, bspline_to_beziers, sample_loop

ezdxf = pytest.importorskip("ezdxf")
pytest.importorskip("svgpathtools")

DATA = Path(__file__).parent / "data" / "patterns"
NODES = (17, 17)
ACC = 1e-6          # boundary nodes on the true outline, relative to the piece's size


# --------------------------------------------------------------------------- geometry helpers


def boundary_nodes(grid) -> np.ndarray:
    p = grid.points[..., :2]
    return np.concatenate([p[:, 0], p[:, -1], p[0, :], p[-1, :]])


def dist_segment(p: np.ndarray, a, b) -> np.ndarray:
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = b - a
    t = np.clip(((p - a) @ d) / (d @ d), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * d), axis=1)


def dist_arc(p: np.ndarray, center, r: float, contains) -> np.ndarray:
    """Distance to a circular arc; ``contains(angle)`` says which angles belong to it."""
    c = np.asarray(center, float)
    v = p - c
    ang = np.arctan2(v[:, 1], v[:, 0])
    on = np.abs(np.hypot(v[:, 0], v[:, 1]) - r)
    return np.where(contains(ang), on, np.inf)


def dist_bezier(p: np.ndarray, ctrl) -> np.ndarray:
    """Distance to a polynomial Bézier curve: dense search, then Newton steps."""
    ctrl = np.asarray(ctrl, float)
    k = len(ctrl) - 1
    binom = np.array([math.comb(k, i) for i in range(k + 1)], float)

    def curve(t):
        t = np.asarray(t, float)[..., None]
        i = np.arange(k + 1)
        basis = binom * t ** i * (1 - t) ** (k - i)
        return basis @ ctrl

    ts = np.linspace(0, 1, 4001)
    pts = curve(ts)
    d = np.linalg.norm(p[:, None] - pts[None], axis=2)
    t = ts[d.argmin(axis=1)]
    h = 1e-7
    for _ in range(30):       # Newton on f(t) = (B(t) - p) . B'(t)
        b0, bp, bm = curve(t), curve(np.clip(t + h, 0, 1)), curve(np.clip(t - h, 0, 1))
        d1 = (bp - bm) / (2 * h)
        d2 = (bp - 2 * b0 + bm) / h ** 2
        f = ((b0 - p) * d1).sum(1)
        fp = (d1 * d1).sum(1) + ((b0 - p) * d2).sum(1)
        t = np.clip(t - np.where(np.abs(fp) > 0, f / fp, 0), 0, 1)
    return np.linalg.norm(curve(t) - p, axis=1)


def dist_polyline(p: np.ndarray, poly: np.ndarray, closed: bool = False) -> np.ndarray:
    """Upper bound of the distance to a dense polyline: its segments next to the nearest vertex."""
    from scipy.spatial import cKDTree

    n = len(poly)
    _, i = cKDTree(poly).query(p)
    best = np.full(len(p), np.inf)
    for lo in (i - 1, i):
        ok = np.ones(len(p), bool) if closed else (lo >= 0) & (lo + 1 < n)
        a, b = poly[lo % n], poly[(lo + 1) % n]
        d = b - a
        t = np.clip(((p - a) * d).sum(1) / np.maximum((d * d).sum(1), 1e-300), 0, 1)
        dist = np.linalg.norm(p - (a + t[:, None] * d), axis=1)
        best = np.where(ok, np.minimum(best, dist), best)
    return best


def dist_polyline_exact(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance to an open polyline, by brute force (for curves that may cross themselves)."""
    a, b = poly[:-1], poly[1:]
    d = b - a
    dd = np.maximum((d * d).sum(-1), 1e-300)
    out = []
    for chunk in np.array_split(p, max(1, len(p) * len(a) // 2_000_000)):
        t = np.clip(((chunk[:, None] - a[None]) * d[None]).sum(-1) / dd, 0, 1)
        out.append(np.linalg.norm(chunk[:, None] - (a[None] + t[..., None] * d[None]), axis=2).min(1))
    return np.concatenate(out)


def in_sweep(ang: np.ndarray, start: float, delta: float) -> np.ndarray:
    """Are the angles (radians) on the arc from ``start`` turning by ``delta``?"""
    rel = (ang - start) % (2 * np.pi) if delta >= 0 else (start - ang) % (2 * np.pi)
    return rel <= abs(delta) + 1e-9


def on_outline(nodes: np.ndarray, parts: list) -> np.ndarray:
    """Smallest distance of each node to any of the outline's parts (callables)."""
    return np.min([f(nodes) for f in parts], axis=0)


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if p.is_file())


# --------------------------------------------------------------------------- SVG

# 1 user unit = 0.01 in = 0.254 mm; y flipped: Y = 101.6 - 0.254 y
S = 0.254
SVG = """<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"
     width="8in" height="4in" viewBox="0 0 800 400">
  <path id="p1" inkscape:label="front" d="M 100 300 L 300 300 A 100 100 0 0 0 300 100 C 250 50 150 150 100 100 Z"/>
  <g transform="translate(500,200) scale(1.5)">
    <circle id="disc" cx="100" cy="0" r="50"/>
  </g>
  <path id="grain" d="M 0 0 L 50 50"/>
  <defs><rect id="hidden" x="0" y="0" width="10" height="10"/></defs>
</svg>
"""


def _svg_user(nodes_mm: np.ndarray) -> np.ndarray:
    return np.column_stack([nodes_mm[:, 0] / S, (101.6 - nodes_mm[:, 1]) / S])


@pytest.fixture
def svg_file(tmp_path: Path) -> Path:
    path = tmp_path / "pattern.svg"
    path.write_text(SVG)
    return path


def test_svg_pieces_units_and_names(svg_file):
    pieces = read_pieces(svg_file)
    assert [p.name for p in pieces] == ["front", "disc"]
    front, disc = pieces
    assert front.units == "in" and front.source == "svg"
    # front: x from 100 to 400 user units, y from ~87 to 300
    w, h = front.extent
    assert w == pytest.approx(300 * S, rel=1e-9)
    assert front.area > 0                              # counter-clockwise
    # the segment end points are kept exactly
    corners_mm = np.array([[100 * S, 101.6 - 300 * S], [300 * S, 101.6 - 300 * S],
                           [300 * S, 101.6 - 100 * S], [100 * S, 101.6 - 100 * S]])
    for c in corners_mm:
        assert np.min(np.linalg.norm(front.outline[front.vertices] - c, axis=1)) < 1e-12
    assert disc.extent == pytest.approx((150 * S, 150 * S), rel=1e-6)
    assert front.tolerance <= 1e-7 * front.size * (1 + 1e-9)


def test_svg_grid_nodes_on_true_outline(svg_file):
    front, disc = read_pieces(svg_file)
    grid = generate_piece(front, NODES)
    assert grid.shape == NODES
    user = _svg_user(boundary_nodes(grid))
    parts = [lambda p: dist_segment(p, (100, 300), (300, 300)),
             lambda p: dist_arc(p, (300, 200), 100.0, lambda a: np.abs(a) <= np.pi / 2 + 1e-9),
             lambda p: dist_bezier(p, [(300, 100), (250, 50), (150, 150), (100, 100)]),
             lambda p: dist_segment(p, (100, 100), (100, 300))]
    err = on_outline(user, parts).max() * S
    assert err <= ACC * front.size, err
    info = grid.info["piece"]
    assert info["name"] == "front" and info["units"] == "mm" and info["file_units"] == "in"
    assert info["corners"]["method"] in ("split", "scored", "candidates")

    g2 = generate_piece(disc, NODES)
    user = _svg_user(boundary_nodes(g2))
    err = np.abs(np.hypot(user[:, 0] - 650, user[:, 1] - 200) - 75).max() * S
    assert err <= ACC * disc.size, err
    assert g2.info["piece"]["corners"]["method"] == "equal-sides"


def test_svg_sheared_arc_and_cubic(tmp_path):
    # a general affine transform (shear, rotation, unequal scales) on a path with an arc:
    # mapped back through its inverse, the nodes lie on the original circle and cubic
    tf = np.array([[1.2, -0.2, 5.0], [0.3, 0.8, 7.0], [0, 0, 1]])
    path = tmp_path / "shear.svg"
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" '
                    'viewBox="0 0 100 100"><path transform="matrix(1.2 0.3 -0.2 0.8 5 7)" '
                    'd="M 10 40 A 30 30 0 1 1 70 40 C 60 60 20 60 10 40 Z"/></svg>')
    (piece,) = read_pieces(path)
    grid = generate_piece(piece, NODES)
    nodes = boundary_nodes(grid)
    user = np.column_stack([nodes[:, 0], 100.0 - nodes[:, 1], np.ones(len(nodes))])
    local = (np.linalg.inv(tf) @ user.T).T[:, :2]
    # (the upper half circle in SVG's y-down frame is y <= 40)
    parts = [lambda p: dist_arc(p, (40, 40), 30.0, lambda a: a <= 1e-9),
             lambda p: dist_bezier(p, [(70, 40), (60, 60), (20, 60), (10, 40)])]
    err = on_outline(local, parts) * np.linalg.norm(tf[:2, :2], 2)
    assert err.max() <= ACC * piece.size, err.max()


@pytest.mark.parametrize("head, root, per_inch", [
    ("<!-- Generator: Adobe Illustrator 27.1.0, SVG Export Plug-In . SVG Version: 6.00 Build 0) -->", "", 72),
    ("", 'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" inkscape:version="0.48.4 r9939"', 90),
    ("", 'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" inkscape:version="0.91 r13725"', 90),
    ("", 'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" inkscape:version="0.92.4 (5da689c313, 2019-01-14)"', 96),
    ("", 'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" inkscape:version="1.4.3 (1:1.4.3)"', 96),
    ("", 'class="freesewing"', 90),
    ("", "", 96),
])
@pytest.mark.parametrize("size", ['width="300" height="200"', 'width="300px" height="200px" viewBox="0 0 300 200"',
                                  "", 'width="300mm" height="200mm" viewBox="0 0 300 200"'])
def test_svg_px_per_inch_is_the_writing_programs(tmp_path, head, root, per_inch, size):
    """A px is 1/96 in in CSS, but Adobe Illustrator writes 72 px an inch, Inkscape up to 0.91 and
    FreeSewing's first core 90: a 96 px square is 1 inch at 96 and more at fewer px an inch,
    whether the px come from the <svg> width and height or from user units with none; a file whose
    width and height are in mm with a viewBox does not depend on it."""
    path = tmp_path / "px.svg"
    path.write_text(f'<?xml version="1.0"?>\n{head}\n<svg xmlns="http://www.w3.org/2000/svg" {root} {size}>'
                    '<rect id="sq" x="10" y="10" width="96" height="96"/></svg>')
    (piece,) = read_pieces(path)
    want = 96.0 if "mm" in size else 96 * 25.4 / per_inch
    assert piece.extent == pytest.approx((want, want), rel=1e-12)


def test_svg_use_draws_what_it_names(tmp_path):
    """An outline drawn only through <use> (an online editor's export: the path in <defs>): each
    <use> draws it, moved by its transform and then its x, y, as in SVG; a <use> of a <symbol>
    draws the symbol's shapes; a <use> of its own group (a cycle) and of a missing id draw nothing."""
    xl = 'xmlns:xlink="http://www.w3.org/1999/xlink"'
    path = tmp_path / "use.svg"
    path.write_text(
        f'<svg xmlns="http://www.w3.org/2000/svg" {xl} width="300mm" height="100mm" viewBox="0 0 300 100">'
        '<defs><path id="p" d="M 0 0 L 40 0 L 40 30 L 0 30 Z"/></defs>'
        '<symbol id="s"><rect x="0" y="0" width="20" height="20"/></symbol>'
        '<use xlink:href="#p" x="10" y="10"/>'
        '<use href="#p" transform="translate(100 0)" x="5" y="50"/>'
        '<use xlink:href="#s" x="200" y="10"/>'
        '<g id="loop"><use xlink:href="#loop"/></g><use xlink:href="#nowhere"/></svg>')
    pieces = read_pieces(path)
    assert len(pieces) == 3
    boxes = sorted((p.outline.min(axis=0).round(9).tolist(), p.outline.max(axis=0).round(9).tolist())
                   for p in pieces)
    # user units are mm; y runs up from the page's bottom edge (100 mm)
    assert boxes == [([10.0, 60.0], [50.0, 90.0]), ([105.0, 20.0], [145.0, 50.0]), ([200.0, 70.0], [220.0, 90.0])]


def test_marked_annotations_are_made_only_when_included(tmp_path, monkeypatch):
    """An outline the file's structure marks as an annotation (a FreeSewing logo's glyphs, drawn
    through <use>) is skipped without being sampled: its size from its control points; named in
    --include it is made then, as it would have been (a glyph that cannot be made says why)."""
    from clothgrid.patterns import piece as piece_mod

    path = tmp_path / "logo.svg"
    path.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="100mm" viewBox="0 0 300 100">'
        '<defs><g id="logo"><path id="ring" d="M 0 10 C 0 -3 20 -3 20 10 C 20 23 0 23 0 10 Z"/>'
        '<path id="flat" d="M 0 0 L 5 0 Z"/></g></defs>'
        '<path id="body" d="M 100 10 L 200 10 L 200 90 L 100 90 Z"/>'
        '<use href="#logo" x="20" y="30"/></svg>')
    made = []
    real = piece_mod.piece_from_primitives
    monkeypatch.setattr("clothgrid.patterns.svg.piece_from_primitives",
                        lambda name, *a, **k: made.append(name) or real(name, *a, **k))
    got = read_pieces(path)
    assert [p.name for p in got] == ["body"] and made == ["body"]
    ring = next(s for s in got.skipped if s.name == "ring")
    assert ring.kind == "mark" and ring.piece is None and ring.meta["use"] == "logo"
    assert ring.as_dict()["size_mm"] == pytest.approx([20.0, 26.0])      # the control points' box
    inc = read_pieces(path, include=["ring"])
    assert [p.name for p in inc] == ["body", "ring"] and made[-1] == "ring"
    r = inc[1]
    assert r.extent[0] == pytest.approx(20.0, rel=1e-6) and r.extent[1] == pytest.approx(19.5, rel=1e-3)
    with pytest.raises(InputError, match="outline 'flat' cannot be gridded"):
        read_pieces(path, include=["flat"])


def _line(a, b):
    from clothgrid.patterns.sampling import Bezier

    return [Bezier(np.array([a, b], dtype=np.float64))]


def test_outer_loops_trace_the_boundary_around_forked_chains(rng):
    """chains.outer_loops: chains that fork (a panel's edges and a waist line across it) give the
    boundary around them, in order, whatever the chains' order and direction, with ends up to the
    tolerance apart; a line that only touches the outline is left out, the waist line is inner;
    two panels sharing an edge give the boundary of both; a drawing whose boundary would run along
    a chain twice (two squares joined by a bridge) gives none; chains with no fork give none."""
    from clothgrid.geometry import signed_area
    from clothgrid.patterns.chains import outer_loops
    from clothgrid.patterns.sampling import Bezier

    def shuffle(chains):
        order = rng.permutation(len(chains))
        out = []
        for k in order:
            c = chains[k]
            if rng.random() < 0.5:
                c = [Bezier(p.ctrl[::-1].copy()) for p in reversed(c)]
            out.append(c)
        return out, order

    def jitter(p):
        return np.asarray(p, dtype=float) + rng.uniform(-3e-4, 3e-4, 2)

    sq = [(0, 0), (10, 0), (10, 20), (0, 20)]
    edges = [_line(jitter(sq[k]), jitter(sq[(k + 1) % 4])) for k in range(4)]
    waist = _line((10, 8), (0, 8))           # ends on the side edges: split them at y = 8
    right = [_line(sq[1], (10, 8)), _line((10, 8), sq[2])]
    left = [_line(sq[3], (0, 8)), _line((0, 8), sq[0])]
    grain = _line((5, 0), (5, -4))           # touches the bottom edge's middle only: not a node
    hook = _line((10, 20), (14, 25))         # one end at a corner, the other free
    chains = [edges[0], *right, edges[2], *left, waist, grain, hook]
    for _ in range(5):
        got_chains, order = shuffle(chains)
        (prims, used, inner), = outer_loops(got_chains, 1e-3)
        assert sorted(order[used]) == [0, 1, 2, 3, 4, 5] and list(order[inner]) == [6]
        pts = np.array([p.start for p in prims])
        assert abs(abs(signed_area(pts)) - 200.0) < 0.05
        assert all(np.linalg.norm(a.end - b.start) <= 2e-3 for a, b in zip(prims, prims[1:] + prims[:1]))
    # two panels side by side sharing their middle edge
    two = [_line((0, 0), (10, 0)), _line((10, 0), (20, 0)), _line((20, 0), (20, 5)), _line((20, 5), (10, 5)),
           _line((10, 5), (0, 5)), _line((0, 5), (0, 0)), _line((10, 0), (10, 5))]
    (prims, used, inner), = outer_loops(two, 1e-6)
    assert sorted(used) == [0, 1, 2, 3, 4, 5] and inner == [6]
    assert abs(abs(signed_area(np.array([p.start for p in prims]))) - 100.0) < 1e-9
    # two squares joined by a bridge: the boundary would run along the bridge twice
    a = [_line((0, 0), (1, 0)), _line((1, 0), (1, 1)), _line((1, 1), (0, 1)), _line((0, 1), (0, 0))]
    b = [_line((5, 0), (6, 0)), _line((6, 0), (6, 1)), _line((6, 1), (5, 1)), _line((5, 1), (5, 0))]
    assert outer_loops(a + b + [_line((1, 0), (5, 0))], 1e-6) == []
    assert outer_loops(a, 1e-6) == []                  # no fork: chain_loops' case
    # a line from a corner to the middle of the opposite side (not a node there): left out, and
    # the loop it forked from is the outline
    (prims, used, inner), = outer_loops(a + [_line((0, 0), (0.5, 1))], 1e-6)
    assert sorted(used) == [0, 1, 2, 3] and inner == []
    assert abs(abs(signed_area(np.array([p.start for p in prims]))) - 1.0) < 1e-12


def test_svg_panel_drawn_as_edges_with_a_waist_line(tmp_path):
    """An Inkscape corset panel drawn as six open edge paths (ends a micrometre apart) and a waist
    line across it: one piece, its boundary, the waist line named as an inner line."""
    path = tmp_path / "corset.svg"
    path.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="200mm" viewBox="0 0 100 200"><g id="A">'
        '<path id="A_WAIST" d="M 1.301 100.478 L 74.953 93.722"/>'
        '<path id="A_TOP" d="M 3.038 4.145 L 78.142 3.935"/>'
        '<path id="AB_UP" d="M 78.142 3.935 L 74.953 93.722"/>'
        '<path id="AB_DOWN" d="M 74.953 93.722 L 73.187 187.774"/>'
        '<path id="A_BOTTOM" d="M 0.161 198.066 C 24.559 198.225 59.578 190.786 73.187 187.774"/>'
        '<path id="AA_DOWN" d="M 0.161 198.066 L 1.301 100.474"/>'
        '<path id="AA_UP" d="M 3.038 4.145 L 1.301 100.477"/></g></svg>')
    (piece,) = read_pieces(path)
    assert piece.name == "A" and piece.meta["inner_lines"] == ["A_WAIST"]
    assert sorted(piece.meta["joined"]) == sorted(["A_TOP", "AB_UP", "AB_DOWN", "A_BOTTOM", "AA_DOWN", "AA_UP"])
    assert any("around 1 inner line ('A_WAIST')" in n for n in piece.notes)
    assert piece.extent[1] == pytest.approx(198.225 - 3.935, abs=0.5)


def test_svg_load_single_boundary(tmp_path, svg_file):
    path = tmp_path / "one.svg"
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="50mm" '
                    'viewBox="0 0 100 50"><rect x="10" y="10" width="60" height="30"/></svg>')
    b = load_single_boundary(path)
    assert b.side_lengths == pytest.approx((60, 30, 60, 30))
    assert np.allclose(b.bottom[0, :2], [10, 10]) and np.allclose(b.top[-1, :2], [70, 40])
    with pytest.raises(InputError, match="has 2 pieces"):
        load_single_boundary(svg_file)


# --------------------------------------------------------------------------- plain DXF


def _plain_dxf(path: Path, units: int = 5) -> dict:
    """A closed LWPOLYLINE with a bulge, a closed SPLINE-free chain of LINEs and an ARC."""
    doc = ezdxf.new("R2010")
    doc.units = units
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0, 0), (40, 0, 0), (40, 30, 0.4), (0, 30, 0)], format="xyb",
                       close=True)
    # a chain: two lines and a half circle, drawn in mixed directions
    msp.add_line((60, 0), (100, 0))
    msp.add_line((60, 30), (60, 0))
    msp.add_arc(center=(100, 15), radius=15, start_angle=-90, end_angle=90)
    msp.add_line((100, 30), (60, 30))
    msp.add_line((200, 200), (210, 210))           # open: ignored
    doc.saveas(path)
    return {"scale": {4: 1.0, 5: 10.0}[units]}


def test_plain_dxf_drawn_by_hand_with_gaps_and_construction_lines(tmp_path):
    """A plain DXF panel drawn as LINEs and an ARC whose ends miss each other by up to 0.4 mm, with
    a waist line across it and a grain line touching nothing: one piece, the boundary around them,
    the gaps and the inner line in its note. Ends 3 mm apart join nothing."""

    def draw(g: float) -> Path:
        doc = ezdxf.new("R2010")
        doc.units = 4                                   # mm
        msp = doc.modelspace()
        msp.add_line((0, 0), (200, 0))
        msp.add_line((200 + g, 0.1), (200, 140))
        msp.add_arc(center=(100, 140 + g / 2), radius=100, start_angle=0, end_angle=180)
        msp.add_line((0, 140), (0, g))
        msp.add_line((0, 70), (200, 70))                # a waist line ending on the sides (not at their ends)
        msp.add_line((100, 20), (100, 120))             # a grain line, meeting nothing
        path = tmp_path / f"hand{g}.dxf"
        doc.saveas(path)
        return path

    # the waist line ends on the sides' middles (not at ends): left out, like the grain line
    (piece,) = read_pieces(draw(0.4))
    area = 200 * 140 + math.pi * 100 ** 2 / 2
    assert piece.area == pytest.approx(area, rel=2e-3)
    assert piece.meta["gap_mm"] == pytest.approx(0.4, abs=0.05)
    assert any("joined from 4 lines and curves" in n and "across gaps of up to" in n for n in piece.notes)
    assert any("2 open line(s) and curves were ignored" in n for n in piece.notes)
    with pytest.raises(InputError, match="no closed polyline"):
        read_pieces(draw(3.0))
    # a waist line from end to end of split sides is an inner line of the outline around them
    doc = ezdxf.new("R2010")
    doc.units = 4
    msp = doc.modelspace()
    for a, b in [((0, 0), (200, 0)), ((200.3, 0), (200, 70)), ((200, 70.2), (200, 140)), ((200, 140), (0, 140)),
                 ((0, 140), (0, 70.3)), ((0, 70), (0, 0.2)), ((0.1, 70), (200.2, 70))]:
        msp.add_line(a, b)
    doc.saveas(tmp_path / "waist.dxf")
    (piece,) = read_pieces(tmp_path / "waist.dxf")
    assert piece.area == pytest.approx(200 * 140, rel=1e-3)
    assert any("joined from 6 lines and curves" in n and "around 1 inner line" in n for n in piece.notes)


@pytest.mark.parametrize("shape", ["rectangle", "pentagon"])
def test_dxf_lines_that_cross_near_their_ends_make_the_outline(tmp_path, rng, shape):
    """A piece drafted with corner lines that overshoot (cross a few mm past each other, in random
    order and directions): cut at the crossings, the ends past them left out, the outline exact.
    Lines crossing in their middles (a drill hole's cross, a grid) make nothing."""
    import ezdxf

    if shape == "rectangle":
        corners = np.array([[0, 0], [300, 0], [300, 500], [0, 500]], dtype=float)
    else:
        corners = np.array([[0, 0], [260, -20], [330, 240], [150, 420], [-40, 260]], dtype=float)
    corners = corners + rng.uniform(-50, 50, size=2)
    n = len(corners)
    doc = ezdxf.new("R2010")
    doc.units = 4
    msp = doc.modelspace()
    order = rng.permutation(n)
    for k in order:
        a, b = corners[k], corners[(k + 1) % n]
        d = (b - a) / np.linalg.norm(b - a)
        a2, b2 = a - d * rng.uniform(0, 12), b + d * rng.uniform(0.5, 12)   # at least one end overshoots
        if rng.random() < 0.5:
            a2, b2 = b2, a2
        msp.add_line(tuple(a2), tuple(b2))
    c = corners.mean(axis=0)
    msp.add_line(tuple(c - [20, 0]), tuple(c + [20, 0]))        # a cross in the middle: not an outline
    msp.add_line(tuple(c - [0, 20]), tuple(c + [0, 20]))
    doc.saveas(tmp_path / "cross.dxf")
    (piece,) = read_pieces(tmp_path / "cross.dxf")
    x, y = corners[:, 0], corners[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))
    assert piece.area == pytest.approx(area, rel=1e-9)
    # every corner is an outline point, and every outline point a corner
    pts = piece.outline
    assert len(pts) == n
    assert max(np.hypot(*(pts - q).T).min() for q in corners) < 1e-9
    assert any("cross near their ends" in note for note in piece.notes)
    # the same lines crossing in their middles are no piece
    doc = ezdxf.new("R2010")
    doc.units = 4
    msp = doc.modelspace()
    for k in range(n):
        a, b = corners[k], corners[(k + 1) % n]
        d = b - a
        msp.add_line(tuple(a - 0.5 * d), tuple(b + 0.5 * d))
    doc.saveas(tmp_path / "grid.dxf")
    with pytest.raises(InputError, match="no closed polyline"):
        read_pieces(tmp_path / "grid.dxf")


def test_plain_dxf_pieces_and_accuracy(tmp_path):
    from ezdxf.math import bulge_to_arc

    path = tmp_path / "plain.dxf"
    s = _plain_dxf(path)["scale"]
    pieces = read_pieces(path)
    assert [p.name for p in pieces] == ["piece1", "piece2"]
    poly, chain = pieces
    assert poly.units == "cm" and poly.source == "dxf"
    c, a0, a1, r = bulge_to_arc((40, 30), (0, 30), 0.4)
    grid = generate_piece(poly, NODES)
    nodes = boundary_nodes(grid) / s
    parts = [lambda p: dist_segment(p, (0, 0), (40, 0)),
             lambda p: dist_segment(p, (40, 0), (40, 30)),
             lambda p: np.where(p[:, 1] >= 30 - 1e-9, np.abs(np.hypot(p[:, 0] - c[0], p[:, 1] - c[1]) - r),
                                np.inf),
             lambda p: dist_segment(p, (0, 30), (0, 0))]
    err = on_outline(nodes, parts).max() * s
    assert err <= ACC * poly.size, err
    # the chain of lines and an arc closes into the second piece
    g2 = generate_piece(chain, NODES)
    nodes = boundary_nodes(g2) / s
    parts = [lambda p: dist_segment(p, (60, 0), (100, 0)), lambda p: dist_segment(p, (60, 30), (60, 0)),
             lambda p: dist_segment(p, (100, 30), (60, 30)),
             lambda p: dist_arc(p, (100, 15), 15.0, lambda a: np.abs(a) <= np.pi / 2 + 1e-9)]
    err = on_outline(nodes, parts).max() * s
    assert err <= ACC * chain.size, err
    assert chain.extent == pytest.approx((550.0, 300.0), abs=chain.tolerance)


def test_plain_dxf_pieces_named_by_their_texts(tmp_path):
    """A plain drawing's ``Piece Name:`` and ``Size:`` texts name the outlines they are written on: on
    the outline's own layer, inside it or beside a narrow strip (within its size, less than half as
    far from it as from any other outline of the layer); two sizes drawn on top of each other, a
    layer each, stay apart (a size's cut line is no seam allowance of another size's sew line); of a
    piece's cut and sew lines the one gridded keeps the name, and ``pieceN`` stays an alias. Texts of
    several pieces or sizes inside one outline (on another layer) name nothing."""
    import ezdxf

    doc = ezdxf.new("R2000")
    doc.header["$INSUNITS"] = 5                                   # cm
    msp = doc.modelspace()

    def rect(x0, y0, w, h, layer):
        msp.add_lwpolyline([(x0, y0), (x0 + w, y0), (x0 + w, y0 + h), (x0, y0 + h)], close=True,
                           dxfattribs={"layer": layer})

    for layer, size, grow in (("S", "Small", 0.0), ("L", "Large", 2.0)):
        rect(0, 0, 40 + grow, 60 + grow, layer)                   # the body's cut line
        rect(1, 1, 38 + grow, 58 + grow, layer)                   # its sew line, 1 cm inside
        rect(60, 0, 50 + grow, 4, layer)                          # a strip's cut line
        rect(60.5, 0.5, 49 + grow, 3, layer)                      # its sew line
        for text, at in ((f"Size: {size}", (10, 30)), ("Piece Name: Body", (10, 28)),
                         ("Quantity: 2", (10, 26)),
                         (f"Size: {size}", (70, 7)), ("Piece Name: Strip", (75, 7))):   # beside the strip
            msp.add_text(text, dxfattribs={"layer": layer, "insert": at, "height": 1})
    rect(0, 100, 30, 30, "0")                                      # two pieces' texts inside: no name
    for text, at in (("Piece Name: A", (5, 110)), ("Piece Name: B", (5, 120))):
        msp.add_text(text, dxfattribs={"layer": "T", "insert": at, "height": 1})
    path = tmp_path / "graded.dxf"
    doc.saveas(path)

    sew = read_pieces(path)
    by = {p.name: p for p in sew}
    assert sorted(by) == ["Body_Large", "Body_Small", "Strip_Large", "Strip_Small", "piece9"]
    assert by["Body_Small"].extent == pytest.approx((380.0, 580.0))            # the sew line, in mm
    assert by["Body_Small"].meta["line"] == "sew" and by["Body_Small"].meta["size"] == "Small"
    assert by["Body_Small"].meta["quantity"] == "2" and by["Body_Small"].aliases == ("piece2",)
    assert {s.name: (s.kind, s.of) for s in sew.skipped} == {
        f"{n}_{z}-2": ("seam allowance", f"{n}_{z}") for n in ("Body", "Strip") for z in ("Small", "Large")}
    cut = {p.name: p for p in read_pieces(path, line="cut")}
    assert sorted(cut) == sorted(by)
    assert cut["Strip_Large"].extent == pytest.approx((520.0, 40.0))
    assert cut["Strip_Large"].aliases == ("piece7",) and sew.resolve("piece7") == "Strip_Large-2"


def test_optitex_graded_flat_dxf():
    """Optitex's graded Basic Tee (tests/data/optitex): 4 pieces in 8 sizes, a layer a size, drawn on
    top of each other; each piece named by its texts and size, gridded along its sew line with its
    cut line skipped as the seam allowance; no units in the file (an error naming --units)."""
    src = Path(__file__).parent / "data" / "optitex" / "basic_tee_graded.dxf"
    with pytest.raises(InputError, match=r"measures 110.2 across \(0.11 m in mm, 1.1 m in cm, 2.8 m in in\).*--units"):
        read_pieces(src)
    got = read_pieces(src, units="cm")
    sizes = ["XS", "Small", "Medium", "Large", "XL", "2XL", "3XL", "4XL"]
    names = [f"{n}_{z}" for n in ("Front", "Back", "Right Sleeve", "Neck Binding") for z in sizes]
    assert sorted(p.name for p in got) == sorted(names)
    assert got.failed == [] and all(p.meta["line"] == "sew" for p in got)
    assert sorted(s.of for s in got.skipped if s.kind == "seam allowance") == sorted(names)
    by = {p.name: p for p in got}
    assert by["Front_Small"].meta["material"] == "Self" and by["Neck Binding_Small"].meta["material"] == "Contrast 1"
    # the sample size's sew lines have the areas its texts say (Area: 0.3392 sq.m for the front)
    assert by["Front_Small"].area == pytest.approx(0.3392e6, rel=1e-3)
    # graded: each size larger than the one before
    for n in ("Front", "Back", "Right Sleeve", "Neck Binding"):
        areas = [by[f"{n}_{z}"].area for z in sizes]
        assert all(b > a for a, b in zip(areas, areas[1:]))


def test_grade_picks_one_size_of_a_graded_pattern(tmp_path, capsys):
    """``--grade SIZE``: of a graded pattern, only the pieces (and skipped outlines) of that size,
    case aside; an unknown size lists the file's sizes, a file without sizes says it is not graded,
    and a boundary file refuses it (exit 2, one error line each, nothing written)."""
    src = Path(__file__).parent / "data" / "optitex" / "basic_tee_graded.dxf"
    assert main(["pieces", str(src), "--units", "cm", "--grade", "medium", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert [p["name"] for p in got["pieces"]] == ["Front_Medium", "Back_Medium", "Right Sleeve_Medium",
                                                  "Neck Binding_Medium"]
    assert [s["of"] for s in got["skipped"]] == [p["name"] for p in got["pieces"]]
    out = tmp_path / "out"
    assert main(["generate", str(src), "--units", "cm", "--grade", "XS", "--piece", "Neck Binding_XS",
                 "-o", str(out / "{piece}.npz"), "-q"]) == 0, capsys.readouterr().err
    assert [f.name for f in out.iterdir()] == ["Neck_Binding_XS.npz"]
    capsys.readouterr()
    for args, words in (([str(src), "--units", "cm", "--grade", "XXL"], "no piece of that size; its sizes are 'XS', "
                                                                          "'Small', 'Medium'"),
                        ([str(Path(__file__).parent / "data" / "freesewing" / "aaron_v3_pattern.svg"), "--grade", "M"],
                         "not graded")):
        assert main(["pieces", *args]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("clothgrid: error:") == 1
    boundary = tmp_path / "b.json"
    boundary.write_text(json.dumps({"outline": [[0, 0], [1, 0], [1, 1], [0, 1]], "corners": [0, 1, 2, 3]}))
    assert main(["generate", str(boundary), "--grade", "M", "-o", str(tmp_path / "g.npz"), "-q"]) == 2
    assert "--grade is for pattern files" in capsys.readouterr().err
    assert not (tmp_path / "g.npz").exists()


def test_dxf_spline_matches_ezdxf(tmp_path):
    doc = ezdxf.new("R2010")
    doc.units = 4
    ctrl = [(0, 0), (30, -10), (60, 0), (70, 40), (30, 60), (-10, 40), (0, 0)]
    doc.modelspace().add_open_spline([(x, y, 0) for x, y in ctrl], degree=3)
    path = tmp_path / "spline.dxf"
    doc.saveas(path)
    (piece,) = read_pieces(path)
    spline = ezdxf.readfile(path).modelspace().query("SPLINE")[0].construction_tool()
    knots = spline.knots()
    dense = np.array([list(v)[:2] for v in spline.points(np.linspace(knots[3], knots[-4], 200001))])
    # every outline point lies on the spline (up to the dense reference's own chord error)
    assert dist_polyline(piece.outline, dense).max() < 1e-8 * piece.size
    # and every point of the spline is within the sampling tolerance of the outline
    assert dist_polyline(dense[::7], piece.outline, closed=True).max() <= piece.tolerance * (1 + 1e-6)
    grid = generate_piece(piece, NODES)
    assert grid.info["piece"]["corners"]["method"] in ("equal-sides", "split", "scored", "candidates")


def test_bspline_decomposition_matches_ezdxf():
    from ezdxf.math import BSpline

    rng = np.random.default_rng(7)
    for trial in range(12):
        p = 1 + trial % 4
        n = p + 1 + trial % 5
        ctrl = rng.normal(size=(n, 2))
        w = rng.random(n) + 0.2 if trial % 2 else None
        knots = (np.arange(n + p + 1, dtype=float) if trial % 3 == 0
                 else np.r_[[0.0] * (p + 1), np.sort(rng.random(n - p - 1)), [1.0] * (p + 1)])
        ref = BSpline([(x, y, 0) for x, y in ctrl], order=p + 1, knots=knots.tolist(),
                      weights=None if w is None else w.tolist())
        pieces = bspline_to_beziers(p, knots, ctrl, w)
        span = np.unique(knots[(knots >= knots[p]) & (knots <= knots[n])])
        assert len(pieces) == len(span) - 1
        for bz, u0, u1 in zip(pieces, span[:-1], span[1:]):
            t = np.linspace(0, 1, 5)
            want = np.array([list(ref.point(float(u0 + x * (u1 - u0))))[:2] for x in t])
            assert np.abs(bz.points(t) - want).max() < 1e-9


# --------------------------------------------------------------------------- AAMA / ASTM DXF

FRONT = [(0, 0), (20, 0), (21, 10), (22, 20), (20, 28), (12, 30), (6, 26), (0, 30)]
FRONT_TURNS = [0, 1, 5, 7]      # the file's turn points (indices into FRONT)
BACK = [(0, 0), (18, 0), (18, 25), (0, 25)]


def _aama(path: Path, units_text: str = "ENGLISH", closed: bool = False) -> None:
    doc = ezdxf.new("R12")
    for name, pts, turns, grain in (("B1", FRONT, FRONT_TURNS, [(10, 5), (10, 25)]),
                                    ("B2", BACK, [0, 1, 2, 3], [(3, 12), (15, 12)])):
        blk = doc.blocks.new(name=name)
        blk.add_polyline2d(pts + ([] if closed else [pts[0]]), close=closed,
                           dxfattribs={"layer": "1"})
        for i in turns:
            blk.add_point(pts[i], dxfattribs={"layer": "2"})
        blk.add_line(*grain, dxfattribs={"layer": "7"})
        blk.add_text(f"Piece Name: {'FRONT' if name == 'B1' else 'BACK'}", dxfattribs={"layer": "1"})
        blk.add_text("Size: M", dxfattribs={"layer": "1"})
    msp = doc.modelspace()
    msp.add_text(f"Units: {units_text}", dxfattribs={"layer": "1"})
    msp.add_blockref("B1", (100, 0))
    msp.add_blockref("B2", (0, 0), dxfattribs={"rotation": 90})
    doc.saveas(path)


def test_aama_dxf_turn_points_grain_and_accuracy(tmp_path):
    path = tmp_path / "style.dxf"
    _aama(path)
    front, back = read_pieces(path)
    assert (front.name, back.name) == ("FRONT", "BACK")
    assert front.source == "aama-dxf" and front.units == "in"
    assert len(front.turn_points) == 4
    # the turn points are the corners, even though (20, 28) turns more sharply than (6, 26)
    choice = choose_corners(front)
    assert choice.method == "turn-points"
    want = (np.array(FRONT)[FRONT_TURNS] + [100, 0]) * 25.4
    assert np.allclose(np.sort(choice.points, axis=0), np.sort(want, axis=0))
    assert np.allclose(choice.points[0], want[0])            # bottom-left at the origin corner
    assert np.allclose(front.grain_line, np.array([[110, 5], [110, 25]]) * 25.4)
    grid = generate_piece(front, NODES)
    poly = (np.array(FRONT) + [100, 0]) * 25.4
    nodes = boundary_nodes(grid)
    parts = [lambda p, a=a, b=b: dist_segment(p, a, b) for a, b in zip(poly, np.roll(poly, -1, 0))]
    assert on_outline(nodes, parts).max() <= ACC * front.size
    # the back piece is rotated 90 degrees by its INSERT; its grain line then runs along y,
    # so the bottom side is the one across it
    assert np.allclose(back.grain_line, np.array([[-12, 3], [-12, 15]]) * 25.4)
    bchoice = choose_corners(back)
    bl, br = bchoice.points[0], bchoice.points[1]
    assert abs(br[1] - bl[1]) < 1e-9 and br[0] > bl[0]


def test_aama_metric_and_closed_polyline(tmp_path):
    path = tmp_path / "metric.dxf"
    _aama(path, units_text="METRIC", closed=True)
    front, _ = read_pieces(path)
    assert front.units == "mm"
    assert front.extent == pytest.approx((22.0, 30.0))


def test_aama_dxf_names_in_utf8_or_a_code_page_and_their_output_files(capsys, tmp_path):
    """An R12 DXF has no encoding of its own (ezdxf takes cp1252): text that is valid UTF-8 with
    multi-byte characters is read as UTF-8 (a real ET export's Chinese piece names came out as
    mojibake), single-byte text as before; output names keep letters of any script."""
    path = tmp_path / "style.dxf"
    _aama(path, units_text="METRIC", closed=True)
    raw = path.read_bytes()
    (tmp_path / "utf8.dxf").write_bytes(raw.replace(b"FRONT", "前片".encode()).replace(b"BACK", "后片".encode()))
    (tmp_path / "cp1252.dxf").write_bytes(raw.replace(b"FRONT", "FÄR".encode("cp1252")))
    assert [p.name for p in read_pieces(tmp_path / "utf8.dxf")] == ["前片", "后片"]
    assert [p.name for p in read_pieces(tmp_path / "cp1252.dxf")] == ["FÄR", "BACK"]
    # GBK (GB2312 characters), as Chinese pattern CAD systems write it, with or without a header
    # naming ANSI_1252; single-byte text whose accented letters stand between ASCII ones is not GBK
    gbk = raw.replace(b"FRONT", "前片".encode("gbk")).replace(b"BACK", "后片(袖)".encode("gbk"))
    assert b"$DWGCODEPAGE" in gbk
    (tmp_path / "gbk.dxf").write_bytes(gbk)
    assert [p.name for p in read_pieces(tmp_path / "gbk.dxf")] == ["前片", "后片(袖)"]
    (tmp_path / "cp1252b.dxf").write_bytes(raw.replace(b"FRONT", "Épaule é".encode("cp1252")))
    assert [p.name for p in read_pieces(tmp_path / "cp1252b.dxf")] == ["Épaule é", "BACK"]
    (tmp_path / "big5.dxf").write_bytes(gbk.replace(b"ANSI_1252", b"ANSI_950"))   # a code page named: ezdxf's
    assert [p.name for p in read_pieces(tmp_path / "big5.dxf")][0] == "前片".encode("gbk").decode("cp950")
    out = tmp_path / "out"
    code, _, err = run(capsys, "generate", tmp_path / "utf8.dxf", "-o", out / "{piece}.npz", "--nodes", "5", "-q")
    assert code == 0, err
    assert files(out) == ["前片.npz", "后片.npz"]


# --------------------------------------------------------------------------- GarmentCode

GC = {
    "pattern": {
        "panels": {
            "skirt_front": {
                "translation": [0, 80, 20], "rotation": [0, 0, 0],
                "vertices": [[0, 0], [50, 0], [45, 60], [5, 60]],
                "edges": [
                    {"endpoints": [0, 1], "curvature": {"type": "quadratic", "params": [[0.5, -0.1]]}},
                    {"endpoints": [1, 2]},
                    {"endpoints": [2, 3], "curvature": {"type": "circle", "params": [40, 0, 0]}},
                    {"endpoints": [3, 0], "curvature": {"type": "cubic",
                                                         "params": [[0.3, 0.05], [0.7, 0.05]]}},
                ]},
            "band": {"vertices": [[0, 0], [60, 0], [60, 5], [0, 5]],
                     "edges": [{"endpoints": [0, 1]}, {"endpoints": [2, 1]},
                               {"endpoints": [2, 3]}, {"endpoints": [3, 0]}]},
        },
        "stitches": []},
    "properties": {"units_in_meter": 100, "curvature_coords": "relative"},
}


def _rel(a, b, uv):
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = b - a
    return a + uv[0] * d + uv[1] * np.array([-d[1], d[0]])


def test_garmentcode_pieces_and_accuracy(tmp_path):
    from svgpathtools import Arc

    path = tmp_path / "skirt_specification.json"
    path.write_text(json.dumps(GC))
    pieces = read_pieces(path)
    assert [p.name for p in pieces] == ["skirt_front", "band"]
    skirt, band = pieces
    assert skirt.units == "cm" and skirt.meta["translation"] == [0, 80, 20]
    assert len(skirt.turn_points) == 4
    assert band.extent == pytest.approx((600.0, 50.0))
    grid = generate_piece(skirt, NODES)
    nodes = boundary_nodes(grid) / 10.0                       # back to cm
    v = np.array(GC["pattern"]["panels"]["skirt_front"]["vertices"], float)
    # GarmentCode's own reading: svgpathtools Arc with sweep = "right" in the panel's frame
    arc = Arc(complex(*v[2]), complex(40, 40), 0, False, False, complex(*v[3]))

    def dist_gc_arc(p):
        return dist_arc(p, (arc.center.real, arc.center.imag), 40.0,
                        lambda a: in_sweep(a, np.radians(arc.theta), np.radians(arc.delta)))

    parts = [lambda p: dist_bezier(p, [v[0], _rel(v[0], v[1], [0.5, -0.1]), v[1]]),
             lambda p: dist_segment(p, v[1], v[2]),
             dist_gc_arc,
             lambda p: dist_bezier(p, [v[3], _rel(v[3], v[0], [0.3, 0.05]),
                                       _rel(v[3], v[0], [0.7, 0.05]), v[0]])]
    err = on_outline(nodes, parts).max() * 10.0
    assert err <= ACC * skirt.size, err
    # the circle edge bulges into the panel ("right" = 0 on an edge running right to left)
    assert skirt.outline[:, 1].max() == pytest.approx(600.0)
    assert grid.info["piece"]["corners"]["method"] == "turn-points"


# --------------------------------------------------------------------------- corners and units


def _poly_piece(points, name="p", **kw) -> Piece:
    pts = np.asarray(points, float)
    return piece_from_polygon(name, pts, vertices=np.arange(len(pts)), **kw)


def test_corners_scored_when_more_than_four():
    # a pentagon-ish house: four right angles and a shallow roof apex (turn 2 x 15 deg)
    house = [(0, 0), (40, 0), (40, 30), (20, 35), (0, 30)]
    piece = _poly_piece(house)
    choice = choose_corners(piece, min_turn=5)
    assert choice.method == "scored"
    assert sorted(choice.corners) == [0, 1, 2, 4]
    assert "left out outline indices 3" in choice.message


def test_corners_split_and_equal_sides():
    # a triangle with a dense hypotenuse: 3 corners, the fourth in the middle of the longest side
    t = np.linspace(0, 1, 41)[1:-1]
    tri = np.vstack([[0, 0], [30, 0], np.column_stack([30 - 30 * t, 40 * t]), [0, 40]])
    choice = choose_corners(_poly_piece(tri))
    assert choice.method == "split" and len(set(choice.corners)) == 4
    mid = choice.outline[[i for i in choice.corners if i not in (0, 1, len(tri) - 1)][0]]
    assert np.allclose(mid, [15, 20])
    # a straight-sided quad with only two sharp turns gets inserted points
    sliver = _poly_piece([(0, 0), (50, -1), (100, 0), (50, 1)])
    c2 = choose_corners(sliver)
    assert len(set(c2.corners)) == 4
    b = piece_boundary(sliver, choice=c2)
    assert min(b.side_lengths) > 0


def test_corners_given_and_near():
    piece = _poly_piece([(0, 0), (10, 0), (20, 0), (20, 10), (0, 10)])
    c = choose_corners(piece, corners=[0, 2, 3, 4])
    assert c.corners == (0, 2, 3, 4) and c.method == "given"
    c = choose_corners(piece, near=[(0.1, 0.1), (19, 1), (21, 11), (-1, 9)])
    assert c.corners == (0, 2, 3, 4) and c.method == "near"
    with pytest.raises(InputError, match="out of range"):
        choose_corners(piece, corners=[0, 2, 3, 9])
    with pytest.raises(InputError, match="not both"):
        choose_corners(piece, corners=[0, 2, 3, 4], near=[(0, 0)] * 4)
    cands = corner_candidates(piece)
    assert [x.index for x in cands] == [0, 2, 3, 4]


@pytest.mark.parametrize("text, mm", [("5mm", 5.0), ("0.5 cm", 5.0), ("1in", 25.4), ("12", 12.0),
                                      ("72pt", 25.4), ("96px", 25.4)])
def test_parse_length(text, mm):
    assert parse_length(text) == pytest.approx(mm)


@pytest.mark.parametrize("text", ["5 furlongs", "-3mm", "0", "mm", "5e999mm"])
def test_parse_length_rejects(text):
    with pytest.raises(InputError):
        parse_length(text)


def test_edge_length_node_counts():
    piece = _poly_piece([(0, 0), (100, 0), (100, 50), (0, 50)])
    b = piece_boundary(piece)
    assert nodes_for_edge_length(b, 5.0) == (21, 11)
    assert nodes_for_edge_length(b, 7.0) == (16, 9)
    g = generate_piece(piece, edge_length="0.5cm")
    assert g.shape == (21, 11) and g.info["piece"]["edge_length"] == 5.0


def test_sampling_bound_holds():
    from clothgrid.patterns.sampling import sample_bezier, sample_ellipse_arc

    rng = np.random.default_rng(3)
    tol = 1e-3
    for _ in range(3):
        ctrl = rng.normal(size=(4, 2)) * 50
        w = rng.random(4) + 0.3
        ell = EllipseArc(rng.normal(size=2), rng.normal(size=2) * 30, rng.normal(size=2) * 10,
                         0.3, 4.0)
        cases = [(Bezier(ctrl), sample_bezier(Bezier(ctrl), tol),
                  Bezier(ctrl).points(np.linspace(0, 1, 2001))),
                 (Bezier(ctrl, w), sample_bezier(Bezier(ctrl, w), tol),
                  Bezier(ctrl, w).points(np.linspace(0, 1, 2001))),
                 (ell, sample_ellipse_arc(ell, tol), ell.points(np.linspace(0.3, 4.0, 2001)))]
        for prim, pts, dense in cases:
            poly = np.vstack([pts, prim.end])
            assert np.array_equal(pts[0], prim.start)
            # every sample is on the curve, every curve point within tol of the polyline
            assert dist_polyline_exact(pts, dense).max() < 1e-4      # the reference's own chord error
            assert dist_polyline_exact(dense, poly).max() <= tol * (1 + 1e-6)
    outline, starts = sample_loop([Bezier(np.array([[0.0, 0.0], [1.0, 0.0]])), ell], tol)
    assert starts.tolist() == [0, 1]


def test_curves_sampled_side_by_side_are_each_curve_sampled_alone(rng):
    """sample_beziers (a loop's curves of one degree subdivided together) gives every curve's
    sample_bezier points bit for bit: lines, quadratics, cubics, rational ones, tiny and large,
    flat and looping, in one mixed list; and it refuses a bad weight as sample_bezier does."""
    from clothgrid.patterns.sampling import sample_bezier, sample_beziers

    curves = []
    for _ in range(60):
        k = int(rng.integers(2, 6))
        scale = 10.0 ** rng.uniform(-3, 3)
        ctrl = rng.normal(size=(k, 2)) * scale
        w = rng.random(k) + 0.2 if rng.random() < 0.4 else None
        curves.append(Bezier(ctrl, w))
    for tol in (1e-4, 1e-2, 1.0):
        got = sample_beziers(curves, tol)
        assert len(got) == len(curves)
        for c, pts in zip(curves, got):
            assert np.array_equal(pts, sample_bezier(c, tol))
    with pytest.raises(InputError, match="non-positive weight"):
        sample_beziers([curves[0], Bezier(np.zeros((3, 2)) + 1.0, np.array([1.0, -1.0, 1.0]))], 1e-3)


# --------------------------------------------------------------------------- command line


def test_cli_pieces_lists_candidates(capsys, svg_file):
    code, out, err = run(capsys, "pieces", svg_file, "--candidates")
    assert code == 0, err
    assert "front:" in out and "disc:" in out and "corner candidates" in out
    assert "turn +90.0" in out
    code, out, _ = run(capsys, "pieces", svg_file, "--json")
    data = json.loads(out)
    assert [p["name"] for p in data["pieces"]] == ["front", "disc"]


def test_cli_generate_every_piece(capsys, svg_file, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    code, stdout, err = run(capsys, "generate", svg_file, "-o", out / "g.obj", "-o", out / "g.npz",
                            "--nodes", "17", "-q")
    assert code == 0, err
    assert files(out) == ["g_disc.npz", "g_disc.obj", "g_front.npz", "g_front.obj"]
    assert "piece front:" in stdout and "piece disc:" in stdout
    with np.load(out / "g_front.npz") as z:
        info = json.loads(str(z["info"]))
    assert info["piece"]["name"] == "front" and info["piece"]["units"] == "mm"


def test_cli_generate_one_piece_and_placeholder(capsys, svg_file, tmp_path):
    code, _, err = run(capsys, "generate", svg_file, "-o", tmp_path / "one.obj", "--piece", "disc",
                       "--edge-length", "5mm", "-q")
    assert code == 0, err
    assert (tmp_path / "one.obj").exists()
    sub = tmp_path / "m"
    sub.mkdir()
    code, _, err = run(capsys, "generate", svg_file, "-o", sub / "{piece}.npz", "--nodes", "9", "-q")
    assert code == 0, err
    assert files(sub) == ["disc.npz", "front.npz"]


def test_cli_generate_given_corners(capsys, tmp_path):
    path = tmp_path / "plain.dxf"
    _plain_dxf(path, units=4)
    code, out, err = run(capsys, "generate", path, "--piece", "piece1", "--corners", "0,1,2,3",
                         "-o", tmp_path / "a.npz", "--nodes", "9")
    assert code == 0, err
    assert "corners given by outline index" in out
    code, _, err = run(capsys, "generate", path, "--corners", "0,1,2,3", "-o", tmp_path / "b.npz")
    assert code == 2 and "--piece" in err
    assert not (tmp_path / "b_piece1.npz").exists()


def test_cli_boundary_json_edge_length(capsys, tmp_path):
    t = np.linspace(0, 1, 5)
    src = tmp_path / "sq.json"
    src.write_text(json.dumps({"bottom": [[x, 0] for x in t], "right": [[1, y] for y in t],
                               "top": [[x, 1] for x in t], "left": [[0, y] for y in t]}))
    code, _, err = run(capsys, "generate", src, "-o", tmp_path / "g.npz", "--edge-length", "0.1", "-q")
    assert code == 0, err
    with np.load(tmp_path / "g.npz") as z:
        assert z["points"].shape[:2] == (11, 11)
    code, _, err = run(capsys, "generate", src, "-o", tmp_path / "h.npz", "--edge-length", "5mm")
    assert code == 2 and "no units" in err
    code, _, err = run(capsys, "generate", src, "-o", tmp_path / "h.npz", "--piece", "x")
    assert code == 2 and "pattern files" in err
    assert not (tmp_path / "h.npz").exists()


def _bad_files() -> dict[str, tuple[str, str | bytes, tuple[str, ...]]]:
    good_dxf = DATA / "square.dxf"
    return {
        "svg-truncated": ("p.svg", SVG[: len(SVG) // 2], ("well-formed", "truncated")),
        "svg-no-closed-path": ("p.svg", '<svg xmlns="http://www.w3.org/2000/svg" width="10mm" '
                               'height="10mm"><path d="M0 0 L5 5 L9 1"/></svg>',
                               ("no closed path",)),
        "svg-two-points": ("p.svg", '<svg xmlns="http://www.w3.org/2000/svg" width="10mm" '
                           'height="10mm" viewBox="0 0 10 10"><polygon points="0,0 9,0"/></svg>',
                           ("only 2", "at least 3")),
        "svg-no-area": ("p.svg", '<svg xmlns="http://www.w3.org/2000/svg" width="10mm" '
                        'height="10mm" viewBox="0 0 10 10"><polygon points="0,0 9,0 4,0"/></svg>',
                        ("no area",)),
        "svg-unknown-units": ("p.svg", '<svg xmlns="http://www.w3.org/2000/svg" width="10em" '
                              'height="10em"><rect width="5" height="5"/></svg>',
                              ("unknown unit", "em")),
        "svg-bad-path": ("p.svg", '<svg xmlns="http://www.w3.org/2000/svg" width="10mm" '
                         'height="10mm"><path d="M0 0 L5 x5 Z"/></svg>', ("path data",)),
        "dxf-truncated": ("p.dxf", good_dxf.read_text()[:150], ("dxf", "truncated")),
        "dxf-no-units": ("p.dxf", good_dxf.read_text().replace("$INSUNITS\n70\n4\n",
                                                                 "$INSUNITS\n70\n0\n"),
                         ("$insunits is 0", "--units")),
        "dxf-not-a-dxf": ("p.dxf", "hello\n", ("dxf",)),
        # a hand-written SPLINE without the R13+ subclass markers (as in a real fixture of an
        # open-source pattern tool): not a cut-off file, and the message says what it is
        "dxf-spline-without-subclass": ("p.dxf", "\n".join(
            ["0", "SECTION", "2", "HEADER", "9", "$INSUNITS", "70", "4", "0", "ENDSEC",
             "0", "SECTION", "2", "ENTITIES", "0", "SPLINE", "8", "1", "70", "8", "71", "3", "72", "8", "73", "4"]
            + [x for k in (0, 0, 0, 0, 1, 1, 1, 1) for x in ("40", str(k))]
            + [x for px, py in ((0, 0), (10, 20), (20, 20), (30, 0)) for x in ("10", str(px), "20", str(py), "30", "0")]
            + ["0", "ENDSEC", "0", "EOF", ""]), ("subclass markers",)),
        "garmentcode-open-loop": ("p.json", json.dumps(
            {"pattern": {"panels": {"a": {"vertices": [[0, 0], [1, 0], [1, 1], [0, 1]],
                                          "edges": [{"endpoints": [0, 1]}, {"endpoints": [1, 2]},
                                                    {"endpoints": [2, 3]}]}}}}),
            ("do not close", "loop")),
        "garmentcode-bad-curvature": ("p.json", json.dumps(
            {"pattern": {"panels": {"a": {"vertices": [[0, 0], [1, 0], [1, 1], [0, 1]],
                                          "edges": [{"endpoints": [0, 1], "curvature": {"type": "spiral"}},
                                                    {"endpoints": [1, 2]}, {"endpoints": [2, 3]},
                                                    {"endpoints": [3, 0]}]}}}}),
            ("curvature type",)),
    }


@pytest.mark.parametrize("case", sorted(_bad_files()))
def test_bad_pattern_files_exit_2(capsys, tmp_path, case):
    name, content, words = _bad_files()[case]
    src = tmp_path / name
    src.write_text(content)
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = run(capsys, "generate", src, "-o", out / "g.obj", "--plot", out / "g.png",
                       "--nodes", "9")
    assert code == 2, err
    assert "clothgrid: error:" in err
    low = err.lower()
    assert any(w.lower() in low for w in words), err
    assert files(out) == []
    code, _, err = run(capsys, "pieces", src)
    assert code == 2 and "clothgrid: error:" in err
    if case == "dxf-spline-without-subclass":
        assert "truncated" not in err, err


def test_unknown_piece_and_duplicate_outputs(capsys, svg_file, tmp_path):
    code, _, err = run(capsys, "generate", svg_file, "-o", tmp_path / "g.obj", "--piece", "sleeve")
    assert code == 2 and "sleeve" in err and "front" in err
    assert files(tmp_path) == ["pattern.svg"]


def test_failed_write_leaves_nothing(capsys, svg_file, tmp_path, monkeypatch):
    from clothgrid import pipeline

    calls = {"n": 0}
    real = pipeline.write_result

    def flaky(result, *args, **kw):
        calls["n"] += 1
        if calls["n"] == 2:
            raise InputError("cannot write: disk full (simulated)")
        return real(result, *args, **kw)

    monkeypatch.setattr(pipeline, "write_result", flaky)
    code, _, err = run(capsys, "generate", svg_file, "-o", tmp_path / "g.obj", "--nodes", "9", "-q")
    assert code == 2 and "disk full" in err
    assert files(tmp_path) == ["pattern.svg"]


def test_data_files_read():
    pieces = read_pieces(DATA / "square.dxf")
    assert len(pieces) == 1 and pieces[0].extent == pytest.approx((100.0, 60.0))
    grid = generate(piece_boundary(pieces[0]), NODES)
    assert grid.shape == NODES


# --------------------------------------------------------------------------- triangles and bad pieces

SHARED = Path(__file__).parents[2] / "shared" / "patterns"
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason=f"no third-party pattern files in {SHARED}")


def test_piece_from_polygon_takes_a_triangle_and_refuses_less():
    tri = piece_from_polygon("godet", np.array([[0.0, 0.0], [0.0, 30.0], [10.0, 0.0]]))   # clockwise in
    assert len(tri.outline) == 3 and tri.area == pytest.approx(150.0)        # counter-clockwise out
    with pytest.raises(InputError, match=r"piece 'two': only 2 distinct points; a piece needs at least 3"):
        piece_from_polygon("two", np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 0.0], [0.0, 0.0]]))
    with pytest.raises(InputError, match="encloses no area"):
        piece_from_polygon("flat", np.array([[0.0, 0.0], [10.0, 0.0], [4.0, 0.0]]))


def test_a_triangle_svg_path_reads_as_a_piece(tmp_path):
    path = tmp_path / "godet.svg"
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" '
                    'viewBox="0 0 100 100"><path id="godet" d="M 10 90 L 90 90 L 50 10 Z"/></svg>')
    (piece,) = read_pieces(path)
    assert piece.name == "godet" and len(piece.outline) == 3 and piece.area == pytest.approx(3200.0)
    assert read_pieces(path).failed == []
    # through reading: whatever the corner choice makes of it, a job or a named per-piece failure
    from clothgrid.pipeline import GridOptions, read_jobs
    try:
        jobs = read_jobs(path, [tmp_path / "{piece}.npz"], options=GridOptions(edge_length="10mm"))
    except InputError as exc:
        assert "piece 'godet'" in str(exc)
    else:
        assert [j.name for j in jobs] == ["godet"]


@needs_shared
def test_godet_skirt_reads_its_triangles_and_grids_every_piece_it_can(capsys, tmp_path):
    """gcn_rand_IMB4RPKGCM: 4 triangular godets (3 points each) once failed the whole file."""
    src = SHARED / "gcn_rand_IMB4RPKGCM_specification.json"
    pieces = read_pieces(src)
    assert pieces.failed == [] and len(pieces) == 8
    godets = sorted(p.name for p in pieces if len(p.outline) == 3)
    assert godets == ["ins_skirt_back_0", "ins_skirt_back_1", "ins_skirt_front_0", "ins_skirt_front_1"]
    code, out, err = run(capsys, "pieces", src)
    assert code == 0 and out.splitlines()[0].endswith("8 pieces (coordinates in mm)")
    code, _, err = run(capsys, "generate", src, "-o", tmp_path / "{piece}.npz", "--edge-length", "20mm", "-q")
    written = {p.stem for p in tmp_path.glob("*.npz")}
    named = {n for n in godets if f"piece '{n}': " in err}
    assert written >= {p.name for p in pieces if len(p.outline) > 3}       # every other piece
    assert written | named == {p.name for p in pieces} and not written & named
    assert code == (EXIT_PARTIAL if named else 0), err     # a godet that fails later fails alone


@needs_shared
def test_real_file_pieces_drawn_as_open_paths_are_joined(capsys, tmp_path):
    """fs_florent_layout.svg (FreeSewing) draws two pieces as open paths: the cap side (cut on the
    fold) as its curve '14' and the fold line '15', the brim as its two curves '53', '54' and two
    short lines '55', '56' drawn as closed 2-point paths. Each group's paths of one class that meet
    end to end are one piece, named after the group; the seam-allowance paths ('16', '17', '18',
    class "fabric sa") do not close and stay open. Every piece is written (exit 0)."""
    src = SHARED / "fs_florent_layout.svg"
    pieces = read_pieces(src)
    assert pieces.failed == [] and [p.name for p in pieces] == ["top", "brimBottom", "brimTop", "side", "brimPlastic"]
    by = {p.name: p for p in pieces}
    assert by["side"].meta["joined"] == ["14", "15"]
    assert sorted(by["brimPlastic"].meta["joined"]) == ["53", "54", "55", "56"]
    assert any("joined from 4 open paths" in n for n in by["brimPlastic"].notes)
    # the brim is a ring sector between its two curves: 194 x 135 mm (FreeSewing's first core drew
    # 90 px an inch: at 96 it was 181.5 x 126.2)
    assert by["brimPlastic"].extent == pytest.approx((181.5 * 96 / 90, 126.2 * 96 / 90), abs=0.1)
    code, _, err = run(capsys, "generate", src, "-o", tmp_path / "{piece}.npz", "--edge-length", "20mm", "-q")
    assert code == 0, err
    assert sorted(p.stem for p in tmp_path.glob("*.npz")) == sorted(by)


def _svg(tmp_path, body: str) -> Path:
    path = tmp_path / "t.svg"
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="200mm" '
                    f'viewBox="0 0 300 200">{body}</svg>')
    return path


def test_open_paths_joined_only_where_two_ends_meet(tmp_path):
    # two halves of a square in one group: one piece, named after the group
    path = _svg(tmp_path, '<g id="panel"><path id="p" d="M 0,0 L 100,0 L 100,100"/>'
                          '<path id="q" d="M 0,0 L 0,100 L 100,100"/></g>')
    got = read_pieces(path)
    assert [p.name for p in got] == ["panel"] and got[0].area == pytest.approx(10000)
    # a third path from a shared end (a fork) whose other end meets nothing (a mark drawn from a
    # corner): it is left out and the outline is the two halves'
    path = _svg(tmp_path, '<g id="panel"><path id="p" d="M 0,0 L 100,0 L 100,100"/>'
                          '<path id="q" d="M 0,0 L 0,100 L 100,100"/><path id="r" d="M 0,0 L -9,-9"/></g>'
                          '<path id="s" d="M 150,0 L 250,0 L 250,100 Z"/>')
    got = {p.name: p for p in read_pieces(path)}
    assert sorted(got) == ["panel", "s"] and got["panel"].area == pytest.approx(10000)
    assert sorted(got["panel"].meta["joined"]) == ["p", "q"] and "inner_lines" not in got["panel"].meta
    # paths of different classes (a sew line and a seam allowance) are not joined
    path = _svg(tmp_path, '<g id="panel"><path class="fabric" d="M 0,0 L 100,0 L 100,100"/>'
                          '<path class="fabric sa" d="M 0,0 L 0,100 L 100,100"/></g>'
                          '<path id="s" d="M 150,0 L 250,0 L 250,100 Z"/>')
    assert [p.name for p in read_pieces(path)] == ["s"]


def test_svg_piece_named_by_its_name_attribute(tmp_path):
    """A pattern program's ``name="sleeve-front-left"`` on a piece's path (not SVG, but written)
    names the piece where it has no ``inkscape:label`` or ``id``; an ``id`` wins over it."""
    path = _svg(tmp_path, '<path name="sleeve-front-left" d="M 0,0 L 100,0 L 100,80 Z"/>'
                          '<path id="cuff" name="sleeve-cuff" d="M 150,0 L 250,0 L 250,30 Z"/>'
                          '<path d="M 0,100 L 100,100 L 100,180 Z"/>')
    assert [p.name for p in read_pieces(path)] == ["sleeve-front-left", "cuff", "piece3"]


def test_unnamed_svg_pieces_are_named_after_the_text_drawn_on_them(tmp_path):
    """Pieces without an id, label or group name (Illustrator's hand-drawn blocks) take the text
    drawn on them that names a garment piece (a part word beats a garment word, then the shorter):
    "SLEEVE" over "WOVEN BODICE BLOCK", a rotated label split into tspans read whole; a piece
    with an id keeps it; a text naming nothing (a size, a brand) names nothing; an arrowhead drawn
    closed on a piece takes no label; two pieces with one label get unique names."""
    body = ('<path d="M 0,0 L 100,0 L 100,150 L 0,150 Z"/>'
            '<text x="20" y="40">SLEEVE</text><text x="20" y="60">WOVEN BODICE BLOCK</text>'
            '<path d="M 48,70 L 52,70 L 50,64 Z"/>'
            '<path d="M 120,0 L 220,0 L 220,150 L 120,150 Z"/>'
            '<text transform="matrix(0 -1 1 0 150 120)"><tspan x="0" y="0">B</tspan>'
            '<tspan x="12" y="0">ACK BODICE B</tspan><tspan x="150" y="0">LOCK</tspan></text>'
            '<text x="130" y="20">MRUK10F - MREU36F</text>'
            '<path id="yoke" d="M 240,0 L 290,0 L 290,40 L 240,40 Z"/><text x="250" y="20">BACK YOKE</text>'
            '<path d="M 0,160 L 60,160 L 60,195 L 0,195 Z"/><text x="5" y="180">UK 10</text>'
            '<path d="M 100,160 L 160,160 L 160,195 L 100,195 Z"/><text x="105" y="190">Cuff</text>'
            '<path d="M 200,160 L 260,160 L 260,195 L 200,195 Z"/><text x="205" y="190">Cuff</text>')
    got = read_pieces(_svg(tmp_path, body))
    assert [p.name for p in got] == ["SLEEVE", "BACK BODICE BLOCK", "yoke", "piece5", "Cuff", "Cuff-2"]
    assert got[0].meta["label"] == "SLEEVE" and any("named after the text 'SLEEVE'" in n for n in got[0].notes)
    assert "label" not in got[2].meta
    assert [(k.kind, k.of) for k in got.skipped] == [("inside", "SLEEVE")]


def test_nested_svg_viewports_place_their_content(tmp_path):
    """A nested ``<svg>`` is a viewport (SVG 1.1): its content is moved by ``x``, ``y`` and its
    ``viewBox`` fitted into ``width`` x ``height`` (numbers, absolute lengths, percentages of the
    parent's viewport; ``preserveAspectRatio`` meet by default, none, slice); without a viewBox it
    only shifts. Checked against the same rectangles drawn in the outer user units."""
    body = ('<svg x="10" y="10" width="50" height="50" viewBox="0 0 100 100">'
            '<rect id="fit" x="0" y="0" width="100" height="100"/></svg>'
            '<svg x="100" y="0" width="50%" height="25%" viewBox="0 0 10 10" preserveAspectRatio="none">'
            '<rect id="stretch" x="0" y="0" width="10" height="10"/></svg>'
            '<svg x="0" y="100" width="60" height="30" viewBox="0 0 10 10">'
            '<rect id="meet" x="0" y="0" width="10" height="10"/></svg>'
            '<svg x="100" y="100"><rect id="shift" x="5" y="5" width="20" height="20"/>'
            '<svg x="40" y="0" width="10mm" height="10mm" viewBox="0 0 1 1"><rect id="mm" width="1" height="1"/></svg></svg>')
    got = {p.name: p for p in read_pieces(_svg(tmp_path, body))}

    def box(p):                     # x range and y range back in the outer user units (y down, 200 high)
        lo, hi = p.outline.min(axis=0), p.outline.max(axis=0)
        return (lo[0], hi[0], 200 - hi[1], 200 - lo[1])

    assert box(got["fit"]) == pytest.approx((10, 60, 10, 60))
    assert box(got["stretch"]) == pytest.approx((100, 250, 0, 50))        # 50 % of 300, 25 % of 200
    assert box(got["meet"]) == pytest.approx((15, 45, 100, 130))          # 30 x 30, centred in 60 x 30
    assert box(got["shift"]) == pytest.approx((105, 125, 105, 125))
    mm = 10 * 96 / 25.4                                                   # 10 mm in user units
    assert box(got["mm"]) == pytest.approx((140, 140 + mm, 100, 100 + mm))
    with pytest.raises(InputError, match="viewBox"):
        read_pieces(_svg(tmp_path, '<svg width="10" height="10" viewBox="0 0 0 1"><rect width="1" height="1"/></svg>'))
    with pytest.raises(InputError, match="positive width and height"):
        read_pieces(_svg(tmp_path, '<svg width="0" height="10" viewBox="0 0 1 1"><rect width="1" height="1"/></svg>'))
    with pytest.raises(InputError, match="nested <svg>"):
        read_pieces(_svg(tmp_path, '<svg width="1em" height="10"><rect width="1" height="1"/></svg>'))


def test_made_up_ids_yield_to_group_names_and_labels(tmp_path):
    """An id a drawing program made up (Inkscape's ``path1234``) names a piece only where nothing
    better does: its layer's name first, else the garment words drawn on it; a chosen id stays."""
    ink = 'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"'
    path = tmp_path / "ink.svg"
    path.write_text(
        f'<svg xmlns="http://www.w3.org/2000/svg" {ink} width="300mm" height="200mm" viewBox="0 0 300 200">'
        '<g inkscape:label="Front" id="layer1"><path id="path1234" d="M 0,0 L 80,0 L 80,80 Z"/></g>'
        '<g id="g77"><path id="path99-3" d="M 100,0 L 180,0 L 180,80 L 100,80 Z"/>'
        '<text x="120" y="40">Sleeve</text></g>'
        '<path id="path5" d="M 200,0 L 280,0 L 280,80 L 200,80 Z"/>'
        '<path id="cuff" d="M 0,100 L 80,100 L 80,180 L 0,180 Z"/><text x="20" y="140">Collar</text>'
        # Inkscape's default layer label names no piece: the text drawn on it does
        '<g inkscape:label="Layer 1" id="layer2"><path id="path77" d="M 100,100 L 180,100 L 180,180 L 100,180 Z"/>'
        '<text x="120" y="140">Back</text></g></svg>')
    got = read_pieces(path)
    assert [p.name for p in got] == ["Front", "Sleeve", "path5", "cuff", "Back"]
    assert [p.aliases for p in got] == [("path1234",), ("path99-3",), (), (), ("path77",)]


def test_freesewing_ids_yield_to_part_names_and_stay_aliases(tmp_path, capsys):
    """FreeSewing 2 ids its paths by running numbers in a group named after the part; FreeSewing 3 and 4
    by ``fs-N`` in ``fs-stack-DESIGN.PART-part-DESIGN.PART`` groups. The pieces take the part's name;
    of a part's sew line and cut line, the one gridded keeps it (whichever the file draws first). The
    id names the piece still (an alias: ``--piece 12``, a stitches file), and a mark the file names as
    one keeps its id."""
    from clothgrid.cli import main

    sq = "M {0},{1} L {2},{1} L {2},{3} L {0},{3} Z"
    path = tmp_path / "fs.svg"
    path.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="400mm" height="300mm" viewBox="0 0 400 300">'
        '<g id="sleeve">'
        f'<path class="fabric sa" id="11" d="{sq.format(0, 0, 110, 210)}"/>'        # the cut line first
        f'<path class="fabric" id="12" d="{sq.format(5, 5, 105, 205)}"/>'
        f'<path class="logo" id="13" d="{sq.format(40, 40, 50, 50)}"/></g>'
        '<g id="fs-container"><g id="fs-stack-tee.front"><g id="fs-stack-tee.front-part-tee.front">'
        f'<path class="fabric" id="fs-1" d="{sq.format(200, 0, 300, 200)}"/></g></g></g></svg>')
    sew = read_pieces(path)
    assert [(p.name, p.aliases, p.meta["line"]) for p in sew] == [("sleeve", ("12",), "sew"), ("front", ("fs-1",), "outline")]
    assert {s.name: s.kind for s in sew.skipped} == {"sleeve-2": "seam allowance", "13": "mark"}
    assert sew.skipped[0].of == "sleeve" and "'sleeve-2'" in sew[0].notes[-1]
    cut = read_pieces(path, line="cut")
    assert [(p.name, p.aliases, p.meta["line"]) for p in cut][0] == ("sleeve", ("11",), "cut")
    assert cut[0].area > sew[0].area
    assert (sew.resolve("12"), sew.resolve("11"), sew.resolve("fs-1"), sew.resolve("nothing")) == (
        "sleeve", "sleeve-2", "front", "nothing")
    # the old names on the command line, for a piece and for a skipped outline
    out = tmp_path / "out"
    assert main(["generate", str(path), "--piece", "12", "--piece", "fs-1", "-o", str(out / "{piece}.npz"),
                 "--nodes", "9", "-q"]) == 0, capsys.readouterr().err
    assert sorted(f.name for f in out.iterdir()) == ["front.npz", "sleeve.npz"]
    capsys.readouterr()
    assert main(["pieces", str(path), "--include", "11", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert [p["name"] for p in got["pieces"]] == ["sleeve", "front", "sleeve-2"]
    assert [p["aliases"] for p in got["pieces"]] == [["12"], ["fs-1"], ["11"]]


def test_freesewing_3_export():
    """FreeSewing 3's Aaron A-shirt (tests/data/freesewing): its two parts, named after their groups
    (``fs-stack-aaron.front-part-aaron.front`` is ``front``), their ``fs-N`` ids kept as aliases, millimetres
    from the root's size; the open seam-allowance paths along the edges not on the fold are no pieces;
    both grid fold-free at the default edge length."""
    from clothgrid.quality import quality

    src = Path(__file__).parent / "data" / "freesewing" / "aaron_v3_pattern.svg"
    got = read_pieces(src)
    assert [(p.name, p.aliases) for p in got] == [("front", ("fs-1",)), ("back", ("fs-5",))]
    assert got.failed == []
    # the A-shirt is 275.6 mm wide (half, cut on the fold) and 754.1 mm long, both parts
    for p in got:
        assert p.extent == pytest.approx((275.56, 754.11), abs=0.01)
        assert p.units == "mm"
    assert got[0].area != pytest.approx(got[1].area, rel=1e-3)       # the front's neckline is deeper
    for p in got:
        g = generate_piece(p, edge_length="10mm")
        assert quality(g).folded == 0


def test_a_layer_of_several_pieces_names_none_of_them(tmp_path):
    """A named layer holding several pieces side by side (made-up ids) does not name them: each takes
    the garment words drawn on it (or keeps the layer's name, numbered, where there are none); one
    part's sew and cut lines in one group keep its name (FreeSewing)."""
    ink = 'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"'
    path = tmp_path / "layer.svg"
    path.write_text(
        f'<svg xmlns="http://www.w3.org/2000/svg" {ink} width="400mm" height="200mm" viewBox="0 0 400 200">'
        '<g inkscape:label="Pattern" id="layer1">'
        '<path id="path11" d="M 0,0 L 80,0 L 80,120 L 0,120 Z"/><text x="20" y="60">FRONT</text>'
        '<path id="path12" d="M 100,0 L 180,0 L 180,120 L 100,120 Z"/><text x="120" y="60">BACK</text>'
        '<path id="path13" d="M 200,0 L 260,0 L 260,60 L 200,60 Z"/></g>'
        '<g id="sleeve"><path id="21" d="M 300,0 L 390,0 L 390,150 L 300,150 Z"/>'
        '<path id="22" d="M 305,5 L 385,5 L 385,145 L 305,145 Z"/><text x="320" y="60">Sleeve cap</text></g></svg>')
    got = read_pieces(path)
    # (the names the last release gave, the ids and the layer's, stay aliases)
    assert [(p.name, p.aliases) for p in got] == [("FRONT", ("path11", "Pattern")), ("BACK", ("path12", "Pattern-2")),
                                                  ("Pattern-3", ("path13",)), ("sleeve", ("22",))]
    assert {s.name: s.kind for s in got.skipped} == {"sleeve-2": "seam allowance"}


def test_tiny_outlines_are_sorted_on_a_draft_and_made_exactly_when_included(tmp_path, capsys):
    """Outlines under ``svg.TINY_REL`` of the largest's size (lettering drawn as paths) are sampled to
    ``svg.DRAFT_REL_TOL`` for the sorting; a piece keeps the reader's tolerance, and a skipped glyph
    named with ``--include`` is made again at it (its points within ``1e-7`` of its size of the curve)."""
    from clothgrid.patterns import svg

    glyphs = "".join(f'<circle id="dot{k}" cx="{20 + 5 * k}" cy="20" r="1"/>' for k in range(5))
    path = _svg(tmp_path, '<path id="front" d="M 0,0 L 280,0 C 290,60 290,120 280,180 L 0,180 Z"/>' + glyphs)
    got = read_pieces(path)
    assert [p.name for p in got] == ["front"] and got[0].tolerance == pytest.approx(1e-7 * got[0].size, rel=1e-6)
    dots = [s for s in got.skipped if s.name.startswith("dot")]
    assert len(dots) == 5 and all(s.piece is None and s.size == pytest.approx((2.0, 2.0), rel=1e-3) for s in dots)
    assert all("draft" not in s.meta for s in dots)
    made = dots[0].made()
    assert made.tolerance == pytest.approx(1e-7 * made.size, rel=1e-6)
    r = np.hypot(*(made.outline - [20.0, 180.0]).T)      # the circle at (20, 20), y flipped in a 200 high page
    assert np.abs(r - 1.0).max() <= 1e-7 * made.size
    # the same reading with every outline at the full tolerance: the same pieces and skipped kinds
    svg_tiny = svg.TINY_REL
    try:
        svg.TINY_REL = 0.0
        full = read_pieces(path)
    finally:
        svg.TINY_REL = svg_tiny
    assert [p.name for p in full] == ["front"] and np.array_equal(full[0].outline, got[0].outline)
    assert [(s.name, s.kind) for s in full.skipped] == [(s.name, s.kind) for s in got.skipped]
    assert main(["pieces", str(path), "--include", "dot0", "--piece", "dot0", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["pieces"][0]["sampling_tolerance_mm"] == pytest.approx(
        made.tolerance)


def test_without_word_drops_the_line_word_from_a_name():
    from clothgrid.patterns.svg import _without_word

    assert _without_word("A.seamline", "seamline") == "A"
    assert _without_word("Front_SEW_line", "sew") == "Front_line"
    assert _without_word("seamline", "seamline") == "seamline"        # nothing else left
    assert _without_word("--sew--", "sew") == "--sew--"
    assert _without_word("Back piece", "sew") == "Back piece"


def test_open_paths_polylines_and_lines_are_all_counted_in_the_error(tmp_path):
    path = _svg(tmp_path, '<polyline points="0,0 50,0 50,50"/><path d="M 10 10 L 20 20"/>'
                          '<line x1="60" y1="0" x2="90" y2="10"/>')
    with pytest.raises(InputError, match=r"\(3 open paths were skipped"):
        read_pieces(path)


def test_lines_and_open_polylines_meeting_end_to_end_are_an_outline(tmp_path):
    """Illustrator and hand-drawn SVGs draw edges as ``<line>`` elements: four lines of a panel
    (one of them transformed, two drawn backwards) are one piece; an open polyline and a line close
    a triangle; a lone grain line and a zero-length line are left out."""
    path = _svg(tmp_path, '<g id="panel"><line x1="0" y1="0" x2="100" y2="0"/>'
                          '<line x1="100" y1="0" x2="100" y2="80"/>'
                          '<line x1="0" y1="80" x2="100" y2="80"/>'
                          '<line transform="translate(0,80)" x1="0" y1="0" x2="0" y2="-80"/></g>'
                          '<g id="gusset"><polyline points="150,0 250,0 200,60"/>'
                          '<line x1="200" y1="60" x2="150" y2="0"/></g>'
                          '<line id="grain" x1="20" y1="20" x2="20" y2="60"/><line x1="5" y1="5" x2="5" y2="5"/>')
    got = {p.name: p for p in read_pieces(path)}
    assert sorted(got) == ["gusset", "panel"]
    assert got["panel"].extent == pytest.approx((100.0, 80.0)) and got["panel"].area == pytest.approx(8000.0)
    assert got["gusset"].area == pytest.approx(3000.0) and len(got["gusset"].outline) == 3
    assert any("joined from 4 open paths" in n for n in got["panel"].notes)
    bad = read_pieces(_svg(tmp_path, '<line x1="0" y1="0" x2="1em" y2="5"/><path d="M0,0 L90,0 L90,90 Z"/>'))
    assert len(bad) == 1 and len(bad.failed) == 1 and "expected a number" in bad.failed[0].reason


def _hand_drawn_sleeve(gap_px: float = 0.5) -> str:
    """A sleeve block as Adobe Illustrator exports a hand-drawn one (72 px an inch): its cap as two
    open curves, its sides, hem, bicep and elbow lines as separate ``<line>``s, the upper ends
    ``gap_px`` apart (the lower part closes exactly, by the elbow line), a centre line from the
    cap's top to the middle of the hem, and a grain-line arrowhead as a small closed path."""
    g = gap_px
    return ('<?xml version="1.0" encoding="utf-8"?>\n'
            '<!-- Generator: Adobe Illustrator 15.0.0, SVG Export Plug-In -->\n'
            '<svg xmlns="http://www.w3.org/2000/svg" width="1000px" height="1300px" viewBox="0 0 1000 1300"><g>'
            '<path fill="none" stroke="#000" d="M500,100 c-150,0 -200,200 -300,250"/>'
            '<path fill="none" stroke="#000" d="M500,100 c150,0 200,200 300,250"/>'
            f'<line fill="none" stroke="#000" x1="{200 + g}" y1="{350 - g / 2}" x2="280" y2="800"/>'
            f'<line fill="none" stroke="#000" x1="{800 - g}" y1="{350 + g / 2}" x2="720" y2="800"/>'
            '<line fill="none" stroke="#000" x1="280" y1="800" x2="350" y2="1200"/>'
            '<line fill="none" stroke="#000" x1="720" y1="800" x2="650" y2="1200"/>'
            '<line fill="none" stroke="#000" x1="350" y1="1200" x2="650" y2="1200"/>'
            f'<line fill="none" stroke="#000" x1="{200 + g}" y1="350" x2="{800 - g / 2}" y2="350"/>'
            '<line fill="none" stroke="#000" x1="280" y1="800" x2="720" y2="800"/>'
            f'<line fill="none" stroke="#000" x1="500" y1="{100 + g}" x2="500" y2="1200"/>'
            '<path d="M490,600 L510,600 L500,570 Z"/></g></svg>')


def test_svg_block_drawn_by_hand_as_lines_with_gaps(tmp_path):
    """A block drawn by hand in Illustrator (BCSizing's sleeve and bodice blocks): separate lines and
    curves whose ends miss each other by up to 0.2 mm are one piece, across construction lines (the
    bicep and elbow lines are inner lines; the elbow line closes the lower part exactly, which is
    part of the sleeve, not a piece), the centre line ending on the hem is left out, and the
    arrowhead is a mark drawn on the piece. Ends 2 mm apart are not joined."""
    path = tmp_path / "sleeve.svg"
    path.write_text(_hand_drawn_sleeve(0.5))
    got = read_pieces(path)
    assert len(got) == 1
    (piece,) = got
    mm = 25.4 / 72
    assert piece.extent == pytest.approx((600 * mm, 1100 * mm), abs=0.3)
    assert len(piece.meta["joined"]) == 7 and len(piece.meta["inner_lines"]) == 2
    assert piece.meta["gap_mm"] == pytest.approx(np.hypot(0.5, 0.25) * mm, rel=0.05)
    gap = f"across gaps of up to {piece.meta['gap_mm']:.3g} mm"
    assert any(gap in n and "around 2 inner lines" in n for n in piece.notes)
    assert [(k.kind, k.of) for k in got.skipped] == [("inside", piece.name)]
    # the sleeve grids without a fold
    from clothgrid.quality import quality

    assert quality(generate_piece(piece, (17, 31))).folded == 0
    path.write_text(_hand_drawn_sleeve(6.0))    # 2.1 mm: not a gap in the line, so not joined
    pieces = read_pieces(path)
    assert all(p.area < 0.5 * piece.area for p in pieces)


def test_an_outline_drawn_by_hand_that_stops_short_of_its_start_is_closed(tmp_path):
    """One open path (SVG) or LWPOLYLINE (plain DXF) whose end stops 0.4 mm short of its start is an
    outline, with a note; so is an arc drawn almost round. A line drawn back beside itself (a V
    0.3 mm open) and a grain line are none, and a sliver that only a gap would close is no failed
    piece either."""
    body = ('<path id="hand" d="M 10,10 L 110,10 L 110,90 C 80,100 40,100 10,90 L 10,10.4"/>'
            '<path id="grain" d="M 150,20 L 150,120"/><path id="vee" d="M 200,10 L 250,100 L 200.3,10"/>'
            '<path id="a" d="M 120,150 L 170,190"/><path id="b" d="M 170,190 L 120.3,150"/>'
            '<path id="arc" d="M 230,150 A 30 30 0 1 1 230.4,150"/>')
    got = read_pieces(_svg(tmp_path, body))
    assert sorted(p.name for p in got) == ["arc", "hand"] and not got.failed
    hand = {p.name: p for p in got}["hand"]
    assert hand.area == pytest.approx(100 * 80 + 510, rel=1e-3)      # the cubic's cap: 90 (3/2 + 8/3 + 3/2)
    assert any("an open path whose ends are 0.4 mm apart, taken as closed" in n for n in hand.notes)
    assert {p.name: p for p in got}["arc"].area == pytest.approx(math.pi * 30 ** 2, rel=1e-3)
    doc = ezdxf.new("R2010")
    doc.units = 4
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (200, 0), (200, 150), (0, 150), (0, 0.3)])       # not flagged closed
    msp.add_line((50, 50), (50, 120))
    doc.saveas(tmp_path / "hand.dxf")
    (piece,) = read_pieces(tmp_path / "hand.dxf")
    assert piece.area == pytest.approx(200 * 150, rel=1e-3)
    assert any("whose ends are 0.3 mm apart, taken as closed" in n for n in piece.notes)


def test_dashed_outline_across_a_piece_is_a_construction_line(tmp_path):
    """A dashed closed outline reaching over a larger solid piece's outline (a bust radius drawn
    around the bust point) is skipped; a dashed one inside a piece is a mark drawn on it; one that
    touches no piece stays a piece (programs that draw every line dashed)."""
    from clothgrid.patterns.annotations import dashed

    assert not dashed(None) and not dashed("") and not dashed(";none;#000;")
    assert not dashed(";none;#000;none") and not dashed(";none;#000;0,0") and not dashed("c;none;#000; 0 ")
    assert dashed(";none;#000;0.567,0.567") and dashed("a;none;#000;5 2") and dashed(";none;;.5")
    body = ('<path id="front" fill="none" stroke="#000" d="M 0,0 L 100,0 L 100,150 L 0,150 Z"/>'
            '<ellipse id="radius" fill="none" stroke="#000" stroke-dasharray="2,1" cx="95" cy="75" rx="30" ry="30"/>'
            '<rect id="pocket" fill="none" stroke="#000" style="stroke-dasharray: 3 1" x="20" y="20" width="30" height="30"/>'
            '<rect id="apart" fill="none" stroke="#000" stroke-dasharray="2,1" x="200" y="0" width="80" height="120"/>')
    got = read_pieces(_svg(tmp_path, body))
    assert sorted(p.name for p in got) == ["apart", "front"]
    kinds = {k.name: (k.kind, k.of) for k in got.skipped}
    assert kinds == {"radius": ("dashed line", "front"), "pocket": ("inside", "front")}
    # drawn solid, the circle across the outline is a piece of its own
    got = read_pieces(_svg(tmp_path, body.replace('stroke-dasharray="2,1" cx', 'cx')))
    assert "radius" in [p.name for p in got]


@pytest.mark.parametrize("dim", [2, 3])
def test_arc_sampler_is_resample_polyline_and_spaces_by_arc_length(rng, dim):
    """The corner choice's coarse grids sample each side from one ArcSampler, the parametrisation
    resample_polyline samples once: on fresh polylines (repeated points among them) its samples are
    resample_polyline's exactly, equally spaced in arc length to rounding, the ends exact, and the
    transfinite grid of four sides is the same from samplers as from point arrays; a side of no
    length is the same BoundaryError."""
    from clothgrid.boundary import ArcSampler, resample_polyline
    from clothgrid.errors import BoundaryError
    from clothgrid.patterns.corners import _sides_grid

    for _ in range(10):
        sides = []
        for _k in range(4):
            pts = np.cumsum(rng.normal(size=(int(rng.integers(3, 40)), dim)), axis=0) * 10.0
            k = int(rng.integers(1, len(pts)))
            pts[k] = pts[k - 1]                                  # a zero-length segment
            sides.append(pts)
        for sd in sides:
            arc = ArcSampler(sd)
            for n in (2, 3, int(rng.integers(4, 70))):
                got = arc.sample(n)
                assert np.array_equal(got, resample_polyline(sd, n))
                assert np.array_equal(got[0, :dim], sd[0]) and np.array_equal(got[-1, :dim], sd[-1])
                # each sample on the polyline at its arc position: the distances along it are equal
                t = np.linspace(0.0, arc.s[-1], n)
                ref = np.stack([np.interp(t, arc.s[np.r_[True, np.diff(arc.s) > 0]],
                                          np.pad(sd, ((0, 0), (0, 3 - dim)))[np.r_[True, np.diff(arc.s) > 0], c])
                                for c in range(3)], -1)
                assert np.allclose(got, ref, rtol=0, atol=1e-9 * arc.s[-1])
        nu, nv = (int(x) for x in rng.integers(3, 40, size=2))
        assert np.array_equal(_sides_grid([ArcSampler(sd) for sd in sides], nu, nv), _sides_grid(sides, nu, nv))
    with pytest.raises(BoundaryError, match="zero length"):
        ArcSampler(np.zeros((3, dim)))
    with pytest.raises(BoundaryError, match="at least 2 points"):
        ArcSampler(np.zeros((1, 3)))


def test_snap_to_outline_matches_a_kd_tree(rng):
    """Turn points snap to the nearest outline point within the tolerance by a grid of cells: the
    same answers as SciPy's k-d tree on fresh outlines (offset and scaled), with points on, near,
    just beyond and far from the outline; non-finite points never snap."""
    from scipy.spatial import cKDTree

    from clothgrid.patterns.piece import snap_to_outline

    for _ in range(60):
        n, m = int(rng.integers(1, 2000)), int(rng.integers(1, 40))
        scale = 10 ** rng.uniform(-2, 4)
        t = np.sort(rng.uniform(0, 2 * np.pi, n))
        outline = rng.uniform(-1e5, 1e5, 2) + scale * np.c_[np.cos(t), np.sin(t) * rng.uniform(0.2, 1)]
        tol = 1e-6 * 2 * scale
        spread = rng.choice([0.0, 0.3, 0.7, 2.0, 100.0], (m, 1))
        points = outline[rng.integers(0, n, m)] + rng.normal(size=(m, 2)) * tol * spread
        points[rng.random(m) < 0.1] = np.nan
        finite = np.isfinite(points).all(axis=1)
        dist, near = np.full(m, np.inf), np.full(m, -1)
        dist[finite], near[finite] = cKDTree(outline).query(points[finite])
        nearest, ok = snap_to_outline(outline, points, tol)
        assert np.array_equal(ok, dist <= tol)
        assert np.array_equal(nearest[ok], near[ok]) and (nearest[~ok] == -1).all()



@pytest.mark.parametrize("side_mm, warned", [(40.0, True), (300.0, False), (20_000.0, True)])
def test_a_piece_size_that_suggests_wrong_units_is_warned_about(capsys, tmp_path, side_mm, warned):
    """A file read in its own units whose largest piece is under 100 mm or over 10 m (a CLO export
    that says METRIC with centimetres, millimetres read as inches) gets one warning line naming
    --units, on 'pieces' and 'generate' alike, and is gridded as it says; --units silences it."""
    src = tmp_path / "p.svg"
    src.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" width="{2 * side_mm}mm" height="{2 * side_mm}mm" '
                   f'viewBox="0 0 {2 * side_mm} {2 * side_mm}"><polygon points="0,0 {side_mm},0 {side_mm},'
                   f'{0.6 * side_mm} 0,{0.6 * side_mm}"/></svg>')
    code, _, err = run(capsys, "pieces", src)
    assert code == 0 and (err.count("warning:") == 1) == warned, err
    if warned:
        assert "--units" in err and "mm across" in err
        # the unit that makes the piece the most typical size is suggested, with the size it gives
        # (no unit among mm, cm, in, m makes a piece read in mm smaller: none is suggested then)
        assert ("--units cm would make it 400 mm" in err) == (side_mm == 40.0), err
        assert ("would make it" in err) == (side_mm == 40.0), err
    code, _, err = run(capsys, "generate", src, "-o", tmp_path / "{piece}.npz", "--nodes", "5", "-q")
    assert code == 0 and (err.count("warning:") == 1) == warned, err
    code, _, err = run(capsys, "pieces", src, "--units", "mm")
    assert code == 0 and "warning:" not in err


def test_a_tiny_outline_that_crosses_itself_is_skipped_a_large_one_fails(capsys, tmp_path):
    """An outline that cannot be made is a failed piece (exit 4, the others written) unless it is
    tiny against the largest piece, as lettering's glyphs drawn as filled paths are: then it is
    skipped as too small, with the reason it could not be made."""
    def svg(eight_mm: float) -> str:
        e = eight_mm
        return ('<svg xmlns="http://www.w3.org/2000/svg" width="400mm" height="400mm" viewBox="0 0 400 400">'
                '<rect id="body" x="10" y="10" width="300" height="200"/>'
                f'<path id="eight" d="M 320 250 L {320 + e} {250 + e} L {320 + e} 250 L 320 {250 + e} Z"/></svg>')

    for e, skipped in ((3.0, True), (60.0, False)):
        src = tmp_path / f"p{int(e)}.svg"
        src.write_text(svg(e))
        code, out, err = run(capsys, "pieces", src, "--json")
        listing = json.loads(out)
        assert [p["name"] for p in listing["pieces"]] == ["body"]
        if skipped:
            assert code == 0 and not listing["failed"]
            (s,) = [s for s in listing["skipped"] if s["name"] == "eight"]
            assert s["kind"] == "small" and "not an outline that can be gridded" in s["reason"]
        else:
            assert code == 4 and [f["name"] for f in listing["failed"]] == ["eight"]


def test_an_outline_that_pinches_is_cut_in_two(tmp_path):
    """A bodice block whose waist dart and shoulder dart are drawn to one apex point (OpenPattern's
    Gilewska block: the two tips 7e-5 mm apart) is two lobes meeting at a point; no grid of one block
    passes through it (56 folded cells). The reader cuts it there into two pieces, each gridded
    fold-free; an outline whose near-touch would leave a sliver (under 1 % of the area) is left whole."""
    rng = np.random.default_rng()
    apex = np.array([60.0, 120.0])
    pts = np.array([[0, 0], [50, 0], apex, [70, 0], [130, 0], [130, 200], [80, 210], apex + [3e-5, -2e-5],
                    [50, 215], [0, 200]], dtype=np.float64)
    angle = rng.uniform(0, 2 * np.pi)
    rot = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
    pts = pts @ rot + rng.uniform(-100, 100, 2)
    d = " ".join(f"{'M' if k == 0 else 'L'} {x:.9f} {y:.9f}" for k, (x, y) in enumerate(pts)) + " Z"
    svg = tmp_path / "block.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="800mm" height="800mm" viewBox="-400 -400 800 800">'
                   f'<path id="front" d="{d}"/></svg>')
    got = read_pieces(svg)
    assert [p.name for p in got] == ["front-part1", "front-part2"]
    whole = abs(sum(0.5 * (pts[k - 1, 0] * pts[k, 1] - pts[k, 0] * pts[k - 1, 1]) for k in range(len(pts))))
    assert sum(p.area for p in got) == pytest.approx(whole, rel=1e-6)      # (the 3e-5 mm gap aside)
    assert all("pinches" in p.notes[-1] and p.meta["split_from"] == "front" for p in got)
    from clothgrid.quality import quality

    for p in got:
        assert quality(generate_piece(p, edge_length=5.0)).folded == 0
    # a near-touch that would cut off a small lobe (0.3 % of the area): left as it is
    from clothgrid.patterns.piece import pinch_pairs, split_pinched

    lobed = np.array([[0, 0], [100, 0], [100, 50], [110, 52], [110, 58], [100.00001, 50.00001], [100, 100],
                      [0, 100]], float)
    piece = piece_from_polygon("s", lobed)
    assert len(pinch_pairs(piece.outline, 1e-3)) == 1
    assert [p.name for p in split_pinched(piece)] == ["s"]


def test_svg_sew_line_left_open_along_a_fold_is_closed_there(tmp_path):
    """TauMeta/tmtp draws the sew line of a piece cut on the fold as an open path whose ends sit on the
    cut line's straight edge (no seam allowance there): it is closed along that edge and gridded as
    the sew line, its cut line skipped as the seam allowance around it. An open path whose missing
    side does not run along the cut line stays open."""
    cut = "M 0,0 L 215,0 L 215,315 L 0,315 Z"                          # 15 mm allowance, none at x = 0
    sew = "M 0,15 L 200,15 C 210,100 190,200 200,300 L 0,300"           # open along x = 0
    body = (f'<g id="Back"><path id="Back-A-cuttingline" class="cuttingline" d="{cut}"/>'
            f'<path id="Back-A-seamline" class="seamline" d="{sew}"/></g>')
    path = _svg(tmp_path, body)
    got = read_pieces(path)
    (piece,) = got
    assert piece.name == "Back-A"
    ends = np.array(piece.meta["closed_along"])
    assert np.ptp(ends[:, 0]) < 1e-9 and abs(np.ptp(ends[:, 1])) == pytest.approx(285.0)
    assert 200 * 285 * 0.95 < piece.area < 210 * 285
    assert any("closed along the straight edge of cut line" in n for n in piece.notes)
    assert [s.name for s in got.skipped] == ["Back-A-cuttingline"]
    # the missing side bulges away from the cut line's edge: nothing to close along
    sew2 = "M 5,15 L 200,15 L 200,300 L 5,300"
    body2 = (f'<g id="Back"><path id="Back-A-cuttingline" class="cuttingline" d="M 0,0 L 215,0 L 215,315 '
             f'L 0,315 C -40,200 -40,100 0,0 Z"/><path id="Back-A-seamline" class="seamline" d="{sew2}"/></g>')
    (only,) = read_pieces(_svg(tmp_path, body2))
    assert "closed_along" not in only.meta and only.name.endswith("cuttingline")
