"""Node counts for a sewn garment: an integer program over the boundary segments.

Every panel's boundary is cut into segments (spec edges, or parts of them where
a grid corner or a seam's node falls inside an edge). Each segment ``s`` gets
``n_s >= 1`` grid intervals. The counts must satisfy

- **seams**: the two matched segments of every stitch get the same count (node
  for node);
- **grids**: the bottom and top sides of every panel's grid have equal totals,
  and so do the left and right sides (a structured ``nu x nv`` grid); every side
  at least 2 intervals (a grid with interior nodes);

and come as close as possible to the targets ``t_s = length_s / h`` in
relative terms: minimise ``sum_s |n_s - t_s| / max(t_s, 1)``, linearised with
one auxiliary ``d_s >= |n_s - t_s|`` per segment (interval assignment as in
CUBIT's mapped meshing). Solved by :func:`scipy.optimize.milp` (HiGHS).

When no assignment exists, :func:`solve_counts` finds a smallest set of
constraint groups (stitches, panels' opposite sides) that is infeasible on its
own, by a deletion filter (drop a group; keep it out if the rest stays
infeasible), and raises :class:`CountConflict` naming them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .errors import InputError

__all__ = ["CountProblem", "CountConflict", "solve_counts", "SHRINK_FREE"]


class CountConflict(InputError):
    """No node counts satisfy the seams and the grids: ``groups`` names the conflicting constraints."""

    def __init__(self, message: str, groups: Sequence[str] = ()) -> None:
        super().__init__(message)
        self.groups = list(groups)


@dataclass
class CountProblem:
    """The integer program's data.

    Attributes
    ----------
    targets : list of float
        Target interval count per segment (its length over the edge length).
    groups : list of (label, rows)
        Equality constraints by group (one stitch, or one panel's pair of
        opposite sides); a row is ``(plus, minus)``: segment lists with
        ``sum(n[plus]) == sum(n[minus])``.
    minimum : list of (segments, k)
        ``sum(n[segments]) >= k`` (each grid side at least 2 intervals).
    fixed : dict
        Segment -> a count it must have (a user's bound).
    shrink : float or None
        With a factor ``f``, the objective also charges ``t_s / n_s - f`` for every segment given
        fewer than ``t_s / f`` intervals (:data:`SHRINK_FREE`); None: the relative deviations alone.
    """

    targets: list[float] = field(default_factory=list)
    groups: list[tuple[str, list[tuple[list[int], list[int]]]]] = field(default_factory=list)
    minimum: list[tuple[list[int], int]] = field(default_factory=list)
    fixed: dict[int, int] = field(default_factory=dict)
    shrink: float | None = None

    def add_segment(self, target: float) -> int:
        self.targets.append(float(target))
        return len(self.targets) - 1


#: :attr:`CountProblem.shrink` as :func:`clothgrid.garment.garment` tries it: a segment may get
#: down to a quarter of its target count at the relative deviations' rate; below that every further
#: cut costs more. The relative deviations' sum alone makes cutting a long segment the cheapest way
#: to balance a grid's sides (a real pants back's 20 cm dart legs got one interval each).
SHRINK_FREE = 4.0
#: The counts at which that penalty is drawn exactly (between them, from below by its tangents).
SHRINK_POINTS = (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 40, 48, 64, 80, 96, 128, 160, 192, 256)


def _solve(problem: CountProblem, groups: Sequence[int], objective: bool, time_limit: float):
    from scipy.optimize import Bounds, LinearConstraint, milp
    from scipy.sparse import coo_matrix

    m = len(problem.targets)
    t = np.asarray(problem.targets, dtype=np.float64)
    rows, cols, vals, lo, hi = [], [], [], [], []
    r = 0

    def add(coef: dict[int, float], a: float, b: float) -> None:
        nonlocal r
        for c, v in coef.items():
            if v != 0:
                rows.append(r)
                cols.append(c)
                vals.append(v)
        lo.append(a)
        hi.append(b)
        r += 1

    for g in groups:
        for plus, minus in problem.groups[g][1]:
            coef: dict[int, float] = {}
            for s in plus:
                coef[s] = coef.get(s, 0.0) + 1.0
            for s in minus:
                coef[s] = coef.get(s, 0.0) - 1.0
            add(coef, 0.0, 0.0)
    for segs, k in problem.minimum:
        add({s: 1.0 for s in segs}, float(k), np.inf)
    n_lo = np.ones(m)
    n_hi = np.maximum(4.0 * t, t + 64.0).round() + 1
    for s, k in problem.fixed.items():
        n_lo[s] = n_hi[s] = k
    if objective:
        # d_s >= n_s - t_s and d_s >= t_s - n_s
        for s in range(m):
            add({s: 1.0, m + s: -1.0}, -np.inf, t[s])
            add({s: -1.0, m + s: -1.0}, -np.inf, -t[s])
        c = np.concatenate([np.zeros(m), 1.0 / np.maximum(t, 1.0)])
        extra = 0
        f = problem.shrink
        if f is not None:
            # e_s >= t_s / n_s - f (0 where n_s >= t_s / f), drawn by the tangents of t_s / n at the
            # counts of SHRINK_POINTS below t_s / f (convex: they meet it there, and bound it from
            # below between)
            for s in range(m):
                for k in SHRINK_POINTS:
                    if k * f >= t[s]:
                        break
                    add({s: -t[s] / (k * k), 2 * m + s: -1.0}, -np.inf, f - 2.0 * t[s] / k)
            c = np.concatenate([c, np.ones(m)])
            extra = m
        integrality = np.concatenate([np.ones(m), np.zeros(m + extra)])
        bounds = Bounds(np.concatenate([n_lo, np.zeros(m + extra)]), np.concatenate([n_hi, np.full(m + extra, np.inf)]))
        nvar = 2 * m + extra
    else:
        c = np.zeros(m)
        integrality = np.ones(m)
        bounds = Bounds(n_lo, n_hi)
        nvar = m
    A = coo_matrix((vals, (rows, cols)), shape=(r, nvar)).tocsr()
    cons = [LinearConstraint(A, np.asarray(lo), np.asarray(hi))] if r else []
    return milp(c, constraints=cons, integrality=integrality, bounds=bounds,
                options={"time_limit": time_limit, "disp": False})


def solve_counts(problem: CountProblem, *, time_limit: float = 30.0) -> tuple[np.ndarray, dict]:
    """The interval count of every segment; raises :class:`CountConflict` if none exists.

    Returns
    -------
    counts : numpy.ndarray
        ``(m,)`` int64, at least 1 each.
    info : dict
        ``seconds``, ``objective`` (sum of relative deviations), ``segments``,
        ``constraints`` (equalities), ``max_rel_dev``.
    """
    t0 = time.perf_counter()
    m = len(problem.targets)
    if m == 0:
        raise InputError("no boundary segments to count")
    every = list(range(len(problem.groups)))
    res = _solve(problem, every, True, time_limit)
    if res.status == 0 and res.x is not None:
        n = np.rint(res.x[:m]).astype(np.int64)
        t = np.asarray(problem.targets)
        info = {"seconds": time.perf_counter() - t0, "objective": float(res.fun), "segments": m,
                "shrink": problem.shrink,
                "constraints": sum(len(g[1]) for g in problem.groups),
                "max_rel_dev": float(np.max(np.abs(n - t) / np.maximum(t, 1.0)))}
        return n, info
    if res.status != 2:        # not "infeasible": time limit or a solver failure
        raise InputError(f"the node-count program was not solved: {res.message}")
    # deletion filter: a smallest infeasible set of groups
    keep = list(every)
    for g in every:
        trial = [x for x in keep if x != g]
        if _solve(problem, trial, False, time_limit).status == 2:
            keep = trial
    labels = [problem.groups[g][0] for g in keep]
    raise CountConflict(
        "no node counts sew every seam node for node on structured grids: these "
        f"{len(labels)} constraints conflict (with each segment at least 1 interval and each "
        "grid side at least 2): " + "; ".join(labels), labels)
