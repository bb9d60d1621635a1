"""Whole garments: every panel of a GarmentCode specification gridded, sewn node for node, placed.

:func:`garment` reads a GarmentCode (or Garment-Pattern-Generator) specification
with its stitches (:func:`clothgrid.patterns.garmentcode.read_garment_spec`), and

1. samples every spec edge densely, in its own direction, and picks each panel's
   four grid corners at panel vertices (:func:`clothgrid.patterns.choose_corners`
   on the vertices; a panel with fewer than four vertices gets corners at the
   middle of its longest edges, carried across the seam to the edge sewn to it);
2. chooses the number of grid intervals of every boundary segment by an integer
   program (:mod:`clothgrid.garment_counts`): both edges of a stitch equal,
   opposite grid sides equal, close to the target edge length;
3. puts the nodes of every segment at equal arc-length fractions of it (so both
   edges of a seam have their nodes at the same fractions, and every panel
   vertex is a node) and grids each panel with the real-pattern defaults
   (uniform weights, ``functional="auto"``), the boundary nodes fixed;
4. places each panel with the spec's rotation and translation (GarmentCode's
   ``R = Rz Ry Rx`` of the XYZ Euler angles in degrees, ``p = R [x, y, 0] +
   t``; Y up; millimetres), keeping the flat pattern coordinates as the rest shape;
5. pairs the nodes of every stitch along the seam (edge ``a``'s end meets edge
   ``b``'s start, GarmentCode's default; start meets start with ``right_wrong``)
   and, on request, welds them.

See ``docs/garment.md``.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from .boundary import Boundary
from .errors import InputError
from .garment_counts import SHRINK_FREE, CountConflict, CountProblem, solve_counts
from .garment_seams import edge_polyline, mesh_report, ordered_pairs, points_at, propagate_splits, weld
from .geometry import signed_area
from .patterns.garmentcode import GarmentSpec, SpecPanel, read_garment_spec
from .quality import TARGET_MIN_ANGLE_DEG
from .units import parse_length

__all__ = ["Garment", "garment", "euler_xyz_to_R", "split_quads", "flat_corners", "SEAM", "GARMENT_SPRING_KINDS", "write_garment"]

#: the spring kind code of the zero-length seam springs (after structural 0, shear 1, bend 2)
SEAM = 3
GARMENT_SPRING_KINDS = ("structural", "shear", "bend", "seam")
SAMPLING_REL_TOL = 1e-7


def euler_xyz_to_R(angles_deg: Sequence[float]) -> np.ndarray:
    """GarmentCode's panel rotation: ``Rz(c) Ry(b) Rx(a)`` of ``[a, b, c]`` in degrees.

    As pygarment's ``pattern/rotation.py::euler_xyz_to_R`` (Maya's XYZ order);
    equal to ``scipy.spatial.transform.Rotation.from_euler("xyz", angles, degrees=True)``.
    """
    a, b, c = np.radians(np.asarray(angles_deg, dtype=np.float64))
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    return rz @ ry @ rx


def split_quads(quads: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """``(2F, 3)`` triangles of quads: along the first diagonal (corners 0-2), or along the other
    one (1-3) where the first would make a triangle of no area.

    A triangular panel's fourth grid corner sits on a straight side, so the grid cell there has a
    180 degree angle; cut along the diagonal through that corner both triangles keep an area
    (the other diagonal runs along the side). ``xy`` are the flat (rest) coordinates.
    """
    q = np.asarray(quads, dtype=np.int64)
    p = np.asarray(xy, dtype=np.float64)[q]

    def area(i: int, j: int, k: int) -> np.ndarray:
        a, b = p[:, j] - p[:, i], p[:, k] - p[:, i]
        return 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])

    total = area(0, 1, 2) + area(0, 2, 3)
    sign = np.where(total < 0, -1.0, 1.0)
    tiny = 1e-9 * np.abs(total)
    first = np.minimum(area(0, 1, 2) * sign, area(0, 2, 3) * sign)
    other = np.minimum(area(0, 1, 3) * sign, area(1, 2, 3) * sign)
    swap = (first <= tiny) & (other > first)
    t = np.stack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]], axis=1)
    t[swap] = np.stack([q[swap][:, [0, 1, 3]], q[swap][:, [1, 2, 3]]], axis=1)
    return t.reshape(-1, 3)


def flat_corners(grid_points: np.ndarray, max_deg: float = 179.0) -> list[int]:
    """Grid corners (0 bottom-left, 1 bottom-right, 2 top-right, 3 top-left) where the boundary
    does not turn (its angle at least ``max_deg``): a triangle's fourth corner on a straight side."""
    P = np.asarray(grid_points, dtype=np.float64)
    out = []
    for k, (c, a, b) in enumerate((((0, 0), (1, 0), (0, 1)), ((-1, 0), (-1, 1), (-2, 0)),
                                   ((-1, -1), (-2, -1), (-1, -2)), ((0, -1), (0, -2), (1, -1)))):
        u, v = P[a] - P[c], P[b] - P[c]
        cos = float(u @ v / (np.linalg.norm(u) * np.linalg.norm(v)))
        if cos <= math.cos(math.radians(max_deg)):
            out.append(k)
    return out


@dataclass
class _Layout:
    """One panel on its way: sampled edges, its counter-clockwise loop, corners, segments."""

    spec: SpecPanel
    polys: list[tuple[np.ndarray, np.ndarray]]
    ccw: list[tuple[int, bool]]            # (edge, reversed) in counter-clockwise order
    flipped: bool                          # the spec's loop runs clockwise in the panel plane
    corners: list[tuple[int, float]] = field(default_factory=list)   # (ccw position, ccw fraction)
    corner_method: str = ""
    fracs: dict[int, list[float]] = field(default_factory=dict)      # edge -> [0, splits..., 1]
    seg: dict[tuple[int, int], int] = field(default_factory=dict)    # (edge, j) -> segment id
    sequence: list[tuple[int, int, bool]] = field(default_factory=list)  # ccw from corner 0: (edge, j, forward)
    sides: list[list[int]] = field(default_factory=list)             # 4 lists of positions in sequence
    alternatives: list[list[tuple[int, float]]] | None = None        # other corner sets, best first
    dart_tips: list[int] = field(default_factory=list)               # vertices two sewn legs share


@dataclass(eq=False)
class Garment:
    """A sewn garment: every panel's grid, placed, with the seams' node pairs.

    Node arrays are indexed by the global node id (panels one after another, a
    panel's nodes in its grid's flat order ``i * nv + j``).

    Attributes
    ----------
    points : (N, 3) placed positions (mm, Y up).
    rest : (N, 2) flat pattern coordinates (mm) in each panel's own frame.
    panel : (N,) panel index of each node; ``panel_names`` the names.
    shapes : list of (nu, nv) per panel; ``offsets`` (P + 1,) first node of each panel.
    quads : (F, 4) oriented as the spec's edge loop (right side out, as GarmentCode sews).
    face_panel : (F,) panel of each quad.
    stitches : (S, 2) node pairs, ordered along each seam (edge ``a``'s direction).
    stitch_id : (S,) index of the spec stitch each pair comes from.
    edge_nodes : dict (panel name, edge index) -> node ids along that spec edge, in its direction.
    edge_fractions : dict (panel name, edge index) -> arc-length fractions of those nodes.
    grids : the panels' :class:`clothgrid.Grid` (2D, flat).
    info : counts, timings, corners, quality per panel.
    """

    spec: GarmentSpec
    points: np.ndarray
    rest: np.ndarray
    panel: np.ndarray
    panel_names: list[str]
    shapes: list[tuple[int, int]]
    offsets: np.ndarray
    quads: np.ndarray
    face_panel: np.ndarray
    stitches: np.ndarray
    stitch_id: np.ndarray
    edge_nodes: dict[tuple[str, int], np.ndarray]
    edge_fractions: dict[tuple[str, int], np.ndarray]
    grids: list[Any]
    info: dict[str, Any]

    @property
    def face_rest(self) -> np.ndarray:
        """``(N, 2)`` the rest coordinates as seen from each face's front side (mm).

        ``rest`` with ``x`` negated on the panels whose spec loop runs clockwise (``flipped`` in
        ``info["panels"]``: GarmentCode's mirrored copies, cut with the fabric turned over). Their
        quads are reversed to follow the spec's loop, so in ``rest`` they run clockwise; in
        ``face_rest`` every quad and triangle runs counter-clockwise, with positive area. Lengths
        and angles are those of ``rest`` (a mirror image). This is the ``st`` of the USD output,
        the ``vt`` of the OBJ, and the panel shape a cloth solver such as Newton's Style3D takes its
        rest state from (it drops a triangle of negative panel area as degenerate).
        """
        out = self.rest.copy()
        flipped = [i for i, p in enumerate(self.info.get("panels", ())) if p.get("flipped")]
        if flipped:
            out[np.isin(self.panel, flipped), 0] *= -1.0
        return out

    @property
    def triangles(self) -> np.ndarray:
        """``(2F, 3)``: every quad cut in two triangles (same orientation), see :func:`split_quads`."""
        return split_quads(self.quads, self.rest)

    def weld_map(self) -> np.ndarray:
        """``(N,)`` welded vertex of every grid node (stitched nodes merged)."""
        return weld(len(self.points), self.stitches)

    def welded(self) -> dict[str, np.ndarray]:
        """The welded mesh: ``map``, ``points`` (mean of the merged nodes), ``quads``, ``triangles``."""
        m = self.weld_map()
        w = int(m.max()) + 1
        cnt = np.bincount(m, minlength=w).astype(np.float64)
        pts = np.column_stack([np.bincount(m, weights=self.points[:, k], minlength=w) for k in range(3)])
        return {"map": m, "points": pts / cnt[:, None], "quads": m[self.quads],
                "triangles": m[self.triangles]}

    def springs(self) -> dict[str, np.ndarray]:
        """Every panel's structural, shear and bend springs (rest lengths on the flat pattern) and
        one zero-length ``seam`` spring per stitched pair of distinct nodes: ``pairs``, ``kind``
        (codes of :data:`GARMENT_SPRING_KINDS`), ``axis``, ``rest_length``."""
        pairs, kind, axis, rest = [], [], [], []
        for g, off in zip(self.grids, self.offsets[:-1]):
            s = g.springs()
            pairs.append(s.pairs + off)
            kind.append(s.kind)
            axis.append(s.axis)
            rest.append(s.rest_length)
        st = self.stitches[self.stitches[:, 0] != self.stitches[:, 1]]
        pairs.append(st)
        kind.append(np.full(len(st), SEAM, dtype=np.int8))
        axis.append(np.full(len(st), -1, dtype=np.int8))
        rest.append(np.zeros(len(st)))
        return {"pairs": np.concatenate(pairs).astype(np.int64), "kind": np.concatenate(kind),
                "axis": np.concatenate(axis), "rest_length": np.concatenate(rest)}

    def masses(self, density: float | str) -> np.ndarray:
        """``(N,)`` lumped node masses in kg for an areal density (kg/m^2 or text like ``150gsm``)."""
        return np.concatenate([g.node_masses(density, "mm") for g in self.grids])

    def mesh_report(self, welded: bool = True) -> dict:
        """:func:`clothgrid.garment_seams.mesh_report` of the welded (or unwelded) quads."""
        if welded:
            w = self.welded()
            return mesh_report(w["quads"], len(w["points"]))
        return mesh_report(self.quads, len(self.points))

    def save(self, path: str | Path, *, seams: str = "keep", density: float | str | None = None) -> Path:
        """Write ``.npz``, ``.obj`` or USD (atomic): see :func:`write_garment`."""
        return write_garment(self, path, seams=seams, density=density)


# --------------------------------------------------------------------------- corners


def _bottom_first(pts: np.ndarray) -> int:
    """Which of 4 corner points (counter-clockwise) starts the side most nearly along +x."""
    best, k_best = -np.inf, 0
    for k in range(4):
        d = pts[(k + 1) % 4] - pts[k]
        n = float(np.hypot(*d))
        v = d[0] / n if n > 0 else -np.inf
        if v > best + 1e-12:
            best, k_best = v, k
    return k_best


def _panel_outline(lay: _Layout) -> tuple[np.ndarray, list[int]]:
    """The panel's counter-clockwise outline points and the outline index of each loop item's start."""
    starts, parts, count = [], [], 0
    for e, rev in lay.ccw:
        pts = lay.polys[e][0][::-1] if rev else lay.polys[e][0]
        starts.append(count)
        parts.append(pts[:-1])
        count += len(pts) - 1
    return np.concatenate(parts), starts


def _choose_corners(lay: _Layout, given: Sequence[Any] | None) -> None:
    """Four corners on the counter-clockwise loop: panel vertices, or edge middles if too few."""
    from .patterns import choose_corners
    from .patterns.piece import piece_from_polygon

    spec, ccw = lay.spec, lay.ccw
    outline, starts = _panel_outline(lay)
    start_vertex = [spec.edges[e].end if rev else spec.edges[e].start for e, rev in ccw]
    if given is not None and any(isinstance(c, tuple) for c in given):
        # (edge, fraction of that edge in its own direction): an SVG / DXF piece's corners
        pos = {e: (k, rev) for k, (e, rev) in enumerate(ccw)}
        at = []
        for e, f in given:
            k, rev = pos[e]
            f = 1.0 - f if rev else f
            at.append(((k + 1) % len(ccw), 0.0) if f >= 1.0 else (k, f))
        order = sorted(at)
        first = order.index(at[0])
        lay.corners = order[first:] + order[:first]
        lay.corner_method = "pattern"
        return
    if given is not None:
        where = {v: k for k, v in enumerate(start_vertex)}
        bad = [v for v in given if v not in where]
        if len(given) != 4 or bad or len(set(given)) != 4:
            raise InputError(f"panel {spec.name!r}: corners must be 4 distinct vertex indices of the "
                             f"panel (0..{len(spec.vertices) - 1}), got {list(given)}")
        ks = sorted(where[v] for v in given)
        first = ks.index(where[given[0]])
        ks = ks[first:] + ks[:first]
        lay.corners = [(k, 0.0) for k in ks]
        lay.corner_method = "given"
        return
    if len(ccw) >= 4:
        idx = np.asarray(starts)
        piece = piece_from_polygon(spec.name, outline, vertices=idx, turn_points=idx)
        if len(piece.outline) == len(outline):
            choice = choose_corners(piece)
            by_outline = {s: k for k, s in enumerate(starts)}
            if not choice.inserted and all(int(c) in by_outline for c in choice.corners):
                lay.corners = [(by_outline[int(c)], 0.0) for c in choice.corners]
                lay.corner_method = choice.method
                return
    # fewer than 4 vertices (a triangle: a godet, a collar tip): split the longest pieces in half
    pieces = [(k, 0.0, 1.0) for k in range(len(ccw))]
    length = [lay.polys[e][1][-1] for e, _ in ccw]
    while len(pieces) < 4:
        i = int(np.argmax([length[k] * (b - a) for k, a, b in pieces]))
        k, a, b = pieces[i]
        pieces[i:i + 1] = [(k, a, 0.5 * (a + b)), (k, 0.5 * (a + b), b)]
    pts = np.array([points_at(_ccw_poly(lay, k), np.array([a]))[0] for k, a, _ in pieces])
    first = _bottom_first(pts)
    pieces = pieces[first:] + pieces[:first]
    lay.corners = [(k, a) for k, a, _ in pieces]
    lay.corner_method = "split"


def _ccw_poly(lay: _Layout, k: int) -> tuple[np.ndarray, np.ndarray]:
    e, rev = lay.ccw[k]
    pts, s = lay.polys[e]
    return (pts[::-1], s[-1] - s[::-1]) if rev else (pts, s)


def _count_problem(gs: Any, lays: dict[str, "_Layout"], h: float, fixed: dict | None,
                   shrink: float | None = None) -> CountProblem:
    """The integer program of the garment's node counts, from its panels' corners (sets each
    layout's segments, sequence and sides); ``shrink``: :attr:`CountProblem.shrink`."""
    for lay in lays.values():
        lay.fracs, lay.seg = {}, {}
    # splits: corners inside edges, carried across seams
    splits: dict[tuple[str, int], set[float]] = {}
    for name, lay in lays.items():
        for k, f in lay.corners:
            if 0.0 < f < 1.0:
                e, rev = lay.ccw[k]
                splits.setdefault((name, e), set()).add(1.0 - f if rev else f)
    propagate_splits(splits, gs.stitches)

    # segments and the integer program
    prob = CountProblem(shrink=shrink)
    for name, lay in lays.items():
        for e in range(len(lay.spec.edges)):
            fr = [0.0] + sorted(splits.get((name, e), ())) + [1.0]
            lay.fracs[e] = fr
            L = lay.polys[e][1][-1]
            for j in range(len(fr) - 1):
                lay.seg[(e, j)] = prob.add_segment(L * (fr[j + 1] - fr[j]) / h)
        seq: list[tuple[int, int, bool]] = []
        starts: list[tuple[int, float]] = []
        for k, (e, rev) in enumerate(lay.ccw):
            m = len(lay.fracs[e]) - 1
            for j in (range(m - 1, -1, -1) if rev else range(m)):
                seq.append((e, j, not rev))
                starts.append((k, 1.0 - lay.fracs[e][j + 1] if rev else lay.fracs[e][j]))
        pos = []
        for k, f in lay.corners:
            hit = [i for i, (kk, ff) in enumerate(starts) if kk == k and abs(ff - f) <= 1e-12]
            if not hit:
                raise InputError(f"panel {name!r}: internal error: a corner is not at a segment start")
            pos.append(hit[0])
        first = pos[0]
        lay.sequence = seq[first:] + seq[:first]
        pos = [(p_ - first) % len(seq) for p_ in pos] + [len(seq)]
        lay.sides = [list(range(pos[i], pos[i + 1])) for i in range(4)]
        if any(not s for s in lay.sides):
            raise InputError(f"panel {name!r}: a grid side has no segment")
        ids = [[lay.seg[lay.sequence[i][:2]] for i in side] for side in lay.sides]
        prob.groups.append((f"panel {name!r}: bottom = top and left = right "
                            f"(corners at vertices {_corner_names(lay)})",
                            [(ids[0], ids[2]), (ids[1], ids[3])]))
        prob.minimum += [(ids[0], 2), (ids[1], 2)]
    for st in gs.stitches:
        la, lb = lays[st.a[0]], lays[st.b[0]]
        ma, mb = len(la.fracs[st.a[1]]) - 1, len(lb.fracs[st.b[1]]) - 1
        if ma != mb:
            raise InputError(f"stitch {st.index}: internal error: its edges are split differently")
        rows = [([la.seg[(st.a[1], j)]], [lb.seg[(st.b[1], j if st.same_direction else ma - 1 - j)]])
                for j in range(ma)]
        prob.groups.append((f"stitch {st.index} ({st.a[0]!r} edge {st.a[1]} ~ {st.b[0]!r} edge {st.b[1]}"
                            + (", right_wrong" if st.same_direction else "") + ")", rows))
    for (pn, e), n in (fixed or {}).items():
        lay = lays[pn]
        if len(lay.fracs[e]) != 2:
            raise InputError(f"panel {pn!r} edge {e} is split by a corner; its count cannot be fixed")
        prob.fixed[lay.seg[(e, 0)]] = int(n)
    return prob


#: On a conflict, at most this many other corner sets are tried per conflicting panel.
MAX_ALTERNATIVES = 12


#: ... chosen among this many corner sets by a transfinite grid's score (no relaxation) first.
PRE_RANKED = 3 * MAX_ALTERNATIVES


def _alternatives(lay: "_Layout") -> list[list[tuple[int, float]]]:
    """Other corner sets of a panel, at its vertices, best coarse grid first (the first choice left
    out). Every set of 4 vertices is scored on its unrelaxed transfinite grid (cheap); the best
    :data:`PRE_RANKED` are scored again on their relaxed coarse grids. Computed once per panel."""
    from .patterns.corners import _sides_grid, _side_points, coarse_grid, grid_score

    if lay.alternatives is not None:
        return lay.alternatives
    ccw = lay.ccw
    if len(ccw) < 4 or len(ccw) > 12:
        lay.alternatives = []
        return []
    outline, starts = _panel_outline(lay)
    pre = []
    for ks in itertools.combinations(range(len(ccw)), 4):
        cand = [(k, 0.0) for k in ks]
        if sorted(cand) == sorted(lay.corners):
            continue
        c = [starts[k] for k in ks]
        try:
            sides = [_side_points(outline, c[k], c[(k + 1) % 4]) for k in range(4)]
            score = grid_score(_sides_grid(sides, 9, 9))
        except (InputError, ValueError, FloatingPointError):
            continue
        pre.append((-score, ks))
    pre.sort()
    scored = []
    for _, ks in pre[:PRE_RANKED]:
        try:
            score = grid_score(coarse_grid(outline, [starts[k] for k in ks]))
        except (InputError, ValueError, FloatingPointError):
            continue
        scored.append((-score, ks))
    scored.sort()
    out = []
    for _, ks in scored[:MAX_ALTERNATIVES]:
        pts = np.array([outline[starts[k]] for k in ks])
        first = _bottom_first(pts)
        ks = ks[first:] + ks[:first]
        out.append([(k, 0.0) for k in ks])
    lay.alternatives = out
    return out


def _loosen(gs: Any, lays: dict[str, "_Layout"], h: float, fixed: dict | None, exc: CountConflict,
            say: Callable[[str], None]) -> tuple[dict, dict, CountProblem]:
    """Node counts after a conflict: other corners for one of the conflicting panels whose corners
    were chosen automatically (its next best sets by coarse grid), the first that works; else
    the conflict, with what to do about it."""
    names = [n for n in lays if any(f"panel {n!r}:" in g for g in exc.groups)
             and lays[n].corner_method not in ("given", "pattern")]
    for name in names:
        lay = lays[name]
        kept = list(lay.corners)
        for alt in _alternatives(lay):
            lay.corners = alt
            prob = _count_problem(gs, lays, h, fixed)
            try:
                counts, info = solve_counts(prob)
            except CountConflict:
                continue
            lay.corner_method = "seams"
            say(f"panel {name!r}: other grid corners (vertices {_corner_names(lay)}): the chosen ones "
                "made the node counts conflict")
            return counts, info, prob
        lay.corners = kept
    raise CountConflict(f"{gs.path}: {exc}. Loosen it by choosing other grid corners for one of "
                        "these panels (corners={'PANEL': [i, j, k, l]}, on the command line "
                        "--corners PANEL=I,J,K,L: panel vertex indices bottom-left, bottom-right, "
                        "top-right, top-left), so that other edges form its opposite sides",
                        exc.groups) from None


def _grid_panel(lay: "_Layout", counts: np.ndarray, opts: dict[str, Any],
                cache: dict[Any, dict[str, Any]]) -> dict[str, Any]:
    """Sample one panel's boundary at its segments' node counts and grid it (``generate`` keeps the
    boundary fixed). Node ids are the panel's own (``i * nv + j``). Cached by corners and counts."""
    from .generate import generate
    from .quality import quality, sim_figures

    key = (lay.spec.name, tuple(lay.corners), tuple(tuple(lay.fracs[e]) for e in sorted(lay.fracs)),
           tuple(int(counts[lay.seg[s[:2]]]) for s in lay.sequence))
    if key in cache:
        return cache[key]
    loop_xy: list[np.ndarray] = []
    seg_pos: dict[tuple[int, int], tuple[int, int]] = {}   # (edge, j) -> (loop start, count)
    cursor = 0
    for e, j, fwd in lay.sequence:
        n = int(counts[lay.seg[(e, j)]])
        fr = lay.fracs[e]
        f = np.linspace(fr[j], fr[j + 1], n + 1)
        if not fwd:
            f = f[::-1]
        xy = points_at(lay.polys[e], f)
        loop_xy.append(xy[:-1])
        seg_pos[(e, j)] = (cursor, n)
        cursor += n
    X = np.concatenate(loop_xy)
    L = len(X)
    side_n = [sum(int(counts[lay.seg[lay.sequence[i][:2]]]) for i in s) for s in lay.sides]
    nu, nv = side_n[0] + 1, side_n[1] + 1
    assert side_n[2] == nu - 1 and side_n[3] == nv - 1 and L == 2 * (nu + nv) - 4

    def gridded(X: np.ndarray) -> Any:
        bottom = X[0:nu]
        right = X[nu - 1:nu + nv - 1]
        top = X[nu + nv - 2:2 * nu + nv - 2][::-1]
        left = np.vstack([X[2 * nu + nv - 3:], X[:1]])[::-1]
        return generate(Boundary.from_sides(bottom, right, top, left, name=lay.spec.name), None, **opts)

    grid = gridded(X)
    q = quality(grid)
    figs = sim_figures(grid.points)
    tips: list[tuple[int, float]] = []
    if q.folded and lay.dart_tips:
        # a needle-sharp dart tip: its two cells share the outline's reflex angle there, and the
        # line inward from it must keep to a cone as narrow as the dart; the tip moved toward its
        # neighbours (the dart shortened by about half a node spacing) leaves the cells room
        Y, moved = _blunted(X, lay, L)
        if moved:
            g2 = gridded(Y)
            q2 = quality(g2)
            f2 = sim_figures(g2.points)
            if (q2.folded, -f2["min_angle_deg"]) < (q.folded, -figs["min_angle_deg"]):
                grid, q, X, tips, figs = g2, q2, Y, moved, f2
    p = np.arange(L)
    gi = np.where(p < nu - 1, p, np.where(p < nu + nv - 2, nu - 1,
                  np.where(p < 2 * nu + nv - 3, nu - 1 - (p - (nu + nv - 2)), 0)))
    gj = np.where(p < nu - 1, 0, np.where(p < nu + nv - 2, p - (nu - 1),
                  np.where(p < 2 * nu + nv - 3, nv - 1, nv - 1 - (p - (2 * nu + nv - 3)))))
    loop_node = gi * nv + gj
    flat = grid.points.reshape(-1, 3)[:, :2]
    # the boundary nodes are the sampled ones (generate keeps the boundary fixed)
    drift = float(np.abs(flat[loop_node] - X).max())
    edge_nodes, edge_fracs = {}, {}
    for e in range(len(lay.spec.edges)):
        nodes, fracs = [], []
        fr = lay.fracs[e]
        for j in range(len(fr) - 1):
            start, n = seg_pos[(e, j)]
            ids = loop_node[(start + np.arange(n + 1)) % L]
            fj = np.linspace(fr[j], fr[j + 1], n + 1)
            fwd = next(fw for ee, jj, fw in lay.sequence if ee == e and jj == j)
            if not fwd:
                ids = ids[::-1]
            nodes.append(ids if j == 0 else ids[1:])
            fracs.append(fj if j == 0 else fj[1:])
        edge_nodes[e] = np.concatenate(nodes)
        edge_fracs[e] = np.concatenate(fracs)
    out = {"grid": grid, "shape": (nu, nv), "edge_nodes": edge_nodes, "edge_fracs": edge_fracs,
           "drift": drift, "quality": q, "figures": figs, "key": key, "dart_tips_moved": tips}
    cache[key] = out
    return out


#: A dart tip is blunted (:func:`_blunted`) where its two boundary edges meet at less than this
#: angle, ...
DART_TIP_DEG = 20.0
#: ... moved this fraction of the way to the middle of its two neighbouring boundary nodes ...
DART_TIP_SHIFT = 0.5
#: ... and never farther than this many of the panel outline's typical (median) node spacings (a
#: dart leg of a few long intervals would otherwise lose centimetres). On GarmentCode-Nesting's
#: rand_033UAN6C0K (pants backs, darts 2.8 cm wide and 18-21 cm deep, one interval a leg at 10 mm)
#: the folded cells at a tip go 2 -> 1 a back; uncapped, the dart shortened by 6 cm, none.
DART_TIP_MOST = 0.5


def _dart_tips(gs: GarmentSpec, name: str) -> list[int]:
    """The vertices of panel ``name`` where the two edges of one of its darts (a stitch of two of its
    own edges) meet: the end of one that is the start of the other, or both ends or both starts."""
    edges = gs.panels[name].edges
    tips = []
    for st in gs.stitches:
        if st.a[0] == name and st.b[0] == name:
            a, b = edges[st.a[1]], edges[st.b[1]]
            shared = {a.start, a.end} & {b.start, b.end}
            if len(shared) == 1:
                tips.append(shared.pop())
    return sorted(set(tips))


def _blunted(X: np.ndarray, lay: "_Layout", L: int) -> tuple[np.ndarray, list[tuple[int, float]]]:
    """The boundary loop ``X`` with each of the panel's dart tips (``lay.dart_tips``: the vertex the
    two legs of a dart share) that is needle-sharp (:data:`DART_TIP_DEG`) moved
    :data:`DART_TIP_SHIFT` of the way to the middle of its neighbours; the tips moved, with how far
    (mm). The tip is a node of both legs, sewn to each other, so the seam still matches node for node."""
    Y = X.copy()
    moved = []
    spacing = float(np.median(np.hypot(*(np.roll(X, -1, axis=0) - X).T)))    # the loop's typical interval
    for v in lay.dart_tips:
        e, end = next((k, ed.end == v) for k, ed in enumerate(lay.spec.edges) if v in (ed.start, ed.end))
        at = lay.polys[e][0][-1 if end else 0]
        k = int(np.argmin(np.hypot(*(X - at).T)))
        p, a, c = X[k], X[k - 1], X[(k + 1) % L]
        u, w = a - p, c - p
        cos = float(u @ w) / (float(np.hypot(*u)) * float(np.hypot(*w)) or 1.0)
        if cos > math.cos(math.radians(DART_TIP_DEG)):
            step = DART_TIP_SHIFT * (0.5 * (a + c) - p)
            reach = float(np.hypot(*step))
            if reach > DART_TIP_MOST * spacing:     # a leg of few long intervals: at most this far
                step *= DART_TIP_MOST * spacing / reach
            Y[k] = p + step
            moved.append((int(v), float(np.hypot(*step))))
    return Y, moved


def _panel_cost(m: dict[str, Any]) -> tuple[int, float]:
    """One panel's :func:`_grid_panel` result: its folded cells, then its smallest angle (negated)."""
    return int(m["quality"].folded), -float(m["figures"]["min_angle_deg"])


def _cost(made: dict[str, dict[str, Any]]) -> tuple[int, float]:
    """Folded cells in all, then the smallest cell angle of all panels (negated: lower is better),
    the grid-corner cells aside: a corner on a straight side (a triangular godet's) has a scaled
    Jacobian of 0 whatever the grid, which made the scaled Jacobian a tie at rounding (1e-16) between
    grids of 1.1 and 4.0 degrees."""
    folded = sum(int(m["quality"].folded) for m in made.values())
    return folded, -min(float(m["figures"]["min_angle_deg"]) for m in made.values())


#: The count objectives :func:`garment` tries: the relative deviations alone (None), and with
#: :data:`~clothgrid.garment_counts.SHRINK_FREE`'s penalty on segments cut below a quarter of their
#: target; the garment that grids better is kept.
COUNT_SHRINKS: tuple[float | None, ...] = (None, SHRINK_FREE)


def _count_candidates(gs: Any, lays: dict[str, "_Layout"], h: float, fixed: dict | None, counts: np.ndarray,
                      count_info: dict, prob: CountProblem, made: dict[str, dict[str, Any]],
                      opts: dict[str, Any], cache: dict[Any, dict[str, Any]]) -> list[tuple]:
    """``(counts, info, problem, made)`` of each objective of :data:`COUNT_SHRINKS` for the same
    corners (each panel gridded with them; the given ones first among equals), best first by
    :func:`_cost` (fewer folded cells, else a larger smallest scaled Jacobian). The relative
    deviations' sum cuts long segments first (a pants back's 20 cm dart legs to one interval each,
    their tips folded); its penalty alone, tried on 26 specs, helped ten and hurt four."""
    cands = [(counts, count_info, prob, made)]
    for shrink in COUNT_SHRINKS:
        if shrink == prob.shrink:
            continue
        p2 = _count_problem(gs, lays, h, fixed, shrink)
        try:
            c2, i2 = solve_counts(p2)
        except (CountConflict, InputError):
            continue
        if not np.array_equal(c2, counts):
            cands.append((c2, i2, p2, {n: _grid_panel(la, c2, opts, cache) for n, la in lays.items()}))
    return sorted(cands, key=lambda c: _cost(c[3]))           # (a stable sort: the given first on ties)


def _counted_and_unfolded(gs: Any, lays: dict[str, "_Layout"], h: float, fixed: dict | None, counts: np.ndarray,
                          count_info: dict, prob: CountProblem, made: dict[str, dict[str, Any]],
                          opts: dict[str, Any], cache: dict[Any, dict[str, Any]], say: Callable[[str], None]) -> tuple:
    """The garment's counts and grids: the candidates of :func:`_count_candidates` in turn, each with
    its folding panels given other corners (:func:`_unfold`), until one leaves no fold; the best kept
    (its progress lines said, the layouts' corners its)."""
    cands = _count_candidates(gs, lays, h, fixed, counts, count_info, prob, made, opts, cache)
    start = {n: (list(la.corners), la.corner_method) for n, la in lays.items()}
    best = None
    for counts, count_info, prob, made in cands:
        for n, (corners, method) in start.items():
            lays[n].corners, lays[n].corner_method = list(corners), method
        _count_problem(gs, lays, h, fixed, prob.shrink)          # the layouts' segments for these corners
        lines: list[str] = []
        got = _unfold(gs, lays, h, fixed, counts, count_info, prob, made, opts, cache, lines.append)
        kept = {n: (list(la.corners), la.corner_method) for n, la in lays.items()}
        if best is None or _cost(got[3]) < _cost(best[0][3]):
            best = (got, kept, lines)
        if _cost(best[0][3])[0] == 0:
            break
    got, kept, lines = best
    for n, (corners, method) in kept.items():
        lays[n].corners, lays[n].corner_method = corners, method
    _count_problem(gs, lays, h, fixed, got[2].shrink)
    for line in lines:
        say(line)
    if got[2].shrink is not None:
        say(f"node counts: a segment cut below 1/{got[2].shrink:g} of its target charged more (the garment "
            "grids better so)")
    return got


def _unfold(gs: Any, lays: dict[str, "_Layout"], h: float, fixed: dict | None, counts: np.ndarray,
            count_info: dict, prob: CountProblem, made: dict[str, dict[str, Any]], opts: dict[str, Any],
            cache: dict[Any, dict[str, Any]], say: Callable[[str], None]) -> tuple:
    """Where a panel with automatic corners keeps folded cells, try its next best corner sets (as
    :func:`_loosen` does for a conflict): each changes the node counts (one integer program for the
    whole garment), so when the panel alone grids better, every panel whose counts change is
    gridded again; a set is kept when the garment's folded cells drop, or its worst corner improves
    at equal folds (the best found is kept)."""
    shrink = prob.shrink                 # the objective the counts were chosen with
    for name, lay in lays.items():
        if int(made[name]["quality"].folded) == 0 or lay.corner_method in ("given", "pattern"):
            continue
        best = (_cost(made), list(lay.corners), counts, count_info, prob, made, lay.corner_method)
        start = best[0][0]
        for alt in _alternatives(lay):
            lay.corners = alt
            try:
                p2 = _count_problem(gs, lays, h, fixed, shrink)
                c2, i2 = solve_counts(p2)
            except (CountConflict, InputError):
                continue
            own = _grid_panel(lay, c2, opts, cache)     # the panel alone first: most sets fold it too
            if _panel_cost(own) >= _panel_cost(best[5][name]):
                continue
            m2 = {n: _grid_panel(la, c2, opts, cache) for n, la in lays.items()}
            cost = _cost(m2)
            if cost < best[0]:
                best = (cost, list(alt), c2, i2, p2, m2, "unfold")
                # no fold left: enough where the panel's smallest angle meets the target, else the
                # other sets are looked at too (a high-low circle skirt's first unfolded set left
                # 1.6 degrees, a later one 6.3)
                if cost[0] == 0 and float(m2[name]["figures"]["min_angle_deg"]) >= TARGET_MIN_ANGLE_DEG:
                    break
        cost, corners, counts, count_info, prob, made, method = best
        lay.corners, lay.corner_method = corners, method
        _count_problem(gs, lays, h, fixed, shrink)  # the layouts' segments for the corners kept
        if cost[0] < start:
            say(f"panel {name!r}: other grid corners (vertices {_corner_names(lay)}): {start} folded "
                f"cells -> {cost[0]}")
    return counts, count_info, prob, made


# --------------------------------------------------------------------------- the garment


def _parse_corners(corners: Any) -> dict[str, list[int]]:
    """``{"panel": [i, j, k, l]}`` or text ``PANEL=i,j,k,l`` (a list of them)."""
    if corners is None:
        return {}
    if isinstance(corners, dict):
        return {str(k): [int(x) for x in v] for k, v in corners.items()}
    out: dict[str, list[int]] = {}
    for text in ([corners] if isinstance(corners, str) else corners):
        name, sep, rest = str(text).rpartition("=")
        try:
            out[name] = [int(x) for x in rest.split(",")]
        except ValueError:
            name = ""
        if not sep or not name:
            raise InputError(f"corners {text!r}: expected PANEL=I,J,K,L (four vertex indices of the panel)")
    return out


def garment(spec: str | Path | GarmentSpec, *, edge_length: float | str = "10mm", units: str | None = None,
            corners: Any = None, fixed: dict[tuple[str, int], int] | None = None,
            stitches: str | Path | None = None,
            progress: Callable[[str], None] | None = None, **generate_options: Any) -> Garment:
    """Grid, sew and place every panel of a GarmentCode specification (or a stitched SVG / DXF pattern).

    Parameters
    ----------
    spec : path or GarmentSpec
        A GarmentCode / Garment-Pattern-Generator ``*_specification.json``, or
        an ``.svg`` / ``.dxf`` pattern with ``stitches``.
    edge_length : float or str
        Target grid edge length (mm, or text with a unit: ``"1cm"``).
    units : str, optional
        The spec's length unit instead of its ``units_in_meter``.
    corners : dict or list of str, optional
        Grid corners of some panels, as four vertex indices of the panel in
        the order bottom-left, bottom-right, top-right, top-left
        (``{"front": [0, 1, 2, 3]}`` or ``["front=0,1,2,3"]``): a way out when the
        automatic corners make the node counts conflict.
    fixed : dict, optional
        ``(panel, edge) -> intervals``: fix the count of a spec edge (not split).
    stitches : path, optional
        The JSON stitches file of an SVG / DXF pattern
        (:mod:`clothgrid.garment_stitches`): its seams, pieces and placement.
        The pieces' grid corners are :func:`clothgrid.patterns.choose_corners`'
        unless ``corners`` gives others (vertex indices of the garment panel:
        the cuts of its outline, ``info["panels"][i]["corner_vertices"]``).
    progress : callable, optional
        Receives progress lines.
    **generate_options
        Passed to :func:`clothgrid.generate` (default ``weights="uniform"``,
        ``functional="auto"``: the real-pattern defaults).

    Raises
    ------
    InputError
        A malformed spec; :class:`~clothgrid.garment_counts.CountConflict` when
        no node counts exist (the message names the conflicting constraints).
    """
    say = progress or (lambda _m: None)
    t_start = time.perf_counter()
    h = parse_length(edge_length, "mm", what="edge length")
    given: dict[str, Any] = {}
    if isinstance(spec, GarmentSpec):
        gs = spec
    elif stitches is not None or Path(spec).suffix.lower() in (".svg", ".dxf"):
        from .garment_stitches import read_stitched_pattern

        # without a stitches file, the seams an SVG lists in its <metadata> (else an InputError)
        sp = read_stitched_pattern(spec, stitches, edge_length=h, units=units)
        gs, given = sp.spec, dict(sp.corners)
    else:
        gs = read_garment_spec(spec, units=units)
    given.update(_parse_corners(corners))
    unknown = [n for n in given if n not in gs.panels]
    if unknown:
        raise InputError(f"corners given for unknown panel(s) {', '.join(map(repr, unknown))}; the panels "
                         f"are {', '.join(map(repr, gs.panels))}")
    for key, n in (fixed or {}).items():
        pn, e = key if isinstance(key, tuple) and len(key) == 2 else (None, None)
        if pn not in gs.panels:
            raise InputError(f"fixed count {key!r}: no panel named {pn!r}; the panels are "
                             f"{', '.join(map(repr, gs.panels))}")
        ne = len(gs.panels[pn].edges)
        if isinstance(e, bool) or not isinstance(e, int) or not 0 <= e < ne:
            raise InputError(f"fixed count {key!r}: panel {pn!r} has no edge {e!r} (it has {ne} edges, 0..{ne - 1})")
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise InputError(f"fixed count {key!r}: the number of intervals must be an integer >= 1, not {n!r}")
    lays: dict[str, _Layout] = {}
    t0 = time.perf_counter()
    for name, p in gs.panels.items():
        size = float(np.linalg.norm(np.ptp(p.vertices, axis=0))) or 1.0
        polys = [edge_polyline(e.curve, SAMPLING_REL_TOL * size) for e in p.edges]
        loop_pts = np.concatenate([(polys[e][0][::-1] if rev else polys[e][0])[:-1] for e, rev in p.loop])
        flipped = signed_area(loop_pts) < 0
        ccw = [(e, not rev) for e, rev in reversed(p.loop)] if flipped else list(p.loop)
        lay = _Layout(p, polys, ccw, flipped, dart_tips=_dart_tips(gs, name))
        try:
            _choose_corners(lay, given.get(name))
        except InputError as exc:
            raise InputError(f"{gs.path}: panel {name!r}: {exc}") from None
        lays[name] = lay
    t_corners = time.perf_counter() - t0

    prob = _count_problem(gs, lays, h, fixed)
    try:
        counts, count_info = solve_counts(prob)
    except CountConflict as exc:
        counts, count_info, prob = _loosen(gs, lays, h, fixed, exc, say)
    say(f"node counts: {len(prob.targets)} segments, {count_info['constraints']} equalities, "
        f"MILP {count_info['seconds']:.3f} s")

    # sample and grid every panel; then, where a panel folds, other corners (same as a conflict)
    opts = {"weights": "uniform", "functional": "auto", **generate_options}
    t1 = time.perf_counter()
    cache: dict[Any, dict[str, Any]] = {}
    made = {name: _grid_panel(lay, counts, opts, cache) for name, lay in lays.items()}
    counts, count_info, prob, made = _counted_and_unfolded(gs, lays, h, fixed, counts, count_info, prob, made,
                                                           opts, cache, say)
    t_grid = time.perf_counter() - t1

    # place and assemble
    names = list(lays)
    grids, pts3, rest, panel_idx, quads, face_panel = [], [], [], [], [], []
    shapes: list[tuple[int, int]] = []
    offsets = [0]
    edge_nodes: dict[tuple[str, int], np.ndarray] = {}
    edge_fracs: dict[tuple[str, int], np.ndarray] = {}
    per_panel: list[dict[str, Any]] = []
    for pi, name in enumerate(names):
        lay, m = lays[name], made[name]
        grid, (nu, nv) = m["grid"], m["shape"]
        for e, ids in m["edge_nodes"].items():
            edge_nodes[(name, e)] = ids + offsets[-1]
            edge_fracs[(name, e)] = m["edge_fracs"][e]
        flat = grid.points.reshape(-1, 3)[:, :2]
        R = euler_xyz_to_R(lay.spec.rotation)
        xyz = np.column_stack([flat, np.zeros(len(flat))]) @ R.T + lay.spec.translation
        q = grid.quads + offsets[-1]
        if lay.flipped:
            q = q[:, ::-1]
        grids.append(grid)
        pts3.append(xyz)
        rest.append(flat.copy())
        panel_idx.append(np.full(len(flat), pi, dtype=np.int32))
        quads.append(q)
        face_panel.append(np.full(len(q), pi, dtype=np.int32))
        shapes.append((nu, nv))
        offsets.append(offsets[-1] + nu * nv)
        qual, figs = m["quality"], m["figures"]       # (the edge length asked does not enter these two)
        per_panel.append({"name": name, "nodes": [nu, nv], "corners": lay.corner_method,
                          "corner_vertices": _corner_names(lay), "flipped": lay.flipped,
                          "functional": grid.info.get("functional"), "folded": int(qual.folded),
                          "flat_corners": flat_corners(grid.points),
                          "min_angle_deg": figs.get("min_angle_deg"), "edge_spread": figs.get("edge_spread"),
                          "boundary_drift": m["drift"], "seconds": grid.info.get("seconds"),
                          "dart_tips_moved_mm": {v: d for v, d in m["dart_tips_moved"]}})
        say(f"{name}: {nu} x {nv} nodes, corners {lay.corner_method}, {qual.folded} folded")
    pairs, sid = [], []
    for st in gs.stitches:
        pr = ordered_pairs(edge_nodes[st.a], edge_nodes[st.b], st.same_direction)
        pairs.append(pr)
        sid.append(np.full(len(pr), st.index, dtype=np.int64))
    notes = list(gs.notes)
    twisted = twisted_seams(gs.stitches, pairs, np.concatenate(panel_idx), names)
    if twisted:
        notes.append(twisted)
        say(twisted)
    info = {"edge_length_mm": h, "length_unit": "mm", "up_axis": "Y", "spec_units": gs.units,
            "mm_per_spec_unit": gs.mm_per_unit, "counts": count_info, "panels": per_panel,
            "seconds": {"corners": t_corners, "milp": count_info["seconds"], "gridding": t_grid,
                        "total": time.perf_counter() - t_start},
            "notes": notes, "warnings": _units_doubt(gs, units)}
    return Garment(gs, np.concatenate(pts3), np.concatenate(rest), np.concatenate(panel_idx), names, shapes,
                   np.asarray(offsets), np.concatenate(quads), np.concatenate(face_panel),
                   np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64),
                   np.concatenate(sid) if sid else np.zeros(0, np.int64), edge_nodes, edge_fracs, grids, info)


def _units_doubt(gs: GarmentSpec, units: str | None) -> list[str]:
    """A line where the largest panel's size (mm) suggests the spec was read in the wrong units
    (:func:`clothgrid.units.size_warning`), unless ``units`` were given; else none."""
    if units is not None or not gs.panels:
        return []
    from .units import size_warning

    size = max(float(np.ptp(p.vertices, axis=0).max()) for p in gs.panels.values())
    doubt = size_warning(size, gs.units, "panel")
    return [doubt] if doubt else []


def twisted_seams(stitches: Sequence[Any], pairs: Sequence[np.ndarray], panel: np.ndarray,
                  names: Sequence[str]) -> str:
    """A note when welding merges two nodes of one panel that no dart of that panel joins.

    Nodes of one panel may weld together only through its own darts (a dart sews its legs; a
    waistband sewn across the dart's mouth then meets both mouth nodes, which the dart has already
    joined). Where two nodes of one panel meet otherwise, a seam is sewn the wrong way round
    (GarmentCode's own ``standing_lapel`` spec misses ``right_wrong`` on its two collar stitches,
    fixed in ``standing_lapel_fix``) and the welded mesh is pinched there. Returns ``""`` when none
    does, else a line naming the panels and the stitches that meet there.
    """
    pairs = [np.asarray(pr, dtype=np.int64).reshape(-1, 2) for pr in pairs]
    if not any(len(pr) for pr in pairs):
        return ""
    n = len(panel)
    full = weld(n, np.concatenate(pairs))
    dart = [pr for st, pr in zip(stitches, pairs) if st.a[0] == st.b[0] and len(pr)]
    by_dart = weld(n, np.concatenate(dart)) if dart else np.arange(n)
    # distinct (welded vertex, panel, dart class): more than one class per (vertex, panel) is a twist
    trip = np.unique(np.column_stack([full, panel, by_dart]), axis=0)
    vp, cnt = np.unique(trip[:, :2], axis=0, return_counts=True)
    bad = vp[cnt > 1]
    if not len(bad):
        return ""
    verts = set(bad[:, 0].tolist())
    pans = sorted({names[int(i)] for i in bad[:, 1]})
    hit = sorted({st.index for st, pr in zip(stitches, pairs) if len(pr) and verts & set(full[pr.reshape(-1)].tolist())})
    return (f"twisted seams: welding merges nodes of one panel that no dart of it joins (panel(s) "
            f"{', '.join(map(repr, pans))}; stitches {', '.join(map(str, hit))} meet there): a stitch "
            "sewn the wrong way round (a missing or extra 'right_wrong'?); the welded mesh is pinched there")


def _corner_names(lay: _Layout) -> str:
    out = []
    for k, f in lay.corners:
        e, rev = lay.ccw[k]
        v = lay.spec.edges[e].end if rev else lay.spec.edges[e].start
        out.append(str(v) if f == 0.0 else f"middle of edge {e}")
    return ", ".join(out)


# --------------------------------------------------------------------------- files


def write_garment(g: Garment, path: str | Path, *, seams: str = "keep",
                  density: float | str | None = None) -> Path:
    """Write a garment to ``.npz``, ``.obj`` or USD (``.usda``, ``.usd``, ``.usdc``), atomically.

    ``.npz``: ``points`` (N, 3) placed, ``rest`` (N, 2), ``panel`` (N,), ``panel_names``,
    ``shapes``, ``quads``, ``triangles``, ``stitches`` (S, 2), ``stitch_id`` (S,),
    ``spring_pairs``, ``spring_kind``, ``spring_kinds``, ``spring_rest_length``, ``masses`` (kg,
    with ``density``), ``length_unit`` (mm), ``up_axis`` (Y), ``info`` (JSON); with ``seams="weld"``
    also ``weld_map`` (N,), ``welded_points``, ``welded_quads``, ``welded_triangles``.
    ``.obj``: one group per panel, ``vt`` the rest coordinates (mm) of every grid node as seen from
    the faces' front side (:attr:`Garment.face_rest`: a flipped panel's ``x`` negated); with
    ``seams="weld"`` the welded vertices (faces still carry each panel's own ``vt``).
    USD: :func:`clothgrid.garment_usd.write_garment_usd` (needs ``usd-core``).
    """
    from .writers import atomic_write, info_json, savez

    if seams not in ("keep", "weld"):
        raise InputError(f"seams must be 'keep' or 'weld', not {seams!r}")
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        sp = g.springs()
        arrays: dict[str, Any] = {
            "points": g.points, "rest": g.rest, "panel": g.panel, "panel_names": np.asarray(g.panel_names),
            "shapes": np.asarray(g.shapes, dtype=np.int64), "quads": g.quads, "face_panel": g.face_panel,
            "triangles": g.triangles, "stitches": g.stitches, "stitch_id": g.stitch_id,
            "spring_pairs": sp["pairs"], "spring_kind": sp["kind"], "spring_axis": sp["axis"],
            "spring_rest_length": sp["rest_length"], "spring_kinds": np.asarray(GARMENT_SPRING_KINDS),
            "length_unit": np.asarray("mm"), "up_axis": np.asarray("Y"), "info": np.asarray(info_json(g.info)),
        }
        if density is not None:
            arrays["masses"] = g.masses(density)
        if seams == "weld":
            w = g.welded()
            arrays.update(weld_map=w["map"], welded_points=w["points"], welded_quads=w["quads"],
                          welded_triangles=w["triangles"])
        with atomic_write(path) as fh:
            savez(fh, **arrays)
        return path
    if suffix == ".obj":
        lines = [f"# clothgrid garment: {len(g.panel_names)} panels, {len(g.stitches)} stitched node pairs; "
                 "mm, Y up; vt = flat pattern coordinates (mm), front side up\n"]
        if seams == "weld":
            w = g.welded()
            vmap, vpts = w["map"], w["points"]
        else:
            vmap, vpts = np.arange(len(g.points)), g.points
        lines += [f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in vpts.tolist()]
        lines += [f"vt {u:.9g} {v:.9g}\n" for u, v in g.face_rest.tolist()]
        for pi, name in enumerate(g.panel_names):
            lines.append(f"g {name}\n")
            for q in g.quads[g.face_panel == pi].tolist():
                lines.append("f " + " ".join(f"{vmap[a] + 1}/{a + 1}" for a in q) + "\n")
        with atomic_write(path) as fh:
            fh.write("".join(lines).encode("utf-8"))
        return path
    if suffix in (".usda", ".usd", ".usdc"):
        from .garment_usd import write_garment_usd

        return write_garment_usd(g, path, seams=seams)
    raise InputError(f"unknown garment output format {path.suffix or '(no extension)'!r} for {str(path)!r}: "
                     "use .npz, .obj, .usda or .usd")
