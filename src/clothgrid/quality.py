"""Cell quality of a structured grid: folds, scaled Jacobian, aspect, angles.

A cell ``(i, j)`` has the corners ``(i, j), (i+1, j), (i+1, j+1), (i, j+1)``.
At each corner ``k`` the cross product ``(R[k+1] - R[k]) x (R[k-1] - R[k])``
(corners in quad order) must point along the piece's reference normal; a cell
with any corner pointing the other way (or degenerate) is *folded*.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import InputError
from .geometry import PLANAR_TOL, best_fit_plane, boundary_loop, cross, plane_axes, vector_area
from .grid import Grid

__all__ = ["Quality", "quality", "quality_record", "CellRecord", "sim_figures", "edge_spread", "targets_met", "TARGET_MIN_ANGLE_DEG",
           "FLOOR_MIN_ANGLE_DEG", "TARGET_EDGE_SPREAD"]

#: Largest distance of the boundary loop from its best-fit plane, relative to
#: its bounding-box diagonal, for which a 3D piece counts as planar.
#: Half width of the block of cells whose corner cross products give the local
#: normal of a cell on a curved (non-planar) piece: 2 means a 5 x 5 block.
LOCAL_RADIUS = 2
#: Cells measured at a time (whole rows of cells; temporaries of a few MB).
BLOCK_CELLS = 1 << 18


@dataclass(frozen=True, eq=False)
class Quality:
    """Quality measures of a grid's cells (see :func:`quality`).

    Attributes
    ----------
    folded : int
        Number of folded (or degenerate) cells.
    folded_cells : numpy.ndarray
        ``(K, 2)`` int64 ``(i, j)`` of the folded cells, ordered by ``i`` then ``j``.
    min_scaled_jacobian : float
        Smallest corner cross product of the two unit edge vectors, signed with
        the orientation: 1 for a square, ``<= 0`` for a folded or degenerate corner.
    max_aspect_ratio : float
        Largest ratio of a cell's longest to its shortest edge (1 for squares).
    max_orthogonality_deviation_deg : float
        Largest ``|angle - 90|`` over all cell corners, in degrees.
    edge_spread_u, edge_spread_v : float
        Longest over shortest u-edge ``R[i+1, j] - R[i, j]`` and v-edge
        ``R[i, j+1] - R[i, j]`` of the whole grid.
    """

    folded: int
    folded_cells: np.ndarray
    min_scaled_jacobian: float
    max_aspect_ratio: float
    max_orthogonality_deviation_deg: float
    edge_spread_u: float
    edge_spread_v: float

    def as_dict(self) -> dict[str, Any]:
        """The measures as plain Python numbers and lists (JSON-serialisable)."""
        return {
            "folded": int(self.folded),
            "folded_cells": np.asarray(self.folded_cells).tolist(),
            "min_scaled_jacobian": float(self.min_scaled_jacobian),
            "max_aspect_ratio": float(self.max_aspect_ratio),
            "max_orthogonality_deviation_deg": float(self.max_orthogonality_deviation_deg),
            "edge_spread_u": float(self.edge_spread_u),
            "edge_spread_v": float(self.edge_spread_v),
        }

    def table(self, max_listed: int = 5) -> str:
        """A two-column text table of the measures, ending with the folded cells.

        Parameters
        ----------
        max_listed : int
            How many folded cells to name at most.
        """
        rows = [
            ("min scaled Jacobian", f"{self.min_scaled_jacobian:.6g}"),
            ("max aspect ratio", f"{self.max_aspect_ratio:.6g}"),
            ("max orthogonality deviation", f"{self.max_orthogonality_deviation_deg:.4g} deg"),
            ("edge spread u (max/min)", f"{self.edge_spread_u:.6g}"),
            ("edge spread v (max/min)", f"{self.edge_spread_v:.6g}"),
        ]
        width = max(len(name) for name, _ in rows)
        lines = [f"{name:<{width}}  {value}" for name, value in rows]
        line = f"folded cells: {self.folded}"
        if self.folded:
            shown = ", ".join(f"({i}, {j})" for i, j in np.asarray(self.folded_cells)[:max_listed])
            more = ", ..." if self.folded > max_listed else ""
            line += f" (first at cells {shown}{more})"
        return "\n".join(lines + [line])

    def __repr__(self) -> str:
        return (f"Quality(folded={self.folded}, min_scaled_jacobian={self.min_scaled_jacobian:.4g}, "
                f"max_aspect_ratio={self.max_aspect_ratio:.4g}, "
                f"max_orthogonality_deviation_deg={self.max_orthogonality_deviation_deg:.4g})")


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors of ``(d, ...)`` component-first vectors (zero for zero vectors), and lengths."""
    length = np.sqrt(np.einsum("k...,k...->...", v, v))
    return np.divide(v, length, out=np.zeros_like(v), where=length > 0), length


def _cross(a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Cross product of ``(3, ...)`` component-first vectors."""
    return np.stack([a[1] * c[2] - a[2] * c[1], a[2] * c[0] - a[0] * c[2], a[0] * c[1] - a[1] * c[0]])


def _box_sum(a: np.ndarray, r: int) -> np.ndarray:
    """Sum of ``a`` (``(d, m, n)``) over the ``(2r+1)^2`` block around each entry, clipped."""
    for axis in (1, 2):
        pad = [(0, 0)] * 3
        pad[axis] = (1, 0)
        c = np.pad(np.cumsum(a, axis=axis), pad)          # c[k] = sum of the first k entries
        pad[axis] = (r, r)
        c = np.pad(c, pad, mode="edge")                    # c[k] -> c[clip(k - r, 0, m)]
        m = a.shape[axis]
        hi, lo = [slice(None)] * 3, [slice(None)] * 3
        hi[axis], lo[axis] = slice(2 * r + 1, 2 * r + 1 + m), slice(0, m)
        a = c[tuple(hi)] - c[tuple(lo)]
    return a


def _reference_normal(grid: Grid, normal, orientation) -> np.ndarray | None:
    """The piece's oriented unit normal, or ``None`` when it must be local per cell."""
    points = grid.points
    if normal is not None:
        n = np.asarray(normal, dtype=np.float64).reshape(3)
    elif grid.dim == 2:
        n = np.array([0.0, 0.0, 1.0])
    else:
        loop = boundary_loop(points)
        _, n, dist = best_fit_plane(loop)
        if dist > PLANAR_TOL * float(np.linalg.norm(np.ptp(loop, axis=0))):
            return None
    norm = np.linalg.norm(n)
    if not norm > 0:
        raise InputError(f"normal must be a non-zero 3-vector, not {normal!r}")
    n = n / norm
    if orientation is None:
        orientation = 1.0 if vector_area(boundary_loop(points)) @ n >= 0 else -1.0
    return n * float(np.sign(orientation) or 1.0)


def quality(grid: Grid, *, normal=None, orientation: float | None = None) -> Quality:
    """Measure the cells of ``grid``: folds, scaled Jacobian, aspect ratio, angles.

    Parameters
    ----------
    grid : Grid
        The grid; only ``points`` and ``dim`` are used.
    normal : array_like, optional
        Reference normal ``(3,)`` of the piece, overriding the detection: by
        default +z for 2D grids, the best-fit plane's normal for 3D grids whose
        boundary is planar (distance ``<= 1e-9`` x bounding-box diagonal), and
        otherwise a local normal per cell, the sum of the corner cross products
        of the cells in the 5 x 5 block around it (so an isolated fold stands
        out against the surrounding surface).
    orientation : float, optional
        +1 (or -1) when the boundary loop (bottom, right, top reversed, left
        reversed) turns counter-clockwise (clockwise) about the reference
        normal; the default takes the sign of the loop's signed area. With
        local normals it only multiplies them (default +1).

    Returns
    -------
    Quality
        Cells with a zero-length edge count as folded.
    """
    return quality_record(grid, normal=normal, orientation=orientation)[0]


def quality_record(grid: Grid, *, normal=None, orientation: float | None = None
                   ) -> tuple[Quality, CellRecord | None]:
    """:func:`quality`, and where the grid is large and planar (measured by
    :mod:`clothgrid.quality_kernels`, more than :data:`KERNEL_CELLS` cells) a
    :class:`CellRecord` of its measures block by block, which measures a copy
    of the grid with a few nodes moved again only where they are; else None."""
    R = np.asarray(grid.points, dtype=np.float64)
    nu, nv = R.shape[:2]
    if nu < 2 or nv < 2:
        nan = float("nan")
        return Quality(0, np.zeros((0, 2), np.int64), nan, nan, nan, nan, nan), None

    n = _reference_normal(grid, normal, orientation)
    local = None if n is not None else (1.0 if orientation is None else float(np.sign(orientation) or 1.0))
    basis = None if n is None else plane_axes(n)              # (2, 3), e1 x e2 = n
    if basis is not None and (nu - 1) * (nv - 1) > KERNEL_CELLS:     # one pass, no temporaries
        from .quality_kernels import new_blocks

        record = CellRecord(np.ascontiguousarray(basis), new_blocks(nu, nv))
        return record.measure(R), record
    cells, parts = _measure_blocks(R, basis, local, n is None)
    return _from_parts(cells, parts), None


class CellRecord:
    """A large planar grid's cell measures kept block by block (:func:`quality_record`; a block is
    :data:`clothgrid.quality_kernels.BLOCK` cells of a row), so that a grid with the same boundary
    and only some nodes moved is measured again only in the blocks of cells at those nodes
    (:meth:`remeasure`): the same :class:`Quality`, bit for bit, as measuring it whole."""

    def __init__(self, basis: np.ndarray, blocks: np.ndarray):
        self.basis, self.blocks = basis, blocks
        self.folded_cells = np.zeros((0, 2), np.int64)

    def measure(self, points: np.ndarray, todo: np.ndarray | None = None) -> Quality:
        """Measure the blocks marked in ``todo`` (every block by default) of ``points`` into the
        record; the whole grid's :class:`Quality`. (The folded cells are kept as a list: a cell mask
        of the whole grid lives only while it is measured.)"""
        from .grid_kernels import mask_places
        from .quality_kernels import block_figures, planar_blocks

        mu, mv = points.shape[0] - 1, points.shape[1] - 1
        folded = np.zeros((mu, mv), np.bool_)
        if todo is None:
            todo = np.ones(self.blocks.shape[:2], bool)
        else:
            folded[self.folded_cells[:, 0], self.folded_cells[:, 1]] = True     # those not measured again
        planar_blocks(np.ascontiguousarray(points, dtype=np.float64), self.basis, STRAIGHT_CORNER_SINE,
                      folded, self.blocks, todo)
        self.folded_cells = mask_places(folded)
        figures = (float(f) for f in block_figures(self.blocks))
        return _from_parts(self.folded_cells, [(None, *figures)])

    def remeasure(self, points: np.ndarray, nodes: np.ndarray) -> Quality:
        """The :class:`Quality` of ``points``, the grid measured last with only ``nodes`` (``(K,
        2)`` ``(i, j)``) moved (and its boundary kept): the blocks of the cells at those nodes
        measured again; the record is then ``points``'."""
        from .quality_kernels import BLOCK

        mu, mv = points.shape[0] - 1, points.shape[1] - 1
        todo = np.zeros(self.blocks.shape[:2], bool)
        i, j = np.asarray(nodes[:, 0]), np.asarray(nodes[:, 1])
        for di in (-1, 0):            # a node's four cells; its edges are held by the same blocks
            for dj in (-1, 0):
                todo[np.clip(i + di, 0, mu - 1), np.clip(j + dj, 0, mv - 1) // BLOCK] = True
        return self.measure(points, todo)


def _from_parts(cells: np.ndarray, parts: list[tuple]) -> Quality:
    """A :class:`Quality` from the folded cells and the blocks' figures (:func:`_measure`'s tuples)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        spread_u = np.float64(max(p[4] for p in parts)) / np.float64(min(p[5] for p in parts))
        spread_v = np.float64(max(p[6] for p in parts)) / np.float64(min(p[7] for p in parts))
    return Quality(
        folded=int(len(cells)),
        folded_cells=cells.astype(np.int64),
        min_scaled_jacobian=float(min(p[1] for p in parts)),
        max_aspect_ratio=float(max(p[2] for p in parts)),
        max_orthogonality_deviation_deg=float(max(p[3] for p in parts)),
        edge_spread_u=float(spread_u),
        edge_spread_v=float(spread_v),
    )


def _measure_blocks(R: np.ndarray, basis: np.ndarray | None, local: float | None,
                    curved: bool) -> tuple[np.ndarray, list[tuple]]:
    """:func:`_measure` over blocks of cell rows of ``R``: the folded cells' indices, and each block's tuple."""
    nu, nv = R.shape[:2]
    # Blocks of cell rows, so temporaries stay small (a 4096^2 grid in one piece took 3.9 GB);
    # curved pieces read LOCAL_RADIUS extra rows on each side for their local normals.
    step = max(1, BLOCK_CELLS // (nv - 1))
    halo = LOCAL_RADIUS if curved else 0
    parts = []
    for a in range(0, nu - 1, step):
        b = min(a + step, nu - 1)                              # cells a .. b-1
        lo, hi = max(a - halo, 0), min(b + halo, nu - 1)
        block = R[lo:hi + 1]
        if basis is None:                                     # curved piece: local normals
            X = np.ascontiguousarray(np.moveaxis(block, -1, 0))   # (3, rows, nv), component first
        else:                                                 # planar: lengths and angles are in-plane
            X = (basis @ block.reshape(-1, 3).T).reshape(2, hi + 1 - lo, nv)
        parts.append(_measure(X, a - lo, b - lo, local, first=a == 0, last=b == nu - 1))
    cells = np.concatenate([np.argwhere(p[0]) + [a, 0] for p, a in zip(parts, range(0, nu - 1, step))])
    return cells, parts


#: A grid corner's own angle counts as a fold when its sine is below minus this
#: (about 180.00000006 degrees): a corner on a straight side is a straight angle.
STRAIGHT_CORNER_SINE = 1e-9


def _measure(X: np.ndarray, a: int, b: int, local: float | None, *,
             first: bool = False, last: bool = False):
    """The measures of cell rows ``a .. b-1`` of the points block ``X`` (``(d, rows, nv)``).

    ``d = 2``: coordinates in the piece's plane. ``d = 3`` with ``local`` (+1 or
    -1): a curved piece, whose cells are checked against local normals. Returns
    the folded mask of those rows, min scaled Jacobian, max aspect ratio, max
    angle deviation, and the longest and shortest u- and v-edges. ``first`` and
    ``last`` say that the rows hold the grid's first or last row of cells: the
    angle at a grid corner (the outline's own angle there) counts as folded
    only when it is reflex beyond :data:`STRAIGHT_CORNER_SINE`, so that a corner
    on a straight side (a three-cornered piece) is a straight angle, not a fold.
    """
    raw_u, raw_v = X[:, 1:] - X[:, :-1], X[:, :, 1:] - X[:, :, :-1]
    eu, len_u = _unit(raw_u)                                  # (d, rows-1, nv) u-edges
    ev, len_v = _unit(raw_v)                                  # (d, rows, nv-1) v-edges
    n = None
    if local is not None:
        cell_sum = _cross(raw_u[:, :, :-1] + raw_u[:, :, 1:], raw_v[:, :-1] + raw_v[:, 1:])
        n, _ = _unit(_box_sum(cell_sum, LOCAL_RADIUS))        # sum of the corner crosses
        n = n[:, a:b] * local
    # Cells a .. b-1: their u-edges are rows a .. b-1 of raw_u, their v-edges rows a .. b of raw_v.
    eu, ev, len_u, len_v = eu[:, a:b], ev[:, a:b + 1], len_u[a:b], len_v[a:b + 1]
    unit = {"b": eu[:, :, :-1], "t": eu[:, :, 1:], "l": ev[:, :-1], "r": ev[:, 1:]}
    shape = (b - a, X.shape[2] - 1)
    min_sj, max_cos = np.full(shape, np.inf), np.zeros(shape)
    folded = np.zeros(shape, dtype=bool)
    # Corner k of the quad, edge pair (R[k+1]-R[k], R[k-1]-R[k]) in terms of the cell's sides:
    # 0: (b, l)  1: (r, -b)  2: (-t, -r)  3: (-l, t), whose crosses are b x l, b x r, t x r, t x l.
    # the grid corners among these cells: corner type -> (row, column) of its cell
    at = {"bl": (0, 0) if first else None, "tl": (0, -1) if first else None,
          "br": (-1, 0) if last else None, "tr": (-1, -1) if last else None}
    for one, two in ("bl", "br", "tr", "tl"):
        pa, pc = unit[one], unit[two]
        if n is None:
            sj = pa[0] * pc[1] - pa[1] * pc[0]
        else:
            sj = np.einsum("k...,k...->...", _cross(pa, pc), n)
        bad = ~(sj > 0)
        cell = at[one + two]
        if cell is not None and bad.size:
            bad[cell] = not sj[cell] > -STRAIGHT_CORNER_SINE
        folded |= bad
        np.minimum(min_sj, sj, out=min_sj)
        cos = np.einsum("k...,k...->...", pa, pc)            # |angle - 90| = asin|cos|
        np.maximum(max_cos, np.abs(cos), out=max_cos)

    lengths = np.stack([len_u[:, :-1], len_u[:, 1:], len_v[:-1], len_v[1:]])
    shortest, longest = lengths.min(axis=0), lengths.max(axis=0)
    degenerate = ~(shortest > 0)
    folded |= degenerate
    deviation = np.where(degenerate, 90.0, np.degrees(np.arcsin(np.minimum(max_cos, 1.0))))
    with np.errstate(invalid="ignore", divide="ignore"):
        aspect = np.where(degenerate, np.inf, longest / shortest)
    return (folded, float(min_sj.min()), float(aspect.max()), float(deviation.max()),
            float(len_u.max()), float(len_u.min()), float(len_v.max()), float(len_v.min()))


#: Targets of a simulation-grade grid of a real pattern piece (issue 12, docs/patterns.md).
TARGET_MIN_ANGLE_DEG = 10.0
FLOOR_MIN_ANGLE_DEG = 3.0
TARGET_EDGE_SPREAD = 4.0


def line_lengths(points: np.ndarray) -> tuple[float, float]:
    """Geometric mean lengths of a grid's u-lines (``points[:, j]``) and v-lines (``points[i, :]``)."""
    P = np.asarray(points, dtype=np.float64)
    lu = np.linalg.norm(np.diff(P, axis=0), axis=-1).sum(axis=0)
    lv = np.linalg.norm(np.diff(P, axis=1), axis=-1).sum(axis=1)
    with np.errstate(divide="ignore"):
        return float(np.exp(np.log(lu).mean())), float(np.exp(np.log(lv).mean()))


#: Grids of more cells than this take :mod:`clothgrid.quality_kernels` for :func:`sim_figures`
#: (NumPy's temporaries cost about 0.75 us a cell, 0.75-1.0 s at 1024^2; the kernel 0.06 s, but
#: importing Numba and loading it costs about 0.25 s once, more than NumPy on smaller grids).
KERNEL_CELLS = 1 << 18


def _angle_and_edge_extremes(P: np.ndarray) -> tuple[float, float, np.ndarray, float, float]:
    """:func:`clothgrid.quality_kernels.angle_and_edge_extremes` in NumPy (``(nu, nv, 3)`` nodes)."""
    c = (P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:])
    nc = (P.shape[0] - 1, P.shape[1] - 1)
    amin = np.full(nc, 180.0)
    amax = np.zeros(nc)
    # the cell's normal: the sum of its corner cross products (for the sign of each angle)
    normal = np.zeros(nc + (3,))
    crosses = [cross(c[(k + 1) % 4] - c[k], c[k - 1] - c[k]) for k in range(4)]
    for k in range(4):
        normal += crosses[k]
    corner_angle = []
    for k in range(4):
        a, b = c[(k + 1) % 4] - c[k], c[k - 1] - c[k]
        cr = np.einsum("...k,...k->...", crosses[k], normal)
        sin = np.linalg.norm(crosses[k], axis=-1) * np.sign(cr)
        ang = np.degrees(np.arctan2(sin, np.einsum("...k,...k->...", a, b)))
        ang = np.where(ang < 0, 0.0, ang)          # folded: 0
        corner_angle.append(ang)
        amin = np.minimum(amin, ang)
        amax = np.maximum(amax, ang)
    corners = np.array([corner_angle[0][0, 0], corner_angle[1][-1, 0], corner_angle[2][-1, -1],
                        corner_angle[3][0, -1]])
    if nc[0] * nc[1] > 4:
        keep = np.ones(nc, bool)
        keep[0, 0] = keep[-1, 0] = keep[0, -1] = keep[-1, -1] = False
        amin, amax = amin[keep], amax[keep]
    lo, hi = _edge_extremes(P)
    return float(amin.min()), float(amax.max()), corners, lo, hi


def _edge_extremes(P: np.ndarray) -> tuple[float, float]:
    """Shortest and longest edge of an ``(nu, nv, 3)`` grid (NumPy)."""
    eu = np.linalg.norm(np.diff(P, axis=0), axis=-1)
    ev = np.linalg.norm(np.diff(P, axis=1), axis=-1)
    return float(min(eu.min(), ev.min())), float(max(eu.max(), ev.max()))


def _xyz(points: np.ndarray) -> np.ndarray:
    """``points`` as a C-contiguous float64 ``(nu, nv, 3)`` array (``z = 0`` added to 2D points)."""
    P = np.ascontiguousarray(points, dtype=np.float64)
    if P.shape[-1] == 2:
        P = np.concatenate([P, np.zeros(P.shape[:-1] + (1,))], axis=-1)
    return P


def _spread(lo: float, hi: float) -> float:
    """Longest over shortest edge, ``inf`` where an edge has no length."""
    return hi / lo if lo > 0 else float("inf")


def edge_spread(points: np.ndarray) -> float:
    """Longest over shortest edge of a small grid (``inf`` where an edge has no length): the
    ``edge_spread`` of :func:`sim_figures` without its angles (the corner choice scores thousands
    of coarse grids)."""
    return _spread(*_edge_extremes(_xyz(points)))


def sim_figures(points: np.ndarray, edge_length: float | None = None) -> dict[str, Any]:
    """What a cloth simulator cares about, per grid: folds, angles, edge lengths.

    Parameters
    ----------
    points : numpy.ndarray
        ``(nu, nv, 3)`` nodes of a planar or curved grid.
    edge_length : float, optional
        The edge length asked for (same units), to compare the shortest edge with.

    Returns
    -------
    dict
        ``min_angle_deg`` and ``max_angle_deg`` (over all cell corners, each
        corner angle measured in the cell's own plane; the four cells at the
        grid's corners aside, where a grid corner may sit on a straight side or
        a sharp tip), ``corner_cell_angles_deg`` (the angle of each grid corner),
        ``shortest_edge``, ``longest_edge``, ``edge_spread`` (longest / shortest
        over all edges), ``shortest_vs_target`` (shortest edge / ``edge_length``).
    """
    P = _xyz(points)
    if (P.shape[0] - 1) * (P.shape[1] - 1) > KERNEL_CELLS:
        from .quality_kernels import angle_and_edge_extremes
    else:
        angle_and_edge_extremes = _angle_and_edge_extremes
    amin, amax, corners, lo, hi = angle_and_edge_extremes(P)
    grid_corners = [float(a) for a in corners]
    lo, hi = float(lo), float(hi)
    return {
        "min_angle_deg": float(amin), "max_angle_deg": float(amax),
        "corner_cell_angles_deg": grid_corners,
        "shortest_edge": lo, "longest_edge": hi,
        "edge_spread": _spread(lo, hi),
        "shortest_vs_target": (lo / float(edge_length)) if edge_length else None,
    }


def targets_met(fig: dict[str, Any], folded: int) -> list[str]:
    """The targets a grid misses (empty: all met), as short phrases."""
    miss = []
    if folded:
        miss.append(f"{folded} folded cell{'s' if folded != 1 else ''}")
    if fig["min_angle_deg"] < TARGET_MIN_ANGLE_DEG:
        miss.append(f"smallest angle {fig['min_angle_deg']:.3g} deg < {TARGET_MIN_ANGLE_DEG:g}")
    if fig["edge_spread"] > TARGET_EDGE_SPREAD:
        miss.append(f"edge spread {fig['edge_spread']:.3g} > {TARGET_EDGE_SPREAD:g}")
    return miss
