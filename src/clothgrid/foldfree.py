"""Fold-free grids on planar pieces: simultaneous untangling and smoothing.

Minimising length alone (eq. 1) can fold cells on non-convex boundaries. This
module moves the interior nodes of a planar grid to a minimum of the
regularised Winslow energy of Escobar et al. ("Simultaneous untangling and
smoothing of tetrahedral meshes", 2003), summed over the four corner triangles
of every cell. At corner ``k`` of a cell, with edges ``a = R[k+1] - R[k]`` and
``b = R[k-1] - R[k]`` (corners in quad order, coordinates in the piece's plane,
oriented so that the boundary turns counter-clockwise),

    J = a x b,    f = (|a|^2 + |b|^2) / (J + sqrt(J^2 + 4 delta^2)),

and the energy is ``E = sum f`` over all corners. For ``delta = 0`` and
``J > 0``, ``f = (|a|^2 + |b|^2) / (2 J)`` is the Winslow / condition-number
energy of the corner, which is infinite on a degenerate corner: a barrier
against folding. A ``delta > 0`` makes ``E`` finite and smooth for folded
corners too, so a folded start can be untangled; ``delta`` is reduced towards 0
as the folds disappear (``delta^2 = eps (eps - J_min)`` while ``J_min < eps``),
then a final smoothing stage with a tiny ``delta`` improves the cells while the
barrier keeps them unfolded. Boundary nodes stay where they are (bit for bit).

See ``docs/foldfree.md``.
"""

from __future__ import annotations

import time
from typing import Any, Callable

import numpy as np

from .blas_threads import one_blas_thread
from .errors import InputError
from .geometry import PLANAR_TOL, boundary_loop, plane_axes, signed_area, vector_area
from .geometry import plane_frame as geometry_plane_frame
from .initial import transfinite

__all__ = ["untangle", "relax", "corner_jacobians", "plane_frame"]

#: ``eps`` of the delta rule, relative to the mean cell area.
EPS = 1e-2
#: ``delta`` of the final smoothing stage, relative to the mean cell area.
DELTA_SMOOTH = 1e-6
#: Most untangling rounds (each a reduced ``delta`` and an L-BFGS run).
MAX_ROUNDS = 40
#: Grids with more nodes than this along both sides are untangled multilevel.
COARSE = 40


def plane_frame(points: np.ndarray, dim: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """The in-plane frame of a planar grid, oriented counter-clockwise.

    Parameters
    ----------
    points : numpy.ndarray
        ``(nu, nv, 3)`` nodes (``z = 0`` for 2D grids).
    dim : int
        2 for a grid given in the xy-plane, else 3.

    Returns
    -------
    centre, basis : numpy.ndarray
        A point of the plane ``(3,)`` and ``(2, 3)`` orthonormal in-plane axes,
        chosen so that the boundary loop (bottom, right, top reversed, left
        reversed) turns counter-clockwise in the coordinates ``(p - centre) @ basis.T``.

    Raises
    ------
    InputError
        The boundary is not planar (a curved 3D piece).
    """
    if dim == 2:
        loop = boundary_loop(points)
        normal = np.array([0.0, 0.0, 1.0]) if vector_area(loop)[2] >= 0 else np.array([0.0, 0.0, -1.0])
        return np.zeros(3), plane_axes(normal)
    centre, basis, dist = geometry_plane_frame(points)
    diag = float(np.linalg.norm(np.ptp(boundary_loop(points), axis=0)))
    if dist > PLANAR_TOL * diag:
        raise InputError(
            f"the fold-free functional is for planar pieces: this piece's boundary is "
            f"{dist / diag:.3g} of its size away from a plane; use functional 'length'")
    return centre, basis


def check_grid_shape(R: np.ndarray, who: str) -> None:
    """InputError unless ``R`` is an ``(nu, nv, 3)`` grid with ``nu, nv >= 3``."""
    if R.ndim != 3 or R.shape[2] != 3 or R.shape[0] < 3 or R.shape[1] < 3:
        raise InputError(f"{who} needs an (nu, nv, 3) grid with nu, nv >= 3, not shape {R.shape}")


def _grid_copy(points: np.ndarray, who: str, copy: bool = True) -> np.ndarray:
    """A float64 copy of an ``(nu, nv, 3)`` grid with ``nu, nv >= 3`` and finite nodes (else InputError);
    with ``copy=False`` the array itself where it is C-contiguous float64 already."""
    R = np.array(points, dtype=np.float64) if copy else np.ascontiguousarray(points, dtype=np.float64)
    check_grid_shape(R, who)
    if not np.isfinite(R).all():
        raise InputError(f"{who} needs finite node coordinates")
    return R


def _axis_map(centre: np.ndarray, basis: np.ndarray) -> list[tuple[int, float]] | None:
    """For a frame that only swaps and negates the x and y axes (a piece in the xy-plane,
    :func:`plane_frame` with ``dim=2``): each planar coordinate's axis and sign; else None."""
    if np.any(centre != 0.0) or basis.shape != (2, 3):
        return None
    axes = []
    for row in basis:
        nz = np.flatnonzero(row)
        if len(nz) != 1 or nz[0] == 2 or abs(row[nz[0]]) != 1.0:
            return None
        axes.append((int(nz[0]), float(row[nz[0]])))
    return axes


def to_plane(R: np.ndarray, centre: np.ndarray, basis: np.ndarray, shift: np.ndarray | None = None,
             scale: float = 1.0) -> np.ndarray:
    """``(R - centre) @ basis.T``: the ``(nu, nv, 2)`` planar coordinates of the grid ``R``; with
    ``shift`` then ``(... - shift) / scale``.

    For a piece in the xy-plane the frame only swaps and negates axes, and the product's terms
    are one coordinate times +-1 plus products with zero: the same values (exact, signed zeros
    aside) come from the coordinates themselves, without the matrix product's temporaries (15 ms
    a grid at 1024^2), in one pass with the shift and scale
    (:func:`~clothgrid.foldfree_kernels.axes_to_plane`, the same bits as NumPy's operations one
    after the other).
    """
    axes = _axis_map(centre, basis)
    if axes is None:
        X = (R - centre) @ basis.T
        if shift is not None:
            X -= shift
            X /= scale
        return X
    X = np.empty(R.shape[:-1] + (2,))
    if R.ndim == 3 and R.dtype == np.float64:
        from .foldfree_kernels import axes_to_plane

        axes_to_plane(R, axes, shift, scale, X)
        return X
    for r, (k, sign) in enumerate(axes):
        np.multiply(R[..., k], sign, out=X[..., r])
    if shift is not None:
        X -= shift
        X /= scale
    return X


def _with_interior(R: np.ndarray, X: np.ndarray, centre: np.ndarray, basis: np.ndarray, dim: int,
                   *, copy: bool = True, shift: np.ndarray | None = None, scale: float = 1.0) -> np.ndarray:
    """``R`` with its interior nodes set from the planar ``X`` (``(nu, nv, 2)`` in the frame ``centre, basis``;
    with ``shift``, ``X * scale + shift`` is, and ``X`` itself may be overwritten); written into ``R``
    itself with ``copy=False``.

    For a piece in the xy-plane (:func:`to_plane`) the interior's x and y are ``X``'s coordinates,
    swapped and negated back (the same values, signed zeros aside, as ``centre + X @ basis``), in
    one pass with the scale and shift where ``R`` is C-contiguous
    (:func:`~clothgrid.foldfree_kernels.axes_from_plane`).
    """
    from .foldfree_kernels import PARALLEL_CELLS, grid_from_plane

    axes = _axis_map(centre, basis) if dim == 2 else None
    if copy and shift is None and axes is not None and R.flags.c_contiguous and R.dtype == np.float64 \
            and X.flags.c_contiguous and X.dtype == np.float64 and R.shape[0] * R.shape[1] >= PARALLEL_CELLS:
        return grid_from_plane(R, X, axes)     # the copy and the interior in one pass
    out = R.copy() if copy else R
    if axes is not None and out.flags.c_contiguous and out.dtype == np.float64:
        from .foldfree_kernels import axes_from_plane

        axes_from_plane(X, axes, shift, scale, out)
    else:
        if shift is not None:
            X *= scale
            X += shift
        if axes is None:
            out[1:-1, 1:-1] = centre + X[1:-1, 1:-1] @ basis
        else:
            for r, (k, sign) in enumerate(axes):
                np.multiply(X[1:-1, 1:-1, r], sign, out=out[1:-1, 1:-1, k])
    if dim == 2:
        out[1:-1, 1:-1, 2] = 0.0
    return out


def corner_jacobians(X: np.ndarray) -> np.ndarray:
    """``(4, nu-1, nv-1)`` corner cross products ``a x b`` of ``(nu, nv, 2)`` planar nodes."""
    P = (X[:-1, :-1], X[1:, :-1], X[1:, 1:], X[:-1, 1:])
    out = np.empty((4,) + P[0].shape[:2])
    for k in range(4):
        a, b = P[(k + 1) % 4] - P[k], P[k - 1] - P[k]
        out[k] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


# Node offsets of the four corners of cell (i, j): the corner's slice of the node array.
_OFFSETS = ((0, 0), (1, 0), (1, 1), (0, 1))


class _Energy:
    """The regularised Winslow energy of the interior nodes and its gradient."""

    def __init__(self, X: np.ndarray):
        self.X = X.copy()                       # (nu, nv, 2); boundary entries fixed
        nu, nv = X.shape[:2]
        self.nu, self.nv = nu, nv
        self.G = np.zeros_like(X)
        self.delta2 = 0.0

    def unpack(self, x: np.ndarray) -> np.ndarray:
        self.X[1:-1, 1:-1] = x.reshape(self.nu - 2, self.nv - 2, 2)
        return self.X

    def __call__(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        X = self.unpack(x)
        nu, nv = self.nu, self.nv
        P = [X[di:nu - 1 + di, dj:nv - 1 + dj] for di, dj in _OFFSETS]
        G = self.G
        G.fill(0.0)
        total = 0.0
        d4 = 4.0 * self.delta2
        for k in range(4):
            a = P[(k + 1) % 4] - P[k]
            b = P[k - 1] - P[k]
            ax, ay, bx, by = a[..., 0], a[..., 1], b[..., 0], b[..., 1]
            J = ax * by - ay * bx
            N = ax * ax + ay * ay + bx * bx + by * by
            s = np.sqrt(J * J + d4)
            D = J + s
            with np.errstate(divide="ignore", invalid="ignore"):
                f = N / D
                dN = 2.0 / D                               # df/dN per component, times the vector
                dJ = -f / D * (1.0 + J / s)                # df/dJ
            total += float(f.sum())
            ga = np.stack([dN * ax + dJ * by, dN * ay - dJ * bx], axis=-1)
            gb = np.stack([dN * bx - dJ * ay, dN * by + dJ * ax], axis=-1)
            for node, g in (((k + 1) % 4, ga), ((k - 1) % 4, gb)):
                di, dj = _OFFSETS[node]
                G[di:nu - 1 + di, dj:nv - 1 + dj] += g
            di, dj = _OFFSETS[k]
            G[di:nu - 1 + di, dj:nv - 1 + dj] -= ga + gb
        if not np.isfinite(total):
            return np.inf, np.zeros(x.shape)
        return total, G[1:-1, 1:-1].ravel().copy()


def _minimise(energy: _Energy, x: np.ndarray, max_iter: int, gtol: float) -> tuple[np.ndarray, int]:
    from scipy.optimize import minimize   # on first use: untangle only (relax runs Numba kernels)

    res = minimize(energy, x, jac=True, method="L-BFGS-B",
                   options={"maxiter": int(max_iter), "gtol": gtol, "ftol": 1e-13, "maxcor": 10})
    return res.x, int(res.nit)


def _every_other(n: int) -> np.ndarray:
    """The indices of every other grid line of ``n``, both ends included (a coarser grid's lines)."""
    return np.unique(np.round(np.linspace(0, n - 1, (n + 1) // 2)).astype(np.int64))


#: The coarser grid of :func:`_relax_all` also keeps the grid lines through the boundary nodes that
#: its own boundary would miss by more than this fraction of the node's shorter boundary edge (the
#: node against the straight line, in index space, between its coarser neighbours, as
#: :func:`_prolong` interpolates it): a dart's tip or mouth (any turn of more than about 30
#: degrees), or a node a short interval from the next (a seam's end near a dart's mouth). Where every
#: other line passed such a node by, the coarser grid's boundary cut it off, and the mismatch,
#: spread down its one line by the interpolation, folded the finer grid there: GarmentCode pants
#: backs at 5 mm (about 196 x 200 nodes, two 20 cm darts whose tips are nodes, sewn leg to leg)
#: kept 37-66 folded cells.
KEEP_MISMATCH = 0.25
#: ... at most this fraction of a side's lines (the worst first), so that the coarser grid stays
#: coarser on a noisy outline.
KEEP_MOST = 0.125


def _coarse_lines(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The grid lines of :func:`_relax_all`'s coarser grid: every other line of ``X`` (both ends
    included), and those through boundary nodes the coarser boundary would miss
    (:data:`KEEP_MISMATCH`)."""
    nu, nv = X.shape[:2]
    out = []
    for n, sides in ((nu, (X[:, 0, :2], X[:, -1, :2])), (nv, (X[0, :, :2], X[-1, :, :2]))):
        lines = _every_other(n)
        worst = np.zeros(n)
        k = np.arange(n)
        for S in sides:
            line = np.stack([np.interp(k, lines, S[lines, c]) for c in range(2)], -1)
            edge = np.hypot(*np.diff(S, axis=0).T)
            short = np.minimum(np.r_[np.inf, edge], np.r_[edge, np.inf])
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.hypot(*(S - line).T) / short
            worst = np.maximum(worst, np.nan_to_num(ratio, nan=0.0, posinf=0.0))
        keep = np.flatnonzero(worst > KEEP_MISMATCH)
        keep = keep[np.argsort(-worst[keep], kind="stable")][:int(KEEP_MOST * n)]
        out.append(np.union1d(lines, keep).astype(np.int64))
    return out[0], out[1]


def _prolong(Xc: np.ndarray, ic: np.ndarray, jc: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Fine start from a coarse grid: bilinear in index space, boundary mismatch spread by TFI."""
    nu, nv = X.shape[:2]
    p = np.interp(np.arange(nu), ic, np.arange(len(ic)))
    q = np.interp(np.arange(nv), jc, np.arange(len(jc)))
    i0 = np.minimum(p.astype(np.int64), len(ic) - 2)
    j0 = np.minimum(q.astype(np.int64), len(jc) - 2)
    a = (p - i0)[:, None, None]
    b = (q - j0)[None, :, None]
    I0, J0 = i0[:, None], j0[None, :]
    F = ((1 - a) * (1 - b) * Xc[I0, J0] + a * (1 - b) * Xc[I0 + 1, J0]
         + (1 - a) * b * Xc[I0, J0 + 1] + a * b * Xc[I0 + 1, J0 + 1])
    D = np.zeros_like(X)
    for sl in (np.s_[0, :], np.s_[-1, :], np.s_[:, 0], np.s_[:, -1]):
        D[sl] = X[sl] - F[sl]
    F += transfinite(D)                                   # spread the mismatch inward (eq. 4)
    F[0, :], F[-1, :], F[:, 0], F[:, -1] = X[0, :], X[-1, :], X[:, 0], X[:, -1]
    return F


def _solve(X: np.ndarray, max_iter: int, smooth_iter: int, say: Callable[[str], None],
           stats: dict[str, Any], level: int = 0) -> np.ndarray:
    """Untangle and smooth the ``(nu, nv, 2)`` counter-clockwise planar grid ``X``."""
    nu, nv = X.shape[:2]
    loop = boundary_loop(X)
    area = signed_area(loop)
    if not area > 0:
        raise InputError("the piece's boundary encloses no area (or does not turn counter-clockwise)")
    scale = np.sqrt(area / ((nu - 1) * (nv - 1)))                 # mean cell area 1
    shift = loop.mean(axis=0)
    Xs = (X - shift) / scale
    jmin = float(corner_jacobians(Xs).min())
    if jmin <= 0 and min(nu, nv) > COARSE:
        # Multilevel: untangle every other grid line first, then start from its interpolation.
        ic, jc = _coarse_lines(Xs)
        Xc = _solve(Xs[np.ix_(ic, jc)], max_iter, smooth_iter, say, stats, level + 1)
        Xs = _prolong(Xc, ic, jc, Xs)
        jmin = float(corner_jacobians(Xs).min())
    tag = f"fold-free {nu}x{nv}:"
    energy = _Energy(Xs)
    x = Xs[1:-1, 1:-1].ravel().copy()
    say(f"{tag} start min corner Jacobian {jmin:.3g} (relative to the mean cell area)")
    rounds = 0
    while jmin <= 0 and rounds < MAX_ROUNDS:
        rounds += 1
        energy.delta2 = EPS * (EPS - jmin)
        x, nit = _minimise(energy, x, max_iter, 1e-6)
        stats["iterations"] += nit
        jmin = float(corner_jacobians(energy.unpack(x)).min())
        say(f"{tag} untangling round {rounds}, delta {np.sqrt(energy.delta2):.3g}, "
            f"{nit} iterations, min corner Jacobian {jmin:.3g}")
    if jmin > 0 and smooth_iter > 0:
        energy.delta2 = DELTA_SMOOTH ** 2
        x_s, nit = _minimise(energy, x.copy(), smooth_iter, 1e-5)
        stats["iterations"] += nit
        j_s = float(corner_jacobians(energy.unpack(x_s)).min())
        if j_s > 0:
            x, jmin = x_s, j_s
        say(f"{tag} smoothing, {nit} iterations, min corner Jacobian {jmin:.3g}")
    if level == 0:
        stats["rounds"] = rounds
        stats["min_corner_jacobian"] = jmin
    stats["levels"] = max(stats.get("levels", 1), level + 1)
    return energy.unpack(x) * scale + shift


@one_blas_thread()     # Numba's threads do the work (clothgrid.blas_threads)
def untangle(points: np.ndarray, *, dim: int = 3, max_iter: int = 400, smooth_iter: int | None = None,
             progress: Callable[[str], None] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
    """Move the interior nodes of a planar grid to an unfolded, smooth position.

    On grids larger than ``COARSE`` nodes a side whose start is folded, the
    grid with every other line is untangled first (recursively) and its
    interpolation is the start of the finer grid.

    Parameters
    ----------
    points : array_like
        ``(nu, nv, 3)`` start grid (for instance the length-functional grid);
        ``z = 0`` for 2D pieces. Its boundary nodes are kept exactly.
    dim : int
        2 if the piece is given in the xy-plane, else 3 (the grid must then lie
        in a plane).
    max_iter : int
        Most L-BFGS iterations of each untangling round.
    smooth_iter : int, optional
        Most L-BFGS iterations of the final smoothing stage (default
        ``max_iter``; 0 skips it).
    progress : callable, optional
        Called with a line of text after each stage.

    Returns
    -------
    points : numpy.ndarray
        ``(nu, nv, 3)`` float64 nodes.
    info : dict
        ``rounds`` (untangling rounds on the finest grid), ``levels`` (grids
        solved), ``iterations`` (all L-BFGS iterations), ``untangled`` (no
        corner with ``J <= 0`` left), ``min_corner_jacobian`` (relative to the
        mean cell area) and ``seconds``.

    Raises
    ------
    InputError
        Not an ``(nu, nv, 3)`` grid with at least 3 x 3 nodes, or not planar.
    """
    t0 = time.perf_counter()
    say = progress or (lambda _msg: None)
    R = _grid_copy(points, "untangle")
    for name, value, least in (("max_iter", max_iter, 1), ("smooth_iter", smooth_iter, 0)):
        if value is None and name == "smooth_iter":
            continue
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < least:
            raise InputError(f"{name} must be an integer >= {least}, not {value!r}")
    smooth_iter = max_iter if smooth_iter is None else int(smooth_iter)
    centre, basis = plane_frame(R, dim)
    X = to_plane(R, centre, basis)                                  # (nu, nv, 2), counter-clockwise
    stats: dict[str, Any] = {"iterations": 0}
    X = _solve(X, int(max_iter), smooth_iter, say, stats)
    out = _with_interior(R, X, centre, basis, dim, copy=False)      # R is this call's own copy
    info = {"rounds": stats["rounds"], "levels": stats["levels"], "iterations": stats["iterations"],
            "untangled": bool(stats["min_corner_jacobian"] > 0),
            "min_corner_jacobian": float(stats["min_corner_jacobian"]), "seconds": time.perf_counter() - t0}
    return out, info


#: Cells whose smallest corner sine is below this are "poor" and get relaxed (about 20 degrees).
POOR_SINE = 0.34
#: Nodes within this many grid lines of a poor cell are moved with it.
MARGIN = 4
#: Largest margin (grid lines) that the eighth of the shorter grid side sets first. On fine grids a
#: fold is often a few cells wide: on the T-shirt front at 512^2 to 2048^2, 8 lines round the poor
#: cells left a larger smallest corner Jacobian and angle and a smaller edge spread than 32 (1024^2:
#: 0.080 against 0.054, 16.7 against 16.1 degrees, 9.6 against 14.8), moving a third of the nodes
#: (docs/performance.md, "Eighth pass").
MAX_MARGIN = 8
#: Where folds remain after the rounds on :data:`MAX_MARGIN`, the rounds run again on a margin of up
#: to this many lines (the eighth of the shorter grid side) before every node is untangled: some
#: folds of fine grids reach further (32 lines round it gave the same grid quality as 128 at 1024^2).
WIDE_MARGIN = 32
#: Most untangling rounds of :func:`relax` per active set.
RELAX_ROUNDS = 30
#: Most Gauss-Seidel sweeps per round.
RELAX_SWEEPS = 60
#: Sweeps per untangling round of a quick relax (``quick=True``: the corner choice's coarse grids,
#: some 2,700 over the survey's files). With 20 the corner choice took 2.55 s of the survey against
#: 3.44 s with :data:`RELAX_SWEEPS`, and chose the same corners on all 281 pieces it ranks by grid
#: (with 10, one piece's differed); the score changed on 1 % of the coarse grids by more than 0.14.
QUICK_SWEEPS = 20
#: Over-relaxation of the ordered sweeps (an active set below :data:`PARALLEL_NODES`): a node's
#: Newton step is first tried this many times over, then halved until the energy falls.
#: Gauss-Seidel passes a correction about one node a sweep. On the Roache regions at 80^2 (both
#: weights) 1.7 took 0.68 of the plain step's (1.0) sweeps and left the smallest corner Jacobian
#: 0.95-2.5x the plain one; over the survey's pieces the whole auto step ran in about half the time
#: and the smallest angle rose from 4.1 to 6.4 degrees. On the 1024^2 T-shirt's large active set
#: it saved no sweep and left a smaller corner Jacobian: the coloured sweeps take the plain step
#: (docs/performance.md, "Eighth pass").
OVERRELAX = 1.7
#: Where every node was untangled from a coarser grid (:func:`_relax_all`), the coarser grid's
#: every interior node is smoothed before it is interpolated (the low frequencies, at a quarter of
#: the cost), and the smoothing after it on the grid asked for moves only the nodes within
#: :data:`SMOOTH_MARGIN` lines of a cell with a corner sine below :data:`SMOOTH_SINE` (35 degrees:
#: above the poor cells' 20, so that the cells the interpolation leaves between 20 and 35 degrees
#: are smoothed too). Smoothing every node of the finer grid instead (before 2026-11-26) took 7.1 s
#: of the 1024^2 T-shirt's auto step with the paper's weights, now 3.0 s (smallest angle 27.0 -> 26.7
#: degrees); the survey's relax at 5 mm edges 7.3 -> 6.3 s, no piece's smallest angle down by a
#: degree, 7 up (docs/performance.md, "Tenth pass").
SMOOTH_MARGIN = 10
SMOOTH_SINE = 0.57
#: The first untangling round on the narrow active set (the poor cells' margin) of a grid with a
#: coarser grid to come (:data:`COARSE_RELAX`) looks at its folded corners after this many sweeps.
#: Where there are more than it started with, the set is given up (the wide set, or every node
#: from the coarser grid, comes next): over the survey's pieces no set that went on to untangle had
#: more at 10 or 20 sweeps, while 14 of the 24 that failed had (fs_wahid piece 4: 220 -> 286 -> 316
#: folded corners, then 489 after its 60 sweeps and two more rounds); the relax took 0.84 of its
#: time at 10 mm and 5 mm edges. The wide set is not given up (giving it up too left a GarmentCode
#: torso with 2 folded cells at 2 mm), nor a coarser grid's. Where none is folded, the round ends
#: there and the smoothing follows (the 1024^2 T-shirt: 79 sweeps instead of 112, the same
#: quality). Otherwise the round goes on as one, the same grid as without the look
#: (docs/performance.md, "Tenth pass").
GIVE_UP_SWEEPS = 20
#: A round's sweeps, and the smoothing's, stop once no node moved more than this in a sweep (in
#: the scaled coordinates: the mean cell area 1, so a thousandth of a mean cell's side).
SWEEP_TOL = 1e-3
#: Within a sweep a node is passed over where neither it nor any of its 8 neighbours moved more
#: than this fraction of :data:`SWEEP_TOL` in that sweep or the last
#: (:func:`~clothgrid.foldfree_kernels.sweep_nodes`' ``quiet``): the stop rule, node by node, with
#: a margin. The smoothing converges slowly (its largest move falls by about 0.93 a sweep on the
#: 1024^2 T-shirt front) while most of its nodes have settled. Over the survey's pieces at 10 mm
#: edges the relax took 4.72 M node steps instead of 5.67 M (0.7: 4.50 M; 1: 4.27 M), each
#: piece's smallest angle within a degree of what it was, no fold, the edge spread after the
#: evening the same in the geometric mean (0.9996; 9 pieces over 5 % larger, 9 over 5 % smaller:
#: the evening's result moves with its start) (docs/performance.md, "Sixteenth pass").
QUIET_FRACTION = 0.5
#: Grids with at least this many nodes on their shorter side untangle every node on the grid of
#: every other line first (:func:`_relax_all`).
COARSE_RELAX = 20
#: Untangling every node stops after this many rounds in a row without fewer folded corners
#: (a wild outline ran all 60 rounds, minutes at 770 x 385 nodes, and ended with more folds).
RELAX_STALL = 6


#: Active sets of at least this many nodes are swept in four colours, each colour's nodes in
#: parallel (:func:`~clothgrid.foldfree_kernels.sweep_nodes_coloured`, and the edge evening's
#: ``_sweep_coloured``); smaller ones, every real piece at the default edge length, in order as before.
PARALLEL_NODES = 8192


#: An ordered sweep is split between threads only where each thread gets at least this many
#: nodes a sweep (about 15 us of work: waking the threads costs a few us a sweep). With
#: OpenBLAS's threads spinning beside them (after a threaded solve, before
#: :mod:`clothgrid.blas_threads`) the parts cost more than they saved: the survey's pieces at
#: 10 mm took 2.7 -> 2.9-4.1 s; with BLAS on one thread, 2.56 -> 2.45 s.
PART_NODES = 128


def node_parts(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The order and part boundaries in which an ordered sweep over ``nodes`` runs on the host's
    threads, the same grid bit for bit; None where it gains nothing (one thread, one component,
    or parts under :data:`PART_NODES`).

    The set's components (nodes joined as 8 neighbours,
    :func:`~clothgrid.foldfree_kernels.node_components`) are dealt to the threads, largest first,
    each to the least loaded; ``order`` lists the nodes part by part, each part in the list's own
    order (``np.argsort`` stable), and part ``p`` is ``order[starts[p]:starts[p + 1]]``.
    """
    import numba

    from .foldfree_kernels import node_components

    threads = numba.get_num_threads()
    if threads < 2 or len(nodes) < 2 * PART_NODES:
        return None
    label, count = node_components(nodes)
    if count < 2:
        return None
    sizes = np.bincount(label, minlength=count)
    loads = np.zeros(min(threads, count), np.int64)
    part = np.empty(count, np.int64)
    for c in np.argsort(-sizes, kind="stable"):
        p = int(np.argmin(loads))
        part[c] = p
        loads[p] += sizes[c]
    if (loads > 0).sum() < 2 or np.sort(loads)[-2] < PART_NODES:
        return None
    of_node = part[label]
    order = np.argsort(of_node, kind="stable")
    starts = np.searchsorted(of_node[order], np.arange(len(loads) + 1)).astype(np.int64)
    return order, starts


def _sweeps(Xs: np.ndarray, nodes: np.ndarray, delta2: float, sweeps: int,
            stats: dict[str, Any]) -> tuple[int, float]:
    """Node sweeps over ``nodes`` until a sweep moves no node more than :data:`SWEEP_TOL`, the
    nodes whose neighbourhood is quiet passed over (:data:`QUIET_FRACTION`): in order (the set's
    separate components on the host's threads, :func:`node_parts`), or in four colours in parallel
    for a large set. Returns the sweeps done (also added to ``stats["sweeps"]``, the node steps
    taken to ``stats["visits"]``) and the last one's largest move."""
    from .foldfree_kernels import sweep_nodes, sweep_nodes_coloured, sweep_nodes_parts

    tol, quiet = SWEEP_TOL, SWEEP_TOL * QUIET_FRACTION
    if len(nodes) < PARALLEL_NODES:
        parts = node_parts(nodes)
        if parts is not None:
            order, starts = parts
            done, last, visits = sweep_nodes_parts(Xs, np.ascontiguousarray(nodes[order]), starts, delta2, sweeps,
                                                   tol, OVERRELAX, quiet)
        else:
            done, last, visits = sweep_nodes(Xs, nodes, delta2, sweeps, tol, OVERRELAX, quiet)    # over-relaxed
    else:
        colour = 2 * (nodes[:, 0] & 1) + (nodes[:, 1] & 1)
        order = np.argsort(colour, kind="stable")
        starts = np.searchsorted(colour[order], np.arange(5)).astype(np.int64)
        done, last, visits = sweep_nodes_coloured(Xs, np.ascontiguousarray(nodes[order]), starts, delta2, sweeps,
                                                  tol, 1.0, quiet)
    stats["sweeps"] += int(done)
    stats["visits"] = stats.get("visits", 0) + int(visits)
    return int(done), float(last)


def _margin(nu: int, nv: int, least: int, cap: int) -> int:
    """Grid lines round a poor cell: an eighth of the shorter grid side, at least ``least``, at most
    ``cap`` (unless ``least`` is more)."""
    return max(least, min(min(nu, nv) // 8, cap))


def _interior_nodes(nu: int, nv: int) -> np.ndarray:
    """``(K, 2)`` every interior node of an ``nu x nv`` grid, row by row."""
    return np.argwhere(np.ones((nu - 2, nv - 2), bool)).astype(np.int64) + 1


def _has_coarser(nu: int, nv: int) -> bool:
    """Whether every node of an ``nu x nv`` grid is untangled from the grid of every other line
    first (:data:`COARSE_RELAX`, :func:`_relax_all`)."""
    return min(nu, nv) >= COARSE_RELAX


def _smooth(Xs: np.ndarray, nodes: np.ndarray, stats: dict[str, Any], sweeps: int = RELAX_SWEEPS) -> None:
    """Smoothing sweeps (``delta`` :data:`DELTA_SMOOTH`) over ``nodes``, counted in ``stats``."""
    _sweeps(Xs, nodes, DELTA_SMOOTH ** 2, sweeps, stats)


def _active_nodes(poor: np.ndarray, margin: int) -> np.ndarray:
    """``(K, 2)`` interior nodes within ``margin`` grid lines of a poor cell (``poor``: cells), row by row."""
    from .foldfree_kernels import dilate
    from .grid_kernels import mask_places

    nu, nv = poor.shape[0] + 1, poor.shape[1] + 1
    near, _ = dilate(poor, margin + 1, margin, nu, nv)
    return mask_places(near)


def _poor_cells(X: np.ndarray, poor_sine: float) -> np.ndarray:
    """Cells with a corner sine below ``poor_sine``, the grid-corner cells aside (a grid corner's
    angle is the outline's): :func:`~clothgrid.foldfree_kernels.cells_below`."""
    from .foldfree_kernels import cells_below

    return cells_below(X, poor_sine)


def _relax_rounds(Xs: np.ndarray, nodes: np.ndarray, stats: dict[str, Any], rounds: int,
                  stall: int | None, strict: bool = False, sweeps: int = RELAX_SWEEPS,
                  give_up: bool = False) -> tuple[float, int, Any]:
    """Untangling rounds of ``sweeps`` sweeps over ``nodes`` (delta by Escobar's rule) until no
    corner is folded, or until ``stall`` rounds in a row did not lower the count of folded corners
    below the last round's (``strict``: below the fewest so far). ``give_up``: the rounds end after
    the first :data:`GIVE_UP_SWEEPS` sweeps where those left more folded corners than there were,
    or none. Returns the smallest corner term and the folded corners' count (:func:`corner_min`'s
    of the whole grid), and the :class:`~clothgrid.foldfree_kernels.CornerCells` that kept them."""
    from .foldfree_kernels import CornerCells

    corners = CornerCells(Xs, True, nodes)  # only the sweeps below move Xs: the cells at their nodes
    jmin, bad = corners.figures()
    stalled, fewest = 0, bad
    while bad and rounds > 0 and len(nodes):
        rounds -= 1
        stats["rounds"] += 1
        # A round runs all its sweeps: ending every round as soon as no corner is folded (tried:
        # 1.6x faster at 1024^2) left worse cells and, on real pieces, folds (fs_wahid_layout.svg
        # piece 4), before sets were given up and coarser grids smoothed. The first round of a set
        # that may be given up (GIVE_UP_SWEEPS) looks after that many sweeps: more folds than it
        # started with give the set up, none end the round there (the smoothing follows), and
        # otherwise the round goes on as one.
        delta2 = EPS * (EPS - min(jmin, 0.0))
        before = bad
        part = GIVE_UP_SWEEPS if give_up and sweeps > GIVE_UP_SWEEPS else sweeps
        give_up = False
        done, _ = _sweeps(Xs, nodes, delta2, part, stats)
        jmin, bad = corners.moved(Xs)
        if part < sweeps and done == part and bad:
            if bad > before:             # more folds than it started with: this set is given up
                stats["given_up"] = stats.get("given_up", 0) + 1
                return float(jmin), int(bad), corners
            _sweeps(Xs, nodes, delta2, sweeps - part, stats)
            jmin, bad = corners.moved(Xs)
        # strict (a coarser grid's start, or every node after one): counts that go up and down
        # without a new low ran all 60 rounds on a wild outline's grids; on one grid alone (below
        # COARSE_RELAX), counts that rise for rounds before they fall untangled the Roache annulus
        # and plow
        if strict:
            stalled, fewest = (0, bad) if bad < fewest else (stalled + 1, fewest)
        else:
            stalled = stalled + 1 if bad >= before else 0
        if stall is not None and stalled >= stall:
            break
    return float(jmin), int(bad), corners


def _relax_all(Xs: np.ndarray, folded: int, stats: dict[str, Any], say: Callable[[str], None],
               coarse: bool = False) -> tuple[int, bool]:
    """Untangle every interior node of ``Xs`` (in place, after the active sets could not, leaving
    ``folded`` folded corners); the folded corners left, and whether the interior is a smoothed
    coarser grid's interpolation (then only the poor cells' neighbourhoods need smoothing).

    On a grid of at least :data:`COARSE_RELAX` nodes a side, the grid of every other line is
    relaxed first (:func:`_relax_scaled`, recursively), every one of its interior nodes is smoothed
    where it is untangled, and its interpolation (what its boundary
    misses spread inward by TFI, as in :func:`untangle`) replaces the interior unless it has more
    folded corners; folds left are untangled on the poor cells' narrow margin, and only where those
    rounds fail on every node. ``coarse``: this grid is itself a finer one's start (its rounds
    stop on the stricter stall rule of :func:`_relax_rounds`).
    """
    from .foldfree_kernels import corner_min

    nu, nv = Xs.shape[:2]
    coarser = _has_coarser(nu, nv)
    if coarser:
        ic, jc = _coarse_lines(Xs)
        Xc = np.ascontiguousarray(Xs[np.ix_(ic, jc)])
        poor = _poor_cells(Xc, POOR_SINE)
        say(f"relax {nu}x{nv}: every node; the {len(ic)}x{len(jc)} grid of every other line first")
        if poor.any():
            _relax_scaled(Xc, poor, stats, say, MARGIN, False, False, coarse=True)
        smoothed = corner_min(Xc, True)[1] == 0
        if smoothed:       # its low frequencies, at a quarter of the finer grid's cost (SMOOTH_MARGIN)
            _smooth(Xc, _interior_nodes(len(ic), len(jc)), stats)
        stats["levels"] = stats.get("levels", 1) + 1
        kept = Xs[1:-1, 1:-1].copy()
        Xs[1:-1, 1:-1] = _prolong(Xc, ic, jc, Xs)[1:-1, 1:-1]
        jmin, bad = corner_min(Xs, True)
        if bad > folded:
            # A coarse grid that could not be untangled either (a wild outline): its interpolation
            # has more folds than the grid it would replace, and every node is untangled from that.
            Xs[1:-1, 1:-1] = kept
            say(f"relax {nu}x{nv}: the coarser grid's start has {bad} folded corners, not kept")
        else:
            if bad:
                nodes = _active_nodes(_poor_cells(Xs, POOR_SINE), _margin(nu, nv, MARGIN, MAX_MARGIN))
                jmin, bad, _ = _relax_rounds(Xs, nodes, stats, 8, 2, coarse)
            say(f"relax {nu}x{nv}: from the coarser grid, {bad} folded corners left")
            if not bad:
                return 0, smoothed
    nodes = _interior_nodes(nu, nv)
    # after a coarser grid's start that failed, the strict stall rule (a wild outline: its count
    # rose from the start and fell by a few corners a round, for all 2 * RELAX_ROUNDS rounds)
    jmin, bad, _ = _relax_rounds(Xs, nodes, stats, 2 * RELAX_ROUNDS, RELAX_STALL, coarse or coarser)
    say(f"relax {nu}x{nv}: all {len(nodes)} interior nodes, {bad} folded corners left")
    return bad, False


def _relax_scaled(Xs: np.ndarray, poor: np.ndarray, stats: dict[str, Any], say: Callable[[str], None],
                  margin: int, whole: bool, quick: bool, coarse: bool = False
                  ) -> tuple[np.ndarray, tuple[float, int] | None]:
    """:func:`relax`'s work on the scaled planar grid ``Xs`` (in place) with ``poor`` cells: the
    narrow then the wide active set, every node where folds remain, then the smoothing; the
    ``(K, 2)`` nodes moved, and :func:`~clothgrid.foldfree_kernels.corner_min`'s figures of the
    result where its last rounds kept them (else None). ``coarse``: a finer grid's start
    (:func:`_relax_all`)."""
    nu, nv = Xs.shape[:2]
    m = max(nu, nv) if whole else _margin(nu, nv, margin, MAX_MARGIN)
    nodes = _interior_nodes(nu, nv) if whole else _active_nodes(poor, m)   # whole: the same nodes, undilated
    wide = _margin(nu, nv, margin, WIDE_MARGIN)
    retry = not quick and not whole and wide > m
    start = Xs[nodes[:, 0], nodes[:, 1]] if retry else None      # a copy (fancy indexing)
    # the narrow set may be given up early where a coarser grid is to come (GIVE_UP_SWEEPS)
    jmin, bad, corners = _relax_rounds(Xs, nodes, stats, 8, 2, coarse, QUICK_SWEEPS if quick else RELAX_SWEEPS,
                                       give_up=not (whole or coarse) and _has_coarser(nu, nv))
    say(f"relax {nu}x{nv}: {len(nodes)} nodes within {m} lines of poor cells, {bad} folded corners left")
    if bad and retry:
        # Failed rounds can leave more folds than they found (the all-node untangling then took
        # 8x as long on fine real pieces): the wide rounds start from the grid as it came.
        Xs[nodes[:, 0], nodes[:, 1]] = start
        m = wide
        nodes = _active_nodes(poor, m)
        jmin, bad, corners = _relax_rounds(Xs, nodes, stats, 8, 2, coarse)
        say(f"relax {nu}x{nv}: {len(nodes)} nodes within {m} lines of poor cells, {bad} folded corners left")
    smooth = nodes
    if bad and not quick:
        bad, from_smoothed = _relax_all(Xs, bad, stats, say, coarse)
        nodes = smooth = _interior_nodes(nu, nv)
        corners = None
        if from_smoothed:        # the coarser grid's smoothing did the rest (SMOOTH_MARGIN)
            smooth = _active_nodes(_poor_cells(Xs, SMOOTH_SINE), SMOOTH_MARGIN)
    if bad == 0 and len(smooth):
        _smooth(Xs, smooth, stats, 8 if quick else RELAX_SWEEPS)
        if not coarse:
            stats["smoothed"] = int(len(smooth))      # the finest grid's smoothed nodes
    # the last rounds' nodes are the ones smoothed: their cells measured again give corner_min's
    return nodes, (None if corners is None else corners.moved(Xs))


@one_blas_thread()     # Numba's threads do the work (clothgrid.blas_threads)
def relax(points: np.ndarray, *, dim: int = 3, poor_sine: float = POOR_SINE, margin: int = MARGIN,
          whole: bool = False, quick: bool = False, progress: Callable[[str], None] | None = None
          ) -> tuple[np.ndarray, dict[str, Any]]:
    """Unfold and improve the poor cells of a planar grid, moving only the nodes near them.

    The energy is :func:`untangle`'s, minimised node by node (Newton steps,
    :mod:`clothgrid.foldfree_kernels`) over the interior nodes within
    ``margin`` grid lines (at least an eighth of the shorter grid side, up to
    :data:`MAX_MARGIN`) of a cell that is folded or has a corner angle whose
    sine is below ``poor_sine``. Where folds remain, the nodes within up to
    :data:`WIDE_MARGIN` lines of a poor or folded cell are untangled, and where
    folds still remain every interior node (from a coarser grid, smoothed on
    every node, where the grid is large enough); then the nodes moved are
    smoothed (after a coarser grid, only those within :data:`SMOOTH_MARGIN`
    lines of a cell with a corner sine below :data:`SMOOTH_SINE`).
    Cost follows the size of the poor region.

    Parameters
    ----------
    points : array_like
        ``(nu, nv, 3)`` grid (``z = 0`` for 2D pieces); boundary nodes are kept exactly.
    dim : int
        2 for a grid in the xy-plane, else 3 (then the grid must be planar).
    poor_sine, margin :
        Which cells are relaxed and how far around them.
    whole : bool
        Relax every interior node (then ``poor_sine`` and ``margin`` are unused).
    quick : bool
        At most 8 untangling rounds of :data:`QUICK_SWEEPS` sweeps and 8
        smoothing sweeps (a cheap look, as when ranking corner choices); folds
        may remain.
    progress : callable, optional
        Called with a line of text per stage.

    Returns
    -------
    points : numpy.ndarray
        ``(nu, nv, 3)`` nodes.
    info : dict
        ``moved`` (the nodes it moved: its active sets, or every interior
        node), ``sweeps`` and ``rounds`` (on every grid), ``visits`` (the node
        steps of all those sweeps: a node whose neighbourhood has settled is
        passed over, :data:`SWEEP_TOL`), ``given_up`` (active
        sets given up after :data:`GIVE_UP_SWEEPS` sweeps, where any),
        ``untangled``, ``min_corner_jacobian`` (smallest ``a x b / (|a|^2 +
        |b|^2)``, 1/2 for a square, grid-corner terms aside), ``seconds``,
        ``method``, and ``levels`` (the grids, where every node was untangled
        from coarser ones).
    """
    t0 = time.perf_counter()
    R = _grid_copy(points, "relax")
    X, centre, basis, stats, _ = relax_in_plane(R, dim=dim, poor_sine=poor_sine, margin=margin, whole=whole,
                                                quick=quick, progress=progress)
    out = R if X is None else _with_interior(R, X, centre, basis, dim, copy=False)   # R: this call's own
    stats["seconds"] = time.perf_counter() - t0
    return out, stats


def relax_in_plane(R: np.ndarray, *, dim: int = 3, poor_sine: float = POOR_SINE, margin: int = MARGIN,
                   whole: bool = False, quick: bool = False, progress: Callable[[str], None] | None = None
                   ) -> tuple[np.ndarray | None, np.ndarray, np.ndarray, dict[str, Any], np.ndarray | None]:
    """:func:`relax`'s work, its result in the plane's coordinates: for a caller that goes on in
    them (:func:`clothgrid.evening.even_in_plane`) and makes the 3D grid once.

    ``R`` (C-contiguous float64 ``(nu, nv, 3)``, finite, ``nu, nv >= 3``) is not changed. Returns
    ``X``, the result's ``(nu, nv, 2)`` coordinates ``(p - centre) @ basis.T`` (a new array; None
    where no cell is poor and nothing moved), the frame ``centre, basis`` (:func:`plane_frame`),
    :func:`relax`'s info (``seconds`` this call's), and the ``(nu, nv)`` bool mask of the interior
    nodes it may have moved (None with ``X``): every other node of ``X`` is ``to_plane``'s of ``R``,
    bit for bit (not through the relax's shift and scale and back).
    """
    from .foldfree_kernels import corner_min

    t0 = time.perf_counter()
    say = progress or (lambda _msg: None)
    centre, basis = plane_frame(R, dim)
    nu, nv = R.shape[:2]
    loop = to_plane(boundary_loop(R), centre, basis)    # X's boundary, before X is made
    area = signed_area(loop)
    if not area > 0:
        raise InputError("the piece's boundary encloses no area")
    scale = np.sqrt(area / ((nu - 1) * (nv - 1)))
    shift = loop.mean(axis=0)
    Xs = np.ascontiguousarray(to_plane(R, centre, basis, shift, scale))    # shifted and scaled in one pass
    stats: dict[str, Any] = {"sweeps": 0, "rounds": 0, "moved": 0, "method": "relax"}
    poor = np.ones((nu - 1, nv - 1), bool) if whole else _poor_cells(Xs, poor_sine)
    if not poor.any():
        jmin, bad = corner_min(Xs, True)
        stats.update(untangled=bad == 0, min_corner_jacobian=float(jmin), seconds=time.perf_counter() - t0)
        return None, centre, basis, stats, None
    nodes, figures = _relax_scaled(Xs, poor, stats, say, margin, whole, quick)
    jmin, bad = corner_min(Xs, True) if figures is None else figures
    stats.update(moved=int(len(nodes)), untangled=bad == 0, min_corner_jacobian=float(jmin))
    # the nodes moved (the last set: an earlier, narrower one was put back or is inside it)
    moved = np.zeros((nu, nv), bool)
    if len(nodes) == (nu - 2) * (nv - 2):
        moved[1:-1, 1:-1] = True
    else:
        moved[nodes[:, 0], nodes[:, 1]] = True
    # their shift and scale undone (NumPy's multiply and add, as _with_interior's); every other node
    # as to_plane gives it, not through the scale and back
    axes = _axis_map(centre, basis)
    if axes is not None and R.dtype == np.float64:
        from .foldfree_kernels import unscale_in_plane

        unscale_in_plane(Xs, R, moved, axes, shift, scale)       # the same, in one pass
    else:
        Xs *= scale
        Xs += shift
        kept = ~moved
        Xs[kept] = to_plane(R, centre, basis)[kept]
    stats["seconds"] = time.perf_counter() - t0
    return Xs, centre, basis, stats, moved
