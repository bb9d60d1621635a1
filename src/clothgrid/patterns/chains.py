"""Open curves joined end to end into closed loops (DXF entities, SVG open paths).

The joiner takes chains of primitives (:mod:`clothgrid.patterns.sampling`) and
uses each whole, forwards or reversed; ends within a tolerance meet. Ends are
hashed into cells of the tolerance's size, so thousands of shuffled segments
join in near-linear time.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from .sampling import Bezier, EllipseArc, Primitive

__all__ = ["chain_loops", "outer_loops", "join_outlines", "Joined", "joined_note", "largest_gap", "reverse", "GAP_MM",
           "GAP_REL"]

#: Open lines and curves left over once those whose ends meet are joined are tried again with
#: their ends this far apart (in mm): a block drawn by hand in Adobe Illustrator as separate lines
#: and curves has its ends 0.1-0.4 mm apart (BCSizing's sleeve and bodice blocks), less than a
#: line's width on paper.
GAP_MM = 1.0
#: ... but at most this share of the drawing's extent (a small drawing's ends are not bridged
#: across it)
GAP_REL = 0.01


def reverse(p: Primitive) -> Primitive:
    """The primitive run the other way."""
    if isinstance(p, Bezier):
        return Bezier(p.ctrl[::-1].copy(), None if p.weights is None else p.weights[::-1].copy())
    return EllipseArc(p.center, p.a, p.b, p.t1, p.t0, p.end_point, p.start_point)


def chain_loops(pieces: list[list[Primitive]], tol: float, members: list[list[int]] | None = None
                ) -> tuple[list[list[Primitive]], int]:
    """Join open chains end to end; the closed loops and the number of chains left open.

    Each chain of ``pieces`` is used whole, forwards or reversed. Chains are taken in file
    order; each is extended at its end by the unused chain with an end nearest to it (within
    ``tol``; the last in file order on ties; reversed when its end is the nearer) until it
    closes or nothing is near. With a list ``members``, the indices into ``pieces`` of the
    chains each loop is made of are appended to it (one list per loop, in the loop's order).

    The ends are hashed into cells of size ``tol`` (near-linear time: 20,000 shuffled LINEs
    join in well under a second); an infinite ``tol`` (join whatever is nearest, for the few
    chains of one AAMA block) puts every end in one cell, a search over all of them.
    """
    index = [k for k, p in enumerate(pieces) if p]
    open_ = [list(pieces[k]) for k in index]
    n = len(open_)
    if n == 0:
        return [], 0
    ends = np.array([[p[0].start, p[-1].end] for p in open_], dtype=np.float64)   # (n, 2, 2)
    finite = math.isfinite(tol)
    origin = ends.reshape(-1, 2).min(axis=0)
    table: dict[tuple[Any, Any], list[int]] = {}

    def key(point: np.ndarray) -> tuple[Any, Any]:
        if not finite:
            return 0, 0
        if tol > 0:
            return tuple(int(v) for v in np.floor((point - origin) / tol))
        return float(point[0]), float(point[1])            # tol 0: ends that coincide

    for k in range(n):
        for side in (0, 1):
            table.setdefault(key(ends[k, side]), []).append(k)
    used = [False] * n

    def nearest(point: np.ndarray) -> tuple[int, bool]:
        """The unused chain with an end nearest ``point`` (within tol), and whether it must be
        reversed (its end is the nearer; its start wins ties)."""
        cx, cy = key(point)
        if finite and tol > 0:
            cand = [c for dx in (-1, 0, 1) for dy in (-1, 0, 1) for c in table.get((cx + dx, cy + dy), ())]
        else:
            cand = table.get((cx, cy), [])
        best, best_d, flip = -1, tol, False
        for k in sorted({k for k in cand if not used[k]}):
            d0 = float(np.linalg.norm(ends[k, 0] - point))
            d1 = float(np.linalg.norm(ends[k, 1] - point))
            if d0 <= best_d:
                best, best_d, flip = k, d0, False
            if d1 <= best_d and d1 < d0:
                best, best_d, flip = k, d1, True
        return best, flip

    loops: list[list[Primitive]] = []
    left_open = 0
    for first in range(n):
        if used[first]:
            continue
        used[first] = True
        chain, mem = open_[first], [first]
        start = chain[0].start
        while True:
            end = chain[-1].end
            if len(chain) > 1 and np.linalg.norm(end - start) <= tol:
                break
            best, flip = nearest(end)
            if best < 0:
                if not np.linalg.norm(end - start) <= tol:
                    left_open += 1
                    mem = []
                break
            used[best] = True
            mem.append(best)
            nxt = open_[best]
            chain += [reverse(p) for p in reversed(nxt)] if flip else nxt
        if mem:
            loops.append(chain)
            if members is not None:
                members.append([index[k] for k in mem])
    return loops, left_open


def _at(p: Primitive, s: float) -> np.ndarray:
    """The point of ``p`` a fraction ``s`` of its parameter range along."""
    if isinstance(p, Bezier):
        return p.points(np.array([s]))[0]
    return p.points(np.array([p.t0 + s * (p.t1 - p.t0)]))[0]


#: how far along a chain's first (last) primitive :func:`outer_loops` looks for the direction in
#: which it leaves (enters) a fork: a short secant, so that curves leaving a point apart are told
#: apart by where they go, not by a distant bend
_LEAVE = 0.05


def outer_loops(pieces: list[list[Primitive]], tol: float
                ) -> list[tuple[list[Primitive], list[int], list[int]]]:
    """The outlines around chains that meet end to end but fork: where three or more chain ends
    meet at a point (a waist line drawn across a panel drawn as separate edges), a closed chain
    through the point is ambiguous, but the boundary of what the chains enclose is not.

    Ends within ``tol`` are one node. Chains with an end no other chain meets are left out,
    repeatedly (lines that only touch the outline). In each connected set of the rest that has a
    node where more than two chain ends met (before any was left out: a construction line drawn
    from a corner of the outline to the middle of a side leaves a plain loop), the faces of the
    drawing are traced (at each node the chains in the order of the directions they leave it in)
    and the one of largest area, the outer boundary, is returned: ``(its primitives in order, the
    chains it runs along, the chains of that set inside it)``. Sets that never forked are
    :func:`chain_loops`'; so are self-crossing drawings, for which no face is trustworthy: a set
    whose outer boundary runs along a chain twice is left out.
    """
    n = len(pieces)
    if n < 3 or not tol > 0:
        return []
    ends = np.array([[p[0].start, p[-1].end] for p in pieces], dtype=np.float64).reshape(-1, 2)
    # nodes: ends within tol, joined (union-find over the hashed cells around each end)
    parent = list(range(2 * n))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    cells: dict[tuple[int, int], list[int]] = {}
    keys = np.floor(ends / tol).astype(np.int64)
    for e in range(2 * n):
        cx, cy = int(keys[e, 0]), int(keys[e, 1])
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for f in cells.get((cx + dx, cy + dy), ()):
                    if np.hypot(*(ends[e] - ends[f])) <= tol:
                        parent[find(e)] = find(f)
        cells.setdefault((cx, cy), []).append(e)
    node = [find(e) for e in range(2 * n)]
    alive = [node[2 * k] != node[2 * k + 1] for k in range(n)]       # a chain from a point to itself: a loop
    # chains with a free end are left out, again and again
    forked: set[int] = set()        # nodes where more than two chain ends meet, before any is left out
    while True:
        degree: dict[int, int] = {}
        for k in range(n):
            if alive[k]:
                for v in (node[2 * k], node[2 * k + 1]):
                    degree[v] = degree.get(v, 0) + 1
        if not forked:
            forked = {v for v, d in degree.items() if d > 2}
        free = [k for k in range(n) if alive[k] and (degree[node[2 * k]] < 2 or degree[node[2 * k + 1]] < 2)]
        if not free:
            break
        for k in free:
            alive[k] = False
    # connected sets of the chains left
    comp = {v: v for v in degree}

    def root(v: int) -> int:
        while comp[v] != v:
            comp[v] = comp[comp[v]]
            v = comp[v]
        return v

    for k in range(n):
        if alive[k]:
            comp[root(node[2 * k])] = root(node[2 * k + 1])
    sets: dict[int, list[int]] = {}
    for k in range(n):
        if alive[k]:
            sets.setdefault(root(node[2 * k]), []).append(k)
    out = []
    for members in sets.values():
        if not any(node[2 * k + s] in forked for k in members for s in (0, 1)):
            continue                                  # never a fork: chain_loops' case
        # half-edges (k, forward): leaving node[2k] forwards, or node[2k+1] backwards
        around: dict[int, list[tuple[float, int, bool]]] = {}
        for k in members:
            for forward in (True, False):
                v = node[2 * k] if forward else node[2 * k + 1]
                p = pieces[k][0] if forward else pieces[k][-1]
                here = p.start if forward else p.end
                there = _at(p, _LEAVE if forward else 1.0 - _LEAVE)
                around.setdefault(v, []).append((math.atan2(there[1] - here[1], there[0] - here[0]), k, forward))
        place: dict[tuple[int, bool], int] = {}
        for v in around:
            around[v].sort()
            for i, (_, k2, f2) in enumerate(around[v]):
                place[(k2, f2)] = i
        faces = []
        seen: set[tuple[int, bool]] = set()
        for k in members:
            for forward in (True, False):
                if (k, forward) in seen:
                    continue
                face = []
                h = (k, forward)
                while h not in seen and len(face) <= 2 * len(members):
                    seen.add(h)
                    face.append(h)
                    kk, fw = h
                    v = node[2 * kk + 1] if fw else node[2 * kk]          # where it arrives
                    ring = around[v]
                    back = place[(kk, not fw)]
                    _, k3, f3 = ring[(back - 1) % len(ring)]        # the next one clockwise
                    h = (k3, f3)
                faces.append(face)
        best, best_area = None, 0.0
        for face in faces:
            pts = []            # the primitives' ends (curves by their chords: enough to pick the largest)
            for k, fw in face:
                pts.extend(p.start for p in pieces[k]) if fw else pts.extend(p.end for p in reversed(pieces[k]))
            xy = np.array(pts)
            area = 0.5 * float(np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1]))
            if abs(area) > abs(best_area):
                best, best_area = face, area
        if best is None or len({k for k, _ in best}) != len(best):
            continue                                  # along a chain twice: not a simple outline
        prims: list[Primitive] = []
        for k, fw in best:
            prims += list(pieces[k]) if fw else [reverse(p) for p in reversed(pieces[k])]
        used = [k for k, _ in best]
        out.append((prims, used, sorted(set(members) - set(used))))
    return out


def _joined_at(pieces: list[list[Primitive]], tol: float) -> list[tuple[list[Primitive], list[int], list[int]]]:
    """:func:`join_outlines`' outlines with ends within ``tol`` meeting: :func:`chain_loops`' loops
    that pass no fork, then :func:`outer_loops` of the chains left."""
    ends = np.array([[p[0].start, p[-1].end] for p in pieces])     # (n, 2, 2)
    # a point where more than two chain ends meet is a fork: which way an outline goes there is
    # a guess, so chain_loops joins no outline through one
    keys = np.floor(ends / tol).astype(np.int64).reshape(-1, 2)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    fork = (counts[inverse.ravel()] > 2).reshape(-1, 2).any(axis=1)
    members: list[list[int]] = []
    out = []
    loops, _ = chain_loops(pieces, tol, members)
    for prims, mem in zip(loops, members):
        if len(mem) < 2 or fork[mem].any():
            continue
        out.append((prims, mem, []))
    used = {k for _, mem, _ in out for k in mem}
    rest = [k for k in range(len(pieces)) if k not in used]
    for prims, mem, inner in outer_loops([pieces[k] for k in rest], tol):
        out.append((prims, [rest[k] for k in mem], [rest[k] for k in inner]))
    return out


class Joined(NamedTuple):
    """An outline :func:`join_outlines` made."""

    prims: list[Primitive]
    members: list[int]        # the chains it runs along, in order
    inner: list[int]          # the chains inside it
    bridged: bool             # made only with ends up to ``gap`` apart (the second pass, or a chain closed on itself)
    crossed: int = 0          # straight lines that cross near their ends, cut at the crossings (:func:`_noded`)


#: Straight lines left over that cross near their ends (a corner drafted with overshooting lines) are
#: cut where they cross: a crossing counts where it lies within this share of each line's length of
#: one of its ends (and within :data:`CROSS_REACH_MM`): lines of a grid or a table that cross in
#: their middles are left alone.
CROSS_REACH = 0.2
#: ... and within this many millimetres (the drawing's units scaled by the caller's ``mm``)
CROSS_REACH_MM = 20.0
#: Chains left over beyond this many (lettering or hatching drawn as lines) are not cut at their
#: crossings: a piece drafted with overshooting lines has tens to hundreds.
NODED_MAX_CHAINS = 5000


def _straight(p: Primitive) -> bool:
    """Whether ``p`` is a straight line parametrised linearly (a Bézier of two unweighted points)."""
    return isinstance(p, Bezier) and len(p.ctrl) == 2 and p.weights is None


def _noded(pieces: list[list[Primitive]], rest: list[int], tol: float, reach: float
           ) -> tuple[list[list[Primitive]], list[int], np.ndarray] | None:
    """The chains ``rest`` of ``pieces`` as one-primitive chains, their straight lines (Béziers of
    two control points) cut where two cross near an end of each (within ``reach`` and
    :data:`CROSS_REACH` of each line's length; ``tol`` of slack at the lines' ends): ``(chains, the
    index in pieces each came from, the crossing points (k, 2))``, or None where no two lines cross so."""
    prims: list[Primitive] = []
    origin: list[int] = []
    for k in rest:
        for p in pieces[k]:
            prims.append(p)
            origin.append(k)
    lines = np.array([i for i, p in enumerate(prims) if _straight(p)], dtype=np.int64)
    if not len(lines):
        return None
    from ..geometry import candidate_pairs

    a = np.array([prims[i].start for i in lines])
    b = np.array([prims[i].end for i in lines])
    length = np.hypot(*(b - a).T)
    lo, hi = np.minimum(a, b) - tol, np.maximum(a, b) + tol
    cuts: dict[int, list[tuple[float, np.ndarray]]] = {}   # line: (parameter, the point) where it is cut
    snaps: dict[tuple[int, bool], np.ndarray] = {}     # (line, its end (True) or start): the crossing
    points: list[np.ndarray] = []
    # a curve's end on a line near the line's end (an overshoot past where a curve begins): the line is
    # cut at that end itself
    ends = np.array([p.start if s == 0 else p.end for k in rest for s, p in ((0, pieces[k][0]), (1, pieces[k][-1]))
                     if not _straight(p)]).reshape(-1, 2)
    if len(ends):
        nl = len(lines)
        box_lo = np.concatenate([lo, ends - tol])
        box_hi = np.concatenate([hi, ends + tol])
        for i, e in candidate_pairs(box_lo, box_hi):
            pick = (i < nl) & (e >= nl)
            i, e = i[pick], e[pick] - nl
            r = b[i] - a[i]
            t = np.einsum("ij,ij->i", ends[e] - a[i], r) / np.maximum(length[i] ** 2, np.finfo(float).tiny)
            dist = np.hypot(*(a[i] + t[:, None] * r - ends[e]).T)
            with np.errstate(divide="ignore", invalid="ignore"):
                ti = tol / length[i]
                ri = np.minimum(CROSS_REACH, reach / length[i])
            hit = np.flatnonzero((dist <= tol) & (t > ti) & (t < 1 - ti) & (np.minimum(t, 1 - t) <= ri))
            for h in hit:
                cuts.setdefault(int(i[h]), []).append((float(t[h]), ends[e[h]]))
                points.append(ends[e[h]])
    for i, j in candidate_pairs(lo, hi) if len(lines) >= 2 else ():
        r, s = b[i] - a[i], b[j] - a[j]
        qp = a[j] - a[i]
        den = r[:, 0] * s[:, 1] - r[:, 1] * s[:, 0]
        ok = np.abs(den) > 1e-12 * length[i] * length[j]
        den = np.where(ok, den, 1.0)
        t = (qp[:, 0] * s[:, 1] - qp[:, 1] * s[:, 0]) / den
        u = (qp[:, 0] * r[:, 1] - qp[:, 1] * r[:, 0]) / den
        with np.errstate(divide="ignore", invalid="ignore"):
            ti, ui = tol / length[i], tol / length[j]
            ri = np.minimum(CROSS_REACH, reach / length[i])
            rj = np.minimum(CROSS_REACH, reach / length[j])
        on = ok & (t >= -ti) & (t <= 1 + ti) & (u >= -ui) & (u <= 1 + ui)
        t_in, u_in = (t > ti) & (t < 1 - ti), (u > ui) & (u < 1 - ui)
        near = (np.minimum(t, 1 - t) <= ri) & (np.minimum(u, 1 - u) <= rj)
        hit = np.flatnonzero(on & (t_in | u_in) & near)
        for h in hit:
            x = a[i[h]] + t[h] * r[h]
            for line, par, inside in ((int(i[h]), float(t[h]), t_in[h]), (int(j[h]), float(u[h]), u_in[h])):
                if inside:
                    cuts.setdefault(line, []).append((par, x))
                else:                      # an end within tol of the crossing: moved onto it
                    snaps[(line, par > 0.5)] = x
            points.append(x)
    if not points:
        return None
    out: list[list[Primitive]] = []
    came: list[int] = []
    cut_of = {int(lines[m]): ts for m, ts in cuts.items()}
    snap_of = {(int(lines[m]), end): x for (m, end), x in snaps.items()}
    for idx, p in enumerate(prims):
        ts = cut_of.get(idx, [])
        s0, s1 = snap_of.get((idx, False)), snap_of.get((idx, True))
        if not ts and s0 is None and s1 is None:
            out.append([p])
            came.append(origin[idx])
            continue
        pts = [p.start if s0 is None else s0, *(x for _, x in sorted(ts, key=lambda c: c[0])),
               p.end if s1 is None else s1]
        for q0, q1 in zip(pts, pts[1:]):
            if np.hypot(*(q1 - q0)) > 0:
                out.append([Bezier(np.array([q0, q1]))])
                came.append(origin[idx])
    return out, came, np.array(points)


def join_outlines(pieces: list[list[Primitive]], tol: float, gap: float = 0.0, mm: float | None = None
                  ) -> list[Joined]:
    """Closed outlines of open chains (each non-empty, finite ends) that meet end to end, a
    :class:`Joined` each.

    Chains whose ends are within ``tol`` meet. A chain of them that closes without passing a fork
    (more than two chain ends at a point) is an outline (:func:`chain_loops`); where chains fork, the
    outline is the boundary around them (:func:`outer_loops`), and the chains inside it are inner
    lines. Where chains are left over and ``gap > tol``, all are joined again with ends up to
    ``gap`` apart (a drawing made by hand, its ends a fraction of a millimetre apart): an outline
    found so takes the place of those found before whose chains it runs along or encloses (a
    sleeve's lower part, which its elbow line closes exactly, in the whole sleeve), and is dropped
    where it takes only part of one, or none of the chains left over. Last, a chain left whose own
    end is within ``gap`` (and 1 % of its size) of its start is an outline of its own: drawn by hand,
    it stops short of where it began. Where ``mm`` (the drawing's units in millimetres) is given,
    the straight lines of the chains still left that cross near their ends (a corner drafted with
    overshooting lines: :data:`CROSS_REACH`, :data:`CROSS_REACH_MM`) are cut at the crossings and
    joined again; the parts past the crossings, which meet nothing, are left out
    (``Joined.crossed``).
    """
    found = [Joined(*f, False) for f in _joined_at(pieces, tol)] if len(pieces) >= 2 else []
    owner = {k: i for i, f in enumerate(found) for k in f.members + f.inner}   # chain -> outline
    if gap > tol and len(pieces) - len(owner) >= 2:
        alive = [True] * len(found)
        for prims, mem, inner in _joined_at(pieces, gap):
            takes = set(mem + inner)
            if all(k in owner for k in mem):
                continue                      # nothing left over: found before
            touched = {owner[k] for k in takes if k in owner}
            if any(set(found[i].members + found[i].inner) - takes for i in touched):
                continue                      # part of an outline found before
            for i in touched:
                alive[i] = False
            found.append(Joined(prims, mem, inner, True))
            alive.append(True)
            owner.update((k, len(found) - 1) for k in takes)
        found = [f for f, a in zip(found, alive) if a]
    if gap > tol:                             # a chain left whose own ends are that close: drawn closed
        found += [Joined(c, [k], [], True) for k, c in enumerate(pieces) if k not in owner and _nearly_closed(c, gap)]
    taken = {k for f in found for k in f.members + f.inner}
    rest = [k for k in range(len(pieces)) if k not in taken]
    if mm is not None and 1 <= len(rest) <= NODED_MAX_CHAINS:     # lines that cross near their ends: cut there
        noded = _noded(pieces, rest, max(tol, gap), CROSS_REACH_MM / mm)
        if noded is not None:
            sub, came, cut_at = noded
            for prims, mem, inner in _joined_at(sub, tol) if len(sub) >= 2 else []:
                members = list(dict.fromkeys(came[m] for m in mem))
                inside = [k for k in dict.fromkeys(came[m] for m in inner) if k not in members]
                starts = np.array([p.start for p in prims])
                crossed = sum(bool((np.hypot(*(starts - c).T) <= tol).any()) for c in cut_at)
                found.append(Joined(prims, members, inside, False, crossed))
    return found


def joined_note(outline: Joined, gap: float, noun: tuple[str, str], names: str = "", inner_names: str = "") -> str:
    """The note on a piece made of a :class:`Joined` outline: how many chains (``noun``: one, many;
    ``names``, ``inner_names`` listed where given), across what gaps (``gap``, its largest, in mm)."""
    if len(outline.members) == 1 and not outline.crossed:
        return f"an {noun[0]} whose ends are {gap:.3g} mm apart, taken as closed"
    listed = f" ({names})" if names else ""
    k = len(outline.inner)
    around = (f"; around {k} inner line{'s' if k != 1 else ''}" + (f" ({inner_names})" if inner_names else "")
              if k else "")
    if outline.crossed:
        how = (f"whose lines cross near their ends ({outline.crossed} crossing{'s' if outline.crossed != 1 else ''}):"
               " cut there, the ends past the crossings left out")
    else:
        how = "that meet end to end" + (f", across gaps of up to {gap:.3g} mm" if outline.bridged else "")
    many = noun[1] if len(outline.members) != 1 else noun[0]
    return f"joined from {len(outline.members)} {many}{listed} {how}{around}"


def _nearly_closed(chain: list[Primitive], gap: float) -> bool:
    """Whether a chain's end is within ``gap`` of its start and within 1 % of its extent, around an
    area (its control points' polygon at least 1 % of its extent squared): an outline drawn
    by hand that stops short of its start, not a line drawn back on itself."""
    pts = np.concatenate([np.asarray(p.ctrl)[:, :2] if isinstance(p, Bezier)
                          else p.points(np.linspace(p.t0, p.t1, 9))[:, :2] for p in chain])
    extent = float(np.hypot(*np.ptp(pts, axis=0)))
    d = float(np.linalg.norm(chain[-1].end - chain[0].start))
    if not (np.isfinite(extent) and extent > 0 and d <= min(gap, 0.01 * extent)):
        return False
    x, y = pts[:, 0], pts[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))
    return area >= 0.01 * extent * extent


def largest_gap(prims: list[Primitive]) -> float:
    """The largest distance from a primitive's end to the next one's start, around the loop."""
    ends = np.array([p.end for p in prims])
    starts = np.array([p.start for p in prims[1:]] + [prims[0].start])
    return float(np.max(np.hypot(*(ends - starts).T)))
