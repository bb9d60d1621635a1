"""Seams of a sewn garment: edge polylines and arc-length fractions, welding, mesh checks.

* :func:`edge_polyline` and :func:`points_at`: a spec edge sampled densely (every
  chord within ``tol`` of the curve) and points at given arc-length fractions of
  that polyline, its end points exact. Both edges of a seam put their nodes at
  the same fractions, so "node for node" holds to rounding on the sampled curves.
* :func:`propagate_splits`: a node forced inside an edge (a grid corner in the
  middle of a three-sided panel's longest edge) is carried to the edge it is sewn
  to, at the matching fraction (``1 - f`` for GarmentCode's default opposite
  directions, ``f`` for ``right_wrong``).
* :func:`weld`: union-find over the stitched node pairs: the map from grid
  nodes to welded vertices.
* :func:`mesh_report`: edges used by more than two faces, degenerate faces,
  vertices whose faces do not form one fan, and the boundary loops (the openings).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from .patterns.sampling import Bezier, Primitive, sample_bezier, sample_ellipse_arc

__all__ = ["Polyline", "edge_polyline", "points_at", "fractions_of", "propagate_splits", "weld", "mesh_report"]


@dataclass(frozen=True, eq=False)
class Polyline:
    """A part of a piece's outline, start to end: ``points`` ``(k, 2)`` in mm (already on the curve)."""

    points: np.ndarray

    @property
    def start(self) -> np.ndarray:
        return self.points[0]

    @property
    def end(self) -> np.ndarray:
        return self.points[-1]


def edge_polyline(curve: "Primitive | Polyline", tol: float) -> tuple[np.ndarray, np.ndarray]:
    """``(points (k, 2), cumulative arc length (k,))`` of a curve, start to end, chords within ``tol``.

    A :class:`Polyline` (a part of an SVG / DXF piece's outline, already sampled) is taken as it is.
    """
    if isinstance(curve, Polyline):
        pts = np.asarray(curve.points, dtype=np.float64)
    else:
        pts = sample_bezier(curve, tol) if isinstance(curve, Bezier) else sample_ellipse_arc(curve, tol)
        pts = np.vstack([pts, np.asarray(curve.end, dtype=np.float64)[None]])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    return pts, s


def points_at(poly: tuple[np.ndarray, np.ndarray], fractions: np.ndarray) -> np.ndarray:
    """Points at arc-length ``fractions`` (0 start, 1 end) of a polyline; the ends exact."""
    pts, s = poly
    f = np.asarray(fractions, dtype=np.float64)
    x = f * s[-1]
    out = np.column_stack([np.interp(x, s, pts[:, 0]), np.interp(x, s, pts[:, 1])])
    out[f <= 0.0] = pts[0]
    out[f >= 1.0] = pts[-1]
    return out


def fractions_of(poly: tuple[np.ndarray, np.ndarray], points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arc-length fraction of the nearest polyline point to each of ``points``, and the distance."""
    pts, s = poly
    a, b = pts[:-1], pts[1:]
    d = b - a
    dd = np.maximum((d * d).sum(1), 1e-300)
    out_f, out_d = [], []
    for p in np.asarray(points, dtype=np.float64):
        t = np.clip(((p - a) * d).sum(1) / dd, 0.0, 1.0)
        q = a + t[:, None] * d
        dist = np.hypot(*(q - p).T)
        k = int(np.argmin(dist))
        out_f.append((s[k] + t[k] * (s[k + 1] - s[k])) / s[-1])
        out_d.append(dist[k])
    return np.asarray(out_f), np.asarray(out_d)


def propagate_splits(splits: dict, stitches: Iterable) -> dict:
    """Carry split fractions across stitches until nothing changes.

    ``splits`` maps ``(panel, edge)`` to a set of fractions in ``(0, 1)`` (in the
    edge's own direction); each stitch has ``a``, ``b`` and ``same_direction``.
    """
    stitches = list(stitches)
    for _ in range(len(stitches) + 1):
        changed = False
        for st in stitches:
            fa, fb = splits.setdefault(st.a, set()), splits.setdefault(st.b, set())
            conv = (lambda f: f) if st.same_direction else (lambda f: 1.0 - f)
            for src, dst in ((fa, fb), (fb, fa)):
                for f in list(src):
                    g = conv(f)
                    if not any(abs(g - x) <= 1e-12 for x in dst):
                        dst.add(g)
                        changed = True
        if not changed:
            break
    return splits


def weld(n: int, pairs: np.ndarray) -> np.ndarray:
    """``(n,)`` welded vertex of every node, numbered by first appearance, after merging ``pairs``."""
    parent = np.arange(n)

    def find(x: int) -> int:
        root = x
        while parent[root] != root:
            root = parent[root]
        while parent[x] != root:
            parent[x], x = root, parent[x]
        return root

    for a, b in np.asarray(pairs, dtype=np.int64).reshape(-1, 2):
        ra, rb = find(int(a)), find(int(b))
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([find(i) for i in range(n)])
    _, first, inverse = np.unique(roots, return_index=True, return_inverse=True)
    order = np.argsort(np.argsort(first))          # number welded vertices by their first node
    return order[inverse].astype(np.int64)


def mesh_report(faces: np.ndarray, n_vertices: int) -> dict:
    """Manifold checks of a polygon mesh (faces ``(F, k)``) and its boundary loops.

    Returns ``degenerate`` (faces with a repeated vertex), ``nonmanifold_edges``
    (used by more than two faces), ``nonmanifold_vertices`` (whose faces are not
    one fan), ``boundary_loops`` (lists of vertices), ``oriented`` (every inner
    edge used once in each direction) and ``euler`` (V - E + F).
    """
    f = np.asarray(faces, dtype=np.int64)
    k = f.shape[1]
    degenerate = int(sum(len(set(row)) < k for row in f.tolist()))
    a = f.reshape(-1)
    b = np.roll(f, -1, axis=1).reshape(-1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * n_vertices + hi
    uniq, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    nonmanifold_edges = int((cnt > 2).sum())
    # orientation: an inner edge is used once as (lo, hi) and once as (hi, lo)
    fwd = np.bincount(inv, weights=(a < b).astype(float), minlength=len(uniq))
    oriented = bool(np.all((cnt != 2) | (fwd == 1)))
    # boundary loops from the directed boundary half-edges
    bmask = cnt[inv] == 1
    nxt: dict[int, list[int]] = {}
    for u, v in zip(a[bmask].tolist(), b[bmask].tolist()):
        nxt.setdefault(u, []).append(v)
    loops: list[list[int]] = []
    used: set[tuple[int, int]] = set()
    for u0, vs in nxt.items():
        for v0 in vs:
            if (u0, v0) in used:
                continue
            loop = [u0]
            u, v = u0, v0
            while (u, v) not in used:
                used.add((u, v))
                if v == u0:
                    break
                loop.append(v)
                cand = [w for w in nxt.get(v, []) if (v, w) not in used]
                if not cand:
                    break
                u, v = v, cand[0]
            loops.append(loop)
    # vertex fans: the faces around each vertex connected through edges at that vertex
    nonmanifold_vertices = 0
    incident: dict[int, list[int]] = {}
    for fi, row in enumerate(f.tolist()):
        for x in set(row):
            incident.setdefault(x, []).append(fi)
    edge_faces: dict[int, list[int]] = {}
    for e, fi in zip(inv.tolist(), np.repeat(np.arange(len(f)), k).tolist()):
        edge_faces.setdefault(e, []).append(fi)
    inv2 = inv.reshape(len(f), k)
    for vtx, fl in incident.items():
        if len(fl) == 1:
            continue
        fs = set(fl)
        seen = {fl[0]}
        stack = [fl[0]]
        while stack:
            fi = stack.pop()
            row = f[fi]
            for j in range(k):
                if row[j] == vtx or row[(j + 1) % k] == vtx:
                    for g in edge_faces[int(inv2[fi, j])]:
                        if g in fs and g not in seen:
                            seen.add(g)
                            stack.append(g)
        if len(seen) != len(fs):
            nonmanifold_vertices += 1
    n_used = len(incident)
    return {"degenerate": degenerate, "nonmanifold_edges": nonmanifold_edges,
            "nonmanifold_vertices": nonmanifold_vertices, "boundary_loops": loops,
            "oriented": oriented, "euler": n_used - len(uniq) + len(f)}


def ordered_pairs(a_nodes: Sequence[int], b_nodes: Sequence[int], same_direction: bool) -> np.ndarray:
    """Node pairs of a seam, ordered along edge ``a``: ``a``'s end meets ``b``'s start by default."""
    a = np.asarray(a_nodes, dtype=np.int64)
    b = np.asarray(b_nodes, dtype=np.int64)
    return np.column_stack([a, b if same_direction else b[::-1]])
