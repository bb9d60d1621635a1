"""Open curves joined end to end into closed loops (DXF entities, SVG open paths).

The joiner takes chains of primitives (:mod:`clothgrid.patterns.sampling`) and
uses each whole, forwards or reversed; ends within a tolerance meet. Ends are
hashed into cells of the tolerance's size, so thousands of shuffled segments
join in near-linear time.
"""

from __future__ import annotations

import math

import numpy as np

from .sampling import Bezier, EllipseArc, Primitive

__all__ = ["chain_loops", "reverse"]


def reverse(p: Primitive) -> Primitive:
    """The primitive run the other way."""
    if isinstance(p, Bezier):
        return Bezier(p.ctrl[::-1].copy(), None if p.weights is None else p.weights[::-1].copy())
    return EllipseArc(p.center, p.a, p.b, p.t1, p.t0, p.end_point, p.start_point)


def chain_loops(pieces: list[list[Primitive]], tol: float, members: list[list[int]] | None = None
                ) -> tuple[list[list[Primitive]], int]:
    """Join open chains end to end; the closed loops and the number of chains left open.

    Each chain of ``pieces`` is used whole, forwards or reversed. With a list
    ``members``, the indices into ``pieces`` of the chains each loop is made
    of are appended to it (one list per loop, in the loop's order).

    The ends are hashed into cells of size ``tol`` (near-linear time: 20,000 shuffled LINEs
    join in well under a second); an infinite ``tol`` (join whatever is nearest) takes the
    pairwise search, for the few chains of one AAMA block.
    """
    index = [k for k, p in enumerate(pieces) if p]
    used: list[list[int]] = []
    if not math.isfinite(tol) or len(index) < 64:
        loops, left = _chain_pairwise(pieces, tol, used)
    else:
        loops, left = _chain_hashed(pieces, tol, used)
    if members is not None:
        members.extend([index[k] for k in m] for m in used)
    return loops, left


def _chain_hashed(pieces: list[list[Primitive]], tol: float, members: list[list[int]]
                  ) -> tuple[list[list[Primitive]], int]:
    open_ = [list(p) for p in pieces if p]
    n = len(open_)
    ends = np.array([[p[0].start, p[-1].end] for p in open_], dtype=np.float64)   # (n, 2, 2)
    cell = tol if tol > 0 else 1.0
    origin = ends.reshape(-1, 2).min(axis=0)
    keys = np.floor((ends - origin) / cell).astype(np.int64) if tol > 0 else None
    table: dict[tuple[int, int], list[tuple[int, int]]] = {}
    if tol > 0:
        for k in range(n):
            for side in (0, 1):
                table.setdefault((int(keys[k, side, 0]), int(keys[k, side, 1])), []).append((k, side))
    else:
        for k in range(n):
            for side in (0, 1):
                table.setdefault((float(ends[k, side, 0]), float(ends[k, side, 1])), []).append((k, side))
    used = [False] * n

    def nearest(point: np.ndarray) -> tuple[int, bool]:
        """The unused chain with an end nearest ``point`` (within tol), first in file order on
        ties, and whether it must be reversed (its end is the nearer; its start wins ties)."""
        if tol > 0:
            cx, cy = (int(v) for v in np.floor((point - origin) / cell))
            cand = [c for dx in (-1, 0, 1) for dy in (-1, 0, 1) for c in table.get((cx + dx, cy + dy), ())]
        else:
            cand = list(table.get((float(point[0]), float(point[1])), ()))
        best, best_d, flip = -1, tol, False
        for k in sorted({k for k, _ in cand if not used[k]}):     # as the pairwise search does
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
                loops.append(chain)
                members.append(mem)
                break
            best, flip = nearest(end)
            if best < 0:
                if np.linalg.norm(end - start) <= tol:
                    loops.append(chain)
                    members.append(mem)
                else:
                    left_open += 1
                break
            used[best] = True
            mem.append(best)
            nxt = open_[best]
            chain += [reverse(p) for p in reversed(nxt)] if flip else nxt
    return loops, left_open


def _chain_pairwise(pieces: list[list[Primitive]], tol: float, members: list[list[int]]
                    ) -> tuple[list[list[Primitive]], int]:
    open_ = [list(p) for p in pieces if p]
    ids = list(range(len(open_)))
    loops: list[list[Primitive]] = []
    left_open = 0
    while open_:
        chain, mem = open_.pop(0), [ids.pop(0)]
        while True:
            start, end = chain[0].start, chain[-1].end
            if len(chain) > 1 and np.linalg.norm(end - start) <= tol:
                loops.append(chain)
                members.append(mem)
                break
            best, best_d, flip = -1, tol, False
            for k, other in enumerate(open_):
                d0 = float(np.linalg.norm(other[0].start - end))
                d1 = float(np.linalg.norm(other[-1].end - end))
                if d0 <= best_d:
                    best, best_d, flip = k, d0, False
                if d1 <= best_d and d1 < d0:
                    best, best_d, flip = k, d1, True
            if best < 0:
                if np.linalg.norm(end - start) <= tol:
                    loops.append(chain)
                    members.append(mem)
                else:
                    left_open += 1
                break
            nxt = open_.pop(best)
            mem.append(ids.pop(best))
            chain += [reverse(p) for p in reversed(nxt)] if flip else nxt
    return loops, left_open
