"""Heat conduction in a non-uniform medium on clothgrid's multigrid (the paper's future work).

The paper ends: the same solver, with four weights per node, solves other PDEs
such as heat transfer in a non-uniform medium. This module is that: steady

    -div(k grad T) = q

and transient

    rho c dT/dt = div(k grad T) + q

on a rectangle of ``nx x ny`` equal cells, in SI units: lengths in metres,
conductivity ``k`` in W/(m K), volumetric heat capacity ``rho c`` in
J/(m^3 K), source ``q`` in W/m^3, temperatures in degrees C (any affine scale
works: only differences enter), heat fluxes in W/m^2 and heat flows in W per
metre of depth (the problem is 2D: a slab of unit depth).

Discretisation: cell-centred finite volumes. The conductance of the face
between two cells is the harmonic mean of their conductivities times face
length over centre distance (``dy/dx * 2 k1 k2 / (k1 + k2)``): the exact
conductance of two half cells in series, so a layered wall is solved exactly.
These are the paper's "four weights per node": per-edge weights ``wu``,
``wv`` of :class:`clothgrid.weights.Weights` on a node array of
``(nx + 2) x (ny + 2)`` nodes whose interior nodes are the cells and whose
outer ring holds the boundary data:

- fixed temperature ``T_b``: the ring node holds ``T_b``, its conductance to
  the boundary cell is ``2 k dy/dx`` (the half cell);
- convection (``h`` in W/(m^2 K), ambient ``T_inf``): the ring node holds
  ``T_inf``, the conductance is the half cell and ``1/h`` in series,
  ``dy / (dx/(2k) + 1/h)``;
- fixed flux ``q_b`` (W/m^2 into the medium; insulated is ``q_b = 0``): no
  conductance, ``q_b dy`` enters the boundary cell's right-hand side.

The system ``A T = b`` is symmetric positive definite (an M-matrix). It is
solved by conjugate gradients preconditioned with one V(1,1) cycle of
black-box multigrid (:mod:`clothgrid.heat_multigrid`: Dendy's
operator-dependent interpolation, Galerkin coarse operators, full coarsening,
symmetric zebra line Gauss-Seidel; Numba kernels). The grid solver's multigrid (linear
interpolation) stalls on conductivity jumps of 10^4 (0.93 per cycle) and
needed 70-79 CG iterations on them as a preconditioner; black-box multigrid
needs 10-16 (docs/heat.md). The grid is oriented so that the line smoother
solves along the direction of the stronger coupling (``info["transposed"]``).

Time steps are implicit, backward Euler or Crank-Nicolson, with the mass
``rho c dx dy / dt`` on the diagonal of level 0.

Backends (``backend=``): ``cpu`` (Numba, float64; ``auto`` is the cpu),
``gl`` (fragment and compute shaders on float32 textures through headless EGL;
iterative refinement with the residual in float64 on the host) and ``cuda``
(numba.cuda kernels on CuPy arrays, float64). The hierarchy is built on the CPU
for all three and uploaded; the V-cycle and conjugate gradients are the same
functions (:mod:`clothgrid.heat_multigrid`) driving each backend's
:class:`~clothgrid.backends.protocol.HeatOps`.

Stopping: the relative residual ``||b - A T|| / ||b||`` (2-norm), recomputed
from the final temperature in float64, must be at most ``tol`` for
``info["converged"]``; ``error_bound=True`` adds a guaranteed bound on the
largest temperature error (kelvin) from the M-matrix barrier argument of
:mod:`clothgrid.solvers.bounds`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .errors import InputError, NotConvergedError
from .fields import finite_number as _finite
from .fields import load_field
from .heat_multigrid import HeatHierarchy, HeatSolver, Stencil5, numba_threads, padded
from .weights import Weights

__all__ = ["Side", "temperature", "flux", "convection", "INSULATED", "parse_side", "load_field", "HeatProblem",
           "HeatResult", "solve_steady", "solve_transient", "SCHEMES", "HEAT_OUTPUTS"]

#: Time-stepping schemes of :func:`solve_transient`.
SCHEMES = ("backward-euler", "crank-nicolson")
#: Output formats of :meth:`HeatResult.save`.
HEAT_OUTPUTS = (".npz", ".vts", ".png")
SIDES = ("left", "right", "bottom", "top")


# --------------------------------------------------------------------------- boundary conditions


@dataclass(frozen=True)
class Side:
    """A boundary condition on one side of the rectangle.

    Attributes
    ----------
    kind : {"temperature", "flux", "convection"}
    value : float
        The fixed temperature (C), the flux into the medium (W/m^2), or the
        ambient temperature (C) of convection.
    h : float
        Heat-transfer coefficient of convection, W/(m^2 K) (0 otherwise).
    """

    kind: str
    value: float
    h: float = 0.0

    @property
    def fixes(self) -> bool:
        """True when the side ties the temperature (fixed temperature or convection)."""
        return self.kind in ("temperature", "convection")

    def __str__(self) -> str:
        if self.kind == "temperature":
            return f"T={self.value:g}"
        if self.kind == "convection":
            return f"h={self.h:g},T={self.value:g}"
        return "insulated" if self.value == 0 else f"q={self.value:g}"


def temperature(value: float) -> Side:
    """A fixed temperature (C) on a side."""
    return Side("temperature", _finite(value, "a side's temperature"))


def flux(value: float) -> Side:
    """A fixed heat flux into the medium (W/m^2) on a side; 0 is insulated."""
    return Side("flux", _finite(value, "a side's heat flux"))


def convection(h: float, ambient: float) -> Side:
    """Convection to an ambient temperature ``ambient`` (C) with coefficient ``h`` (W/(m^2 K), > 0)."""
    hv = _finite(h, "the heat-transfer coefficient h")
    if hv <= 0:
        raise InputError(f"the heat-transfer coefficient h must be positive, not {h!r}")
    return Side("convection", _finite(ambient, "the ambient temperature"), hv)


#: An insulated side (zero flux).
INSULATED = flux(0.0)


def parse_side(text: str | float | Side | None) -> Side:
    """A :class:`Side` from its text form.

    ``"34"`` or ``"T=34"``: fixed temperature 34 C; ``"q=150"``: 150 W/m^2
    into the medium; ``"h=10,T=20"``: convection with ``h = 10 W/(m^2 K)`` to
    air at 20 C; ``"insulated"`` (or ``None``): no flux.
    """
    if text is None:
        return INSULATED
    if isinstance(text, Side):
        return text
    if isinstance(text, (int, float)):
        return temperature(text)
    s = str(text).strip().lower().replace(" ", "")
    if s in ("insulated", "adiabatic", "none"):
        return INSULATED
    parts = dict(p.split("=", 1) if "=" in p else ("t", p) for p in s.split(",") if p)
    keys = set(parts)
    try:
        if keys == {"t"}:
            return temperature(parts["t"])
        if keys == {"q"}:
            return flux(parts["q"])
        if keys == {"h", "t"}:
            return convection(parts["h"], parts["t"])
    except InputError as exc:
        raise InputError(f"invalid side {text!r}: {exc}") from None
    raise InputError(f"invalid side {text!r}: expected a temperature (34 or T=34), a flux (q=150, W/m2 "
                     "into the medium), convection (h=10,T=20) or 'insulated'")


# --------------------------------------------------------------------------- fields


# --------------------------------------------------------------------------- the problem


def _parse_size(size: Any) -> tuple[float, float]:
    if isinstance(size, str):
        parts = size.lower().replace(" ", "").split("x")
    else:
        parts = list(size) if isinstance(size, (tuple, list, np.ndarray)) else [size]
    if len(parts) != 2:
        raise InputError(f"size must be width x height in metres (e.g. 0.01x0.004), not {size!r}")
    w, h = (_finite(p, "the size") for p in parts)
    if w <= 0 or h <= 0:
        raise InputError(f"size must be positive, not {size!r}")
    return w, h


def load_grid_nodes(grid: Any, unit: str | None = None) -> np.ndarray:
    """Node coordinates ``(nu, nv, 3)`` in metres of a gridded piece.

    ``grid``: an array ``(nu, nv, 2|3)`` in ``unit`` (default metres), a :class:`clothgrid.Grid`
    (its points, in ``unit``, default mm), or the path of an ``.npz`` written by ``clothgrid
    generate`` (its ``points`` and ``length_unit``; ``unit`` overrides; mm when it says none).
    """
    from .units import unit_to_mm

    default = "m"
    if isinstance(grid, (str, Path)):
        path = Path(grid)
        try:
            with np.load(path, allow_pickle=False) as d:
                pts = np.asarray(d["points"], dtype=np.float64)
                saved = str(d["length_unit"]) if "length_unit" in d.files else ""
        except (OSError, ValueError, KeyError) as exc:
            raise InputError(f"{path}: not a grid .npz of clothgrid generate (points, length_unit): {exc}") from None
        default = saved or "mm"
    elif hasattr(grid, "points") and hasattr(grid, "shape"):
        pts, default = np.asarray(grid.points, dtype=np.float64), "mm"
    else:
        try:
            pts = np.asarray(grid, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError("the grid must be node coordinates (nu, nv, 2 or 3)") from None
    if pts.ndim != 3 or pts.shape[2] not in (2, 3) or min(pts.shape[:2]) < 2:
        raise InputError(f"the grid must be node coordinates (nu, nv, 2 or 3) with nu, nv >= 2, not shape "
                         f"{pts.shape}")
    if not np.isfinite(pts).all():
        raise InputError("the grid has non-finite coordinates")
    if pts.shape[2] == 2:
        pts = np.concatenate([pts, np.zeros(pts.shape[:2] + (1,))], axis=2)
    return pts * (unit_to_mm(unit or default, "grid unit") / 1000.0)


@dataclass(frozen=True)
class _CellGeometry:
    """Finite-volume geometry of the cells of a structured grid of nodes ``(nu, nv, 3)`` (metres).

    ``area`` (nx, ny) cell areas; ``centre`` (nx, ny, 3) the mean of each cell's corners;
    ``fu`` (nx + 1, ny) lengths of the faces across u (node column ``i``, rows ``j..j+1``) and
    ``du`` (nx + 1, ny, 2) the distances from the cell before and after each of them to the face's
    line (perpendicular: the two-point flux of an orthogonal grid); ``fv``, ``dv`` likewise across v.
    """

    area: np.ndarray
    centre: np.ndarray
    fu: np.ndarray
    du: np.ndarray
    fv: np.ndarray
    dv: np.ndarray

    @staticmethod
    def of(nodes: np.ndarray) -> "_CellGeometry":
        P = nodes
        d1, d2 = P[1:, 1:] - P[:-1, :-1], P[:-1, 1:] - P[1:, :-1]
        area = 0.5 * np.linalg.norm(np.cross(d1, d2), axis=-1)
        if (area <= 0).any():
            raise InputError("the grid has cells of no area (folded or degenerate)")
        c = 0.25 * (P[:-1, :-1] + P[1:, :-1] + P[1:, 1:] + P[:-1, 1:])
        nx, ny = area.shape

        def dist(cells: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
            t = b - a
            L = np.linalg.norm(t, axis=-1)
            t = t / np.maximum(L, 1e-300)[..., None]
            r = cells - a
            perp = r - (r * t).sum(-1)[..., None] * t
            return np.linalg.norm(perp, axis=-1)

        a_u, b_u = P[:, :-1], P[:, 1:]                      # faces across u: (nx + 1, ny)
        fu = np.linalg.norm(b_u - a_u, axis=-1)
        du = np.zeros((nx + 1, ny, 2))
        du[1:, :, 0] = dist(c, a_u[1:], b_u[1:])            # the cell before (i - 1) ...
        du[:-1, :, 1] = dist(c, a_u[:-1], b_u[:-1])         # ... and after (i)
        a_v, b_v = P[:-1, :], P[1:, :]                      # faces across v: (nx, ny + 1)
        fv = np.linalg.norm(b_v - a_v, axis=-1)
        dv = np.zeros((nx, ny + 1, 2))
        dv[:, 1:, 0] = dist(c, a_v[:, 1:], b_v[:, 1:])
        dv[:, :-1, 1] = dist(c, a_v[:, :-1], b_v[:, :-1])
        if (du[1:-1] <= 0).any() or (dv[:, 1:-1] <= 0).any() or (du[[0, -1]].sum(-1) <= 0).any() \
                or (dv[:, [0, -1]].sum(-1) <= 0).any():
            raise InputError("the grid has a cell centre on one of its faces (a degenerate cell)")
        return _CellGeometry(area, c, fu, du, fv, dv)


@dataclass
class HeatProblem:
    """Heat conduction on a rectangle of ``nx x ny`` equal cells (SI units).

    Parameters
    ----------
    conductivity : float or array_like
        ``k`` per cell, W/(m K), ``(nx, ny)`` (``[i, j]``, i along x), or a
        number (then ``cells`` gives the grid).
    size : (float, float) or str, optional
        Width (x) and height (y) in metres, or ``"0.01x0.004"``: a rectangle of equal cells.
    grid : array, Grid or path, optional
        Instead of ``size``: the cells of a gridded piece (:func:`load_grid_nodes`: node coordinates
        ``(nu, nv, 2|3)``, a :class:`clothgrid.Grid` or a ``clothgrid generate`` ``.npz``; ``grid_unit``
        their unit). The cells are the grid's ``(nu - 1) x (nv - 1)`` quads, ``left`` / ``right`` its
        ``i = 0`` / ``i = nu - 1`` sides, ``bottom`` / ``top`` ``j = 0`` / ``j = nv - 1``. How the geometry
        enters: a cell's area multiplies its source and heat capacity; the conductance of a face is
        ``L / (d_a / k_a + d_b / k_b)`` (face length ``L``, ``d`` the distance from each cell centre to
        the face's line: the two-point flux, exact for orthogonal grids; a skewed grid's cross-diffusion
        is left out); a fixed flux acts on the face lengths.
    left, right, bottom, top : Side, str or float, optional
        Boundary conditions (:func:`parse_side`); a side not given is insulated.
    source : float or array_like
        Heat source per cell, W/m^3 (default 0).
    capacity : float or array_like
        Volumetric heat capacity ``rho c`` per cell, J/(m^3 K) (transient only).
    cells : (int, int), optional
        ``(nx, ny)``, needed when every field is a number.
    """

    conductivity: Any
    size: Any = None
    left: Any = None
    right: Any = None
    bottom: Any = None
    top: Any = None
    source: Any = 0.0
    capacity: Any = None
    cells: tuple[int, int] | None = None
    grid: Any = None
    grid_unit: str | None = None
    k: np.ndarray = field(init=False, repr=False)
    nodes: np.ndarray | None = field(init=False, repr=False, default=None)
    geometry: _CellGeometry | None = field(init=False, repr=False, default=None)

    def __post_init__(self) -> None:
        if (self.size is None) == (self.grid is None):
            raise InputError("give the rectangle's size (size=..., --size) or a gridded piece (grid=..., --grid), "
                             "one of them")
        if self.grid is not None:
            self.nodes = load_grid_nodes(self.grid, self.grid_unit)
            self.geometry = _CellGeometry.of(self.nodes)
            gshape = self.geometry.area.shape
            if self.cells is not None and tuple(int(c) for c in self.cells) != gshape:
                raise InputError(f"cells {self.cells!r} do not match the grid's {gshape[0]} x {gshape[1]} cells")
            self.cells = gshape
            xy = self.nodes[..., :2].reshape(-1, 2)
            self.size = tuple(float(v) for v in np.ptp(xy, axis=0))
        else:
            self.size = _parse_size(self.size)
        for s in SIDES:
            setattr(self, s, parse_side(getattr(self, s)))
        shape = None if self.cells is None else tuple(int(c) for c in self.cells)
        if shape is not None and (len(shape) != 2 or min(shape) < 1):
            raise InputError(f"cells must be two counts >= 1, not {self.cells!r}")
        k = load_field(self.conductivity, name="conductivity", shape=shape)
        if isinstance(k, np.ndarray):
            shape = k.shape
        if shape is None:
            raise InputError("give the number of cells (cells=(nx, ny), --cells NXxNY) when the conductivity "
                             "is one number")
        self.cells = shape
        self.k = np.broadcast_to(k, shape).astype(np.float64) if not isinstance(k, np.ndarray) else k
        self.source = load_field(self.source, name="source", shape=shape, positive=False)
        if self.capacity is not None:
            self.capacity = load_field(self.capacity, name="heat capacity", shape=shape)

    # -- geometry
    @property
    def spacing(self) -> tuple[float, float]:
        """``(dx, dy)``, metres (a rectangle's; a gridded piece: its bounding box over the cells)."""
        return self.size[0] / self.cells[0], self.size[1] / self.cells[1]

    def cell_area(self) -> np.ndarray | float:
        """Area of every cell, m^2 (a number on a rectangle)."""
        if self.geometry is not None:
            return self.geometry.area
        dx, dy = self.spacing
        return dx * dy

    def side_faces(self, side: str) -> np.ndarray:
        """Lengths of the faces along ``side``, one per boundary cell (metres)."""
        if self.geometry is not None:
            g = self.geometry
            return {"left": g.fu[0], "right": g.fu[-1], "bottom": g.fv[:, 0], "top": g.fv[:, -1]}[side]
        (nx, ny), (dx, dy) = self.cells, self.spacing
        return np.full(ny, dy) if side in ("left", "right") else np.full(nx, dx)

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """``x``, ``y`` of the cell centres as ``(nx, ny)`` arrays (metres)."""
        if self.geometry is not None:
            return self.geometry.centre[..., 0].copy(), self.geometry.centre[..., 1].copy()
        (nx, ny), (dx, dy) = self.cells, self.spacing
        return np.meshgrid((np.arange(nx) + 0.5) * dx, (np.arange(ny) + 0.5) * dy, indexing="ij")

    @property
    def fixed(self) -> bool:
        """True when some side ties the temperature (else a steady problem is singular)."""
        return any(getattr(self, s).fixes for s in SIDES)

    # -- discretisation
    def boundary_conductance(self, side: str) -> np.ndarray:
        """Per boundary cell of ``side``: conductance to the side's ring node (W/(m K) per metre depth)."""
        (dx, dy), s = self.spacing, getattr(self, side)
        k = {"left": self.k[0], "right": self.k[-1], "bottom": self.k[:, 0], "top": self.k[:, -1]}[side]
        if self.geometry is not None:                   # centre-to-face distance, face length
            g = self.geometry
            half = {"left": g.du[0, :, 1], "right": g.du[-1, :, 0], "bottom": g.dv[:, 0, 1],
                    "top": g.dv[:, -1, 0]}[side]
            face = self.side_faces(side)
        else:
            normal, face = (dx, dy) if side in ("left", "right") else (dy, dx)
            half = normal / 2.0
        if s.kind == "temperature":
            return k * face / half
        if s.kind == "convection":
            return face / (half / k + 1.0 / s.h)
        return np.zeros_like(k)

    def system(self) -> tuple[Weights, np.ndarray, np.ndarray]:
        """The finite-volume system on the node array.

        Returns
        -------
        weights : Weights
            ``wu (nx+1, ny+2)``, ``wv (nx+2, ny+1)``: face conductances
            (harmonic means) between cells, and boundary conductances between
            the boundary cells and the ring nodes (zero along the ring).
        ring : numpy.ndarray
            ``(nx+2, ny+2)`` the ring nodes' temperatures (interior zero).
        rhs : numpy.ndarray
            ``(nx, ny)`` sources and fixed fluxes, W per metre depth.
        """
        (nx, ny), (dx, dy), k = self.cells, self.spacing, self.k
        wu, wv = np.zeros((nx + 1, ny + 2)), np.zeros((nx + 2, ny + 1))
        if self.geometry is not None:
            g = self.geometry
            wu[1:-1, 1:-1] = g.fu[1:-1] / (g.du[1:-1, :, 0] / k[:-1] + g.du[1:-1, :, 1] / k[1:])
            wv[1:-1, 1:-1] = g.fv[:, 1:-1] / (g.dv[:, 1:-1, 0] / k[:, :-1] + g.dv[:, 1:-1, 1] / k[:, 1:])
        else:
            wu[1:-1, 1:-1] = (dy / dx) * 2.0 * k[:-1] * k[1:] / (k[:-1] + k[1:])
            wv[1:-1, 1:-1] = (dx / dy) * 2.0 * k[:, :-1] * k[:, 1:] / (k[:, :-1] + k[:, 1:])
        wu[0, 1:-1] = self.boundary_conductance("left")
        wu[-1, 1:-1] = self.boundary_conductance("right")
        wv[1:-1, 0] = self.boundary_conductance("bottom")
        wv[1:-1, -1] = self.boundary_conductance("top")
        ring = np.zeros((nx + 2, ny + 2))
        rhs = np.broadcast_to(np.asarray(self.source, dtype=np.float64) * self.cell_area(), (nx, ny)).copy()
        for side, sl_ring, sl_cell in (("left", (0, slice(1, -1)), (0, slice(None))),
                                       ("right", (-1, slice(1, -1)), (-1, slice(None))),
                                       ("bottom", (slice(1, -1), 0), (slice(None), 0)),
                                       ("top", (slice(1, -1), -1), (slice(None), -1))):
            s = getattr(self, side)
            if s.fixes:
                ring[sl_ring] = s.value
            else:
                rhs[sl_cell] += s.value * self.side_faces(side)
        return Weights(wu=wu, wv=wv, kind="heat"), ring, rhs

    def mass(self) -> np.ndarray:
        """``rho c dx dy`` per cell (J/(m K) per metre depth)."""
        if self.capacity is None:
            raise InputError("a transient solve needs the heat capacity rho c (capacity=..., --capacity)")
        return np.broadcast_to(np.asarray(self.capacity) * self.cell_area(), self.cells).astype(np.float64)

    def heat_flows(self, T: np.ndarray) -> dict[str, float]:
        """Heat flowing into the medium through each side, and from the sources (W per metre depth)."""
        out: dict[str, float] = {}
        cells = {"left": T[0], "right": T[-1], "bottom": T[:, 0], "top": T[:, -1]}
        for side in SIDES:
            s = getattr(self, side)
            if s.fixes:
                out[side] = float(np.sum(self.boundary_conductance(side) * (s.value - cells[side])))
            else:
                out[side] = float(s.value * np.sum(self.side_faces(side)))
        out["source"] = float(np.sum(np.broadcast_to(self.source, self.cells) * self.cell_area()))
        return out


# --------------------------------------------------------------------------- the operator and its solver


class _Operator:
    """``A + diag(shift)`` of a problem on one orientation, with its black-box multigrid hierarchy and the
    backend's operations on it.

    ``transpose`` swaps x and y so that ``v``, along which the multigrid's
    line smoother solves, is the direction of the stronger coupling
    (:func:`_transpose_for`). ``scale`` multiplies the conductances (0.5 for
    Crank-Nicolson). ``backend``: the backend module (:func:`_backend`).
    """

    def __init__(self, weights: Weights, shift: np.ndarray | None, transpose: bool, scale: float = 1.0,
                 backend: Any = None):
        wu, wv = weights.wu * scale, weights.wv * scale
        if transpose:
            wu, wv = wv.T.copy(), wu.T.copy()
        self.wu, self.wv, self.transpose = wu, wv, transpose
        self.shift = None if shift is None else (shift.T.copy() if transpose else shift)
        self.stencil = Stencil5.from_weights(wu, wv, self.shift)
        self.shape = self.stencil.shape
        self.backend = backend
        self.refinements = 0
        self._mg: HeatHierarchy | None = None
        self._solver: HeatSolver | None = None

    @property
    def multigrid(self) -> HeatHierarchy:
        """The hierarchy, built on first use (on the CPU, whatever the backend)."""
        if self._mg is None:
            self._mg = HeatHierarchy(self.stencil)
        return self._mg

    @property
    def solver(self) -> HeatSolver:
        """The backend's operations on the hierarchy, made on first use."""
        if self._solver is None:
            if self.backend is None:
                self.backend = _backend("cpu")
            self._solver = HeatSolver(self.backend.heat_ops(self.multigrid), self.stencil)
        return self._solver

    def extra(self) -> dict[str, Any]:
        """The backend's keys for the info (``{}`` on the cpu)."""
        return {} if self._solver is None else self._solver.ops.extra()

    def close(self) -> None:
        """Free the backend's device objects."""
        if self._solver is not None:
            self._solver.close()
            self._solver = None

    def orient(self, a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(a.T) if self.transpose else a

    def apply(self, p: np.ndarray) -> np.ndarray:
        """``(A + shift) p`` for an interior array ``p`` (host, float64)."""
        return self.stencil.apply(padded(p))[1:-1, 1:-1]

    def diagonal(self) -> np.ndarray:
        return self.stencil.d[1:-1, 1:-1].copy()


def _pcg(op: _Operator, b: np.ndarray, x: np.ndarray, tol: float, max_iter: int) -> tuple[np.ndarray, int, float]:
    """Preconditioned CG on ``op x = b`` from ``x`` on the operator's backend
    (:meth:`clothgrid.heat_multigrid.HeatSolver.solve`).

    Returns ``(x, iterations, relative residual ||b - A x|| / ||b||)`` (the
    residual recomputed from ``x`` at the end: float64 on the host for gl).
    """
    xp = padded(x)
    it, rel, steps = op.solver.solve(padded(b), xp, tol, max_iter)
    op.refinements += steps
    return xp[1:-1, 1:-1].copy(), it, rel


def _error_bound(op: _Operator, b: np.ndarray, x: np.ndarray, max_iter: int) -> float:
    """Guaranteed ``max |T* - T|`` (kelvin) by the M-matrix barrier argument (``solvers/bounds.py``).

    ``A`` is an M-matrix (``A^-1 >= 0``). The barrier ``z`` (``A z ~ D 1``, solved until its
    Jacobi-scaled residual ``delta`` is at most 0.5) bounds ``A^-1 D 1 <= Z = z / (1 - delta)`` cell
    by cell, which gives the plain bound ``max |D^-1 r| max Z`` of the error ``e = A^-1 r``. That is
    50 to 10^6 times the true error where the residual changes sign from cell to cell (conjugate
    gradients') or peaks where the solution is insensitive to it. The bound returned instead takes
    two more solves on the same operator, any approximations: ``c ~ A^-1 r`` (the error itself) and,
    for what is left, ``r2 = r - A c``, ``y ~ A^-1 |r2|`` with its residual ``s = |r2| - A y``; then

        |e| = |c + A^-1 r2| <= |c| + A^-1 |r2| = |c| + y + A^-1 s <= |c| + y + max(s / D)+ Z

    cell by cell, whatever ``c`` and ``y`` are; its largest value is the true error's to a few per
    cent (``c`` solved to :data:`ERROR_SOLVE_TOL`, ``y`` to :data:`REMAINDER_SOLVE_TOL`). The residuals
    are computed in float64 with rounding errors of up to ``gamma (|b| + |A| |x|)`` (conductances
    spread over 10^8 make them matter at this sharpness): every residual above is taken with that
    allowance added (:data:`ROUNDING`). The smaller of the two bounds is returned."""
    d = op.diagonal()

    def apply_abs(v: np.ndarray) -> np.ndarray:
        """``|A| |v|`` (an M-matrix: ``|A| = 2 diag(A) - A``)."""
        a = np.abs(v)
        return 2.0 * d * a - op.apply(a)

    r = b - op.apply(x)
    slack = ROUNDING * (np.abs(b) + apply_abs(x))       # |r - fl(r)| <= slack
    step = float(np.max((np.abs(r) + slack) / d))
    z = np.zeros_like(d)
    for tol_z in (1e-3, 1e-5, 1e-7, 1e-9, 1e-11):   # a 2-norm tolerance does not bound the largest |r_i| / d_i
        z, _, _ = _pcg(op, d, z, tol_z, max_iter)
        delta = float(np.max((np.abs(d - op.apply(z)) + ROUNDING * (d + apply_abs(z))) / d))
        if delta <= 0.5:                            # A z >= (1 - delta) D 1, and A^-1 >= 0
            break
    if not delta < 1:
        return math.inf
    barrier = z / (1.0 - delta)                          # >= A^-1 D 1, cell by cell
    plain = step * float(np.max(barrier))
    if not step > 0:
        return plain
    c, _, _ = _pcg(op, r, np.zeros_like(d), ERROR_SOLVE_TOL, max_iter)
    left = np.abs(r - op.apply(c)) + slack + ROUNDING * (np.abs(r) + apply_abs(c))   # >= |r2| exactly
    y, _, _ = _pcg(op, left, np.zeros_like(d), REMAINDER_SOLVE_TOL, max_iter)
    rest = max(float(np.max((left - op.apply(y) + ROUNDING * (left + apply_abs(y))) / d)), 0.0)
    return min(plain, float(np.max(np.abs(c) + np.maximum(y, 0.0) + rest * barrier)))


#: Rounding allowance of a float64 residual ``b - A v`` of the 5-point operator, relative to
#: ``|b| + |A| |v|``: ``gamma_n = n u / (1 - n u)`` for the few terms a cell sums, taken generously.
ROUNDING = 16 * 2.0 ** -53
#: How far :func:`_error_bound` solves for the error itself (relative residual, 2-norm): the bound is then
#: the true error to about this share of it (plus the remainder's).
ERROR_SOLVE_TOL = 1e-4
#: ... and for the remainder's ``A^-1 |r - A c|``, a small term.
REMAINDER_SOLVE_TOL = 1e-2


def _backend(name: str) -> Any:
    """The backend module heat runs on: ``auto`` is the cpu (a device is used when asked for by name);
    an unknown name raises InputError, a device that cannot be used BackendUnavailableError (the reason)."""
    from .backends import get_backend

    return get_backend("cpu" if name == "auto" else name)


def _transpose_for(weights: Weights) -> bool:
    """Whether to swap x and y: the multigrid's line smoother solves along ``v``, which should be the
    direction of the stronger coupling (the larger total conductance between cells): with cells 100 times
    wider than tall, lines across the strong coupling took 500+ iterations, along it 6."""
    return float(np.sum(weights.wu[1:-1, 1:-1])) > float(np.sum(weights.wv[1:-1, 1:-1]))


@dataclass
class HeatResult:
    """A solved temperature field.

    Attributes
    ----------
    temperature : numpy.ndarray
        ``(nx, ny)`` cell temperatures, C (``[i, j]``, i along x).
    x, y : numpy.ndarray
        ``(nx, ny)`` cell-centre coordinates, metres.
    problem : HeatProblem
    info : dict
        ``solver``, ``backend``, ``iterations`` (PCG iterations, all steps),
        ``residual`` (relative, the last solve's), ``tol``, ``converged``,
        ``seconds``, ``levels``, ``transposed``; transient: ``scheme``, ``dt``,
        ``steps``, ``time``; with ``error_bound``: ``error_bound`` (kelvin).
    times, history : numpy.ndarray, optional
        Transient: the saved times (s) and ``(len(times), nx, ny)`` fields.
    """

    temperature: np.ndarray
    x: np.ndarray
    y: np.ndarray
    problem: HeatProblem
    info: dict[str, Any]
    times: np.ndarray | None = None
    history: np.ndarray | None = None

    def heat_flows(self) -> dict[str, float]:
        """Heat into the medium per side and from the sources, W per metre depth (:meth:`HeatProblem.heat_flows`)."""
        return self.problem.heat_flows(self.temperature)

    def save(self, path: str | Path) -> Path:
        """Write ``.npz`` (``temperature``, ``x``, ``y``, ``conductivity``, ``info``; transient also
        ``times``, ``history``), ``.vts`` (ParaView) or ``.png`` (field and isotherms), atomically."""
        from .writers import atomic_write, info_json, savez

        path = Path(path)
        ext = path.suffix.lower()
        if ext == ".png":
            return plot_temperature(self, path)
        if ext not in HEAT_OUTPUTS:
            raise InputError(f"unknown heat output format {ext or path.name!r}: use {', '.join(HEAT_OUTPUTS)}")
        with atomic_write(path) as fh:
            if ext == ".npz":
                extra = {} if self.times is None else {"times": self.times, "history": self.history}
                savez(fh, temperature=self.temperature, x=self.x, y=self.y, conductivity=self.problem.k,
                         info=np.array(info_json(self.info)), **extra)
            else:
                fh.write(_vts(self).encode("utf-8"))
        return path


def _b64(a: np.ndarray) -> str:
    import base64

    data = np.ascontiguousarray(a, dtype="<f8").tobytes()
    return base64.b64encode(np.uint64(len(data)).astype("<u8").tobytes() + data).decode("ascii")


def _vts(res: HeatResult) -> str:
    """VTK XML structured grid of the cell centres, point data temperature and conductivity."""
    from .writers import info_json

    nx, ny = res.temperature.shape
    pts = np.stack([res.x, res.y, np.zeros_like(res.x)], axis=-1).transpose(1, 0, 2).reshape(-1, 3)
    flat = lambda a: np.asarray(a).T.reshape(-1)   # VTK: x index fastest
    extent = f"0 {nx - 1} 0 {ny - 1} 0 0"
    comment = f"clothgrid heat {nx} x {ny} cell centres, metres and C; info: {info_json(res.info)}".replace("--", "- -")
    return "\n".join([
        '<?xml version="1.0"?>', f"<!-- {comment} -->",
        '<VTKFile type="StructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">',
        f'  <StructuredGrid WholeExtent="{extent}">', f'    <Piece Extent="{extent}">',
        '      <PointData Scalars="temperature">',
        f'        <DataArray type="Float64" Name="temperature" format="binary">{_b64(flat(res.temperature))}</DataArray>',
        f'        <DataArray type="Float64" Name="conductivity" format="binary">{_b64(flat(res.problem.k))}</DataArray>',
        "      </PointData>", "      <Points>",
        f'        <DataArray type="Float64" Name="Points" NumberOfComponents="3" format="binary">{_b64(pts)}</DataArray>',
        "      </Points>", "    </Piece>", "  </StructuredGrid>", "</VTKFile>", ""])


def plot_temperature(res: HeatResult, path: str | Path, *, title: str | None = None, isotherms: int = 12,
                     layers: bool = True) -> Path:
    """Draw the temperature field with isotherms (and the conductivity's interfaces) to an image file.

    Parameters
    ----------
    res : HeatResult
    path : str or Path
        Image file, format by extension; written atomically.
    title : str, optional
    isotherms : int
        Number of isotherm levels.
    layers : bool
        Outline where the conductivity changes (thin grey lines).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .writers import atomic_write

    path = Path(path)
    fmt = path.suffix[1:].lower() or "png"
    if fmt not in FigureCanvasAgg.get_supported_filetypes():
        raise InputError(f"cannot draw to {str(path)!r}: unknown image format {fmt!r}")
    w, h = res.problem.size
    scale, unit = (1e3, "mm") if max(w, h) < 1 else (1.0, "m")
    fig = Figure(figsize=(8, max(2.5, min(8, 8 * h / w + 1.2))), dpi=150)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    T = res.temperature
    if res.problem.nodes is not None:               # a gridded piece: its cells as they lie
        P = res.problem.nodes
        im = ax.pcolormesh(P[..., 0] * scale, P[..., 1] * scale, T, cmap="inferno", shading="flat")
        ax.set_aspect("equal")
    else:
        im = ax.imshow(T.T, origin="lower", extent=(0, w * scale, 0, h * scale), cmap="inferno", aspect="equal",
                       interpolation="nearest")
    if T.shape[0] > 1 and T.shape[1] > 1 and np.ptp(T) > 0:
        cs = ax.contour(res.x * scale, res.y * scale, T, levels=isotherms, colors="white", linewidths=0.6)
        ax.clabel(cs, fontsize=6, fmt="%.3g")
    k = res.problem.k
    if layers and k.shape[0] > 1 and k.shape[1] > 1 and np.ptp(k) > 0:
        ax.contour(res.x * scale, res.y * scale, np.log(k), levels=np.unique(np.log(k))[:-1] + 1e-9,
                   colors="0.6", linewidths=0.5, linestyles="dashed")
    fig.colorbar(im, ax=ax, label="temperature (C)", shrink=0.9)
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    if title:
        ax.set_title(title)
    with atomic_write(path) as fh:
        fig.savefig(fh, format=fmt, bbox_inches="tight")
    return path


def solve_steady(problem: HeatProblem, *, backend: str = "cpu", tol: float = 1e-8, max_iter: int = 500,
                 error_bound: bool = False, allow_unconverged: bool = False,
                 progress: Callable[[str], None] | None = None, threads: int | None = None) -> HeatResult:
    """Steady temperature: ``-div(k grad T) = q`` with the problem's boundary conditions.

    Parameters
    ----------
    problem : HeatProblem
    backend : {"cpu", "auto", "gl", "cuda"}
        Where the V-cycle and CG run (``auto``: the cpu). ``gl`` computes in
        float32 and refines in float64 on the host until the float64 residual
        meets ``tol`` (``info["refinements"]``); gl or cuda without its device
        raises :class:`~clothgrid.errors.BackendUnavailableError` with the reason.
    tol : float
        Relative residual ``||b - A T|| / ||b||`` to reach.
    max_iter : int
        Most conjugate-gradient iterations.
    error_bound : bool
        Also compute a guaranteed bound on the largest temperature error
        (kelvin; three more solves: the barrier, the error itself and a remainder,
        :func:`_error_bound`; within a few per cent of the true error above float64's rounding).
    allow_unconverged : bool
        Return the result instead of raising :class:`~clothgrid.errors.NotConvergedError`.
    progress : callable, optional
        Receives one line when done.
    threads : int, optional
        Numba threads for the solve (default: Numba's, all cores). On a
        machine shared with other jobs 1 can be faster: a parallel kernel waits
        for its slowest thread (docs/heat.md).

    Returns
    -------
    HeatResult
    """
    if not problem.fixed:
        raise InputError("a steady problem needs a side with a fixed temperature or convection: with every side "
                         "insulated or at a fixed flux the temperature is not determined")
    tol = _check_tol(tol)
    be = _backend(backend)
    with numba_threads(threads):
        t0 = time.perf_counter()
        weights, ring, rhs = problem.system()
        transpose = _transpose_for(weights)
        op = _Operator(weights, None, transpose, backend=be)
        try:
            b = op.orient(rhs) + _ring_load(op, ring)
            x, it, rel = _pcg(op, b, np.zeros_like(b), tol, max_iter)
            info = _info(problem, op, it, rel, tol)
            if error_bound:
                info["error_bound"] = _error_bound(op, b, x, max_iter)
            info.update(op.extra())
        finally:
            op.close()
        info["seconds"] = time.perf_counter() - t0
        T = op.orient(x)
        res = HeatResult(T, *problem.centres(), problem, info)
        if progress:
            progress(f"heat: steady, {problem.cells[0]} x {problem.cells[1]} cells, {it} CG iterations, "
                     f"relative residual {rel:.2e} (tol {tol:.1e}), {info['seconds']:.3f} s")
        if not info["converged"] and not allow_unconverged:
            raise NotConvergedError(f"heat: the relative residual {rel:.2e} is above tol {tol:.1e} after {it} "
                                    "iterations", grid=res)
        return res


def _check_tol(tol: float) -> float:
    t = _finite(tol, "tol")
    if not 0 < t < 1:
        raise InputError(f"tol must be between 0 and 1, not {tol!r}")
    return t


def _ring_load(op: _Operator, ring: np.ndarray) -> np.ndarray:
    """What the ring nodes' temperatures put on the boundary cells: ``sum w * T_ring``."""
    g, wu, wv = op.orient(ring), op.wu, op.wv
    load = np.zeros(op.shape)
    load[0] += wu[0, 1:-1] * g[0, 1:-1]
    load[-1] += wu[-1, 1:-1] * g[-1, 1:-1]
    load[:, 0] += wv[1:-1, 0] * g[1:-1, 0]
    load[:, -1] += wv[1:-1, -1] * g[1:-1, -1]
    return load


def _info(problem: HeatProblem, op: _Operator, it: int, rel: float, tol: float) -> dict[str, Any]:
    import numba

    name = op.backend.name
    precise = op.solver.ops.precise
    info = {"solver": "pcg-multigrid", "backend": name, "iterations": int(it), "residual": float(rel),
            "tol": float(tol), "converged": bool(rel <= tol), "levels": len(op.multigrid),
            "transposed": bool(op.transpose), "threads": numba.get_num_threads(), "cells": list(problem.cells),
            "size_m": list(problem.size), "sides": {s: str(getattr(problem, s)) for s in SIDES},
            "precision": "float64" if precise else "float32 (device), float64 residual (host)"}
    if not precise:
        info["refinements"] = op.refinements
    return info


def solve_transient(problem: HeatProblem, *, dt: float, steps: int, initial: Any = 20.0,
                    scheme: str = "crank-nicolson", save_every: int | None = None, backend: str = "cpu",
                    tol: float = 1e-8, max_iter: int = 500, allow_unconverged: bool = False,
                    progress: Callable[[str], None] | None = None, progress_every: int | None = None,
                    threads: int | None = None) -> HeatResult:
    """Implicit time steps of ``rho c dT/dt = div(k grad T) + q``.

    Parameters
    ----------
    problem : HeatProblem
        With ``capacity`` (``rho c``).
    dt : float
        Time step, s.
    steps : int
        Number of steps.
    initial : float or array_like
        Initial temperature (C), a number or ``(nx, ny)``.
    scheme : {"crank-nicolson", "backward-euler"}
        Second-order Crank-Nicolson or first-order (L-stable) backward Euler.
    save_every : int, optional
        Keep the field every this many steps in ``history`` (and the initial one).
    backend, tol, max_iter, allow_unconverged, threads
        As in :func:`solve_steady` (``tol`` per step).
    progress : callable, optional
        Receives a line per batch of ``progress_every`` steps (default: about 10 lines).

    Returns
    -------
    HeatResult
        The last field; ``times``/``history`` with ``save_every``.
    """
    if scheme not in SCHEMES:
        raise InputError(f"unknown scheme {scheme!r}: use one of {', '.join(SCHEMES)}")
    dt = _finite(dt, "dt")
    if dt <= 0:
        raise InputError(f"dt must be positive, not {dt!r}")
    if int(steps) != steps or steps < 1:
        raise InputError(f"steps must be an integer >= 1, not {steps!r}")
    steps = int(steps)
    tol = _check_tol(tol)
    be = _backend(backend)
    with numba_threads(threads):
        t0 = time.perf_counter()
        T = np.broadcast_to(load_field(initial, name="initial temperature", shape=problem.cells, positive=False),
                            problem.cells).astype(np.float64)
        weights, ring, rhs = problem.system()
        transpose = _transpose_for(weights)
        m = problem.mass() / dt
        half = scheme == "crank-nicolson"
        op = _Operator(weights, m, transpose, scale=0.5 if half else 1.0, backend=be)
        steady = Stencil5.from_weights(op.wu, op.wv)   # A alone (halved), for the explicit half of Crank-Nicolson
        mo = op.orient(m)
        load = op.orient(rhs) + _ring_load(op, ring) * (2.0 if half else 1.0)   # ring load of the unscaled A
        try:
            x = op.orient(T).copy()
            total, worst = 0, 0.0
            times, history = ([0.0], [T.copy()]) if save_every else (None, None)
            every = progress_every or max(1, steps // 10)
            t_batch = time.perf_counter()
            for n in range(1, steps + 1):
                b = mo * x + load
                if half:
                    b -= steady.apply(padded(x))[1:-1, 1:-1]   # (M/dt - A/2) T_n + b, op = M/dt + A/2
                x, it, rel = _pcg(op, b, x.copy(), tol, max_iter)
                total += it
                worst = max(worst, rel)
                if rel > tol and not allow_unconverged:
                    raise NotConvergedError(f"heat: step {n}: the relative residual {rel:.2e} is above tol {tol:.1e} "
                                            f"after {it} iterations")
                if save_every and n % save_every == 0:
                    times.append(n * dt)
                    history.append(op.orient(x).copy())
                if progress and (n % every == 0 or n == steps):
                    progress(f"heat: step {n}/{steps}, t = {n * dt:.4g} s, {total} CG iterations so far, "
                             f"T {x.min():.4g} to {x.max():.4g} C, {time.perf_counter() - t_batch:.2f} s")
                    t_batch = time.perf_counter()
            info = _info(problem, op, total, worst, tol)
            info.update(op.extra())
            info.update(scheme=scheme, dt=dt, steps=steps, time=steps * dt, seconds=time.perf_counter() - t0)
            info["residual_note"] = "largest relative residual over the steps"
        finally:
            op.close()
        out = op.orient(x)
        return HeatResult(out, *problem.centres(), problem, info,
                          times=None if times is None else np.asarray(times),
                          history=None if history is None else np.stack(history))
