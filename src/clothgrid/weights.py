"""Edge weights of the length functional (MATH.md, eqs. 1-2).

The functional is ``F(R) = 1/2 sum wu[i,j] |R[i+1,j]-R[i,j]|^2 + wv[i,j] |R[i,j+1]-R[i,j]|^2``
with ``wu`` of shape ``(nu-1, nv)`` (u-edges) and ``wv`` of shape ``(nu, nv-1)``
(v-edges). The paper's weights (eq. 2) give u-edges in row ``j`` the weight
``Lv[j]^2`` and v-edges in column ``i`` the weight ``Lu[i]^2``.

Weights are *separable* when ``wu[i, j] = cu[i] * dv[j]`` and
``wv[i, j] = du[i] * cv[j]``; the paper's and uniform weights are, and the
fast diagonalisation solver needs it.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError
from .fields import checked_field

__all__ = ["Weights", "WeightField", "paper_lengths", "make_weights", "interior_diagonal", "sample_field"]


class Weights:
    """Positive weights on every edge of an ``nu x nv`` grid.

    Attributes
    ----------
    wu : numpy.ndarray
        ``(nu-1, nv)`` weights of the u-edges ``(i, j)-(i+1, j)``.
    wv : numpy.ndarray
        ``(nu, nv-1)`` weights of the v-edges ``(i, j)-(i, j+1)``.
    kind : str
        ``"paper"``, ``"uniform"``, ``"field"`` (a :class:`WeightField`'s) or ``"custom"``.
    factors : tuple of numpy.ndarray or None
        ``(cu, dv, du, cv)`` with ``wu = cu[:, None] * dv[None, :]`` and
        ``wv = du[:, None] * cv[None, :]`` when the weights are separable.
        Separable weights may be given by their factors alone: ``wu`` and
        ``wv`` are then formed on first use (multigrid never needs them:
        268 MB at 4096 x 4096).
    """

    __slots__ = ("_wu", "_wv", "kind", "factors")

    def __init__(self, wu: np.ndarray | None = None, wv: np.ndarray | None = None, kind: str = "custom",
                 factors: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None):
        if (wu is None or wv is None) and factors is None:
            raise ValueError("Weights needs wu and wv, or the factors of separable weights")
        self._wu, self._wv, self.kind, self.factors = wu, wv, kind, factors

    def __repr__(self) -> str:
        nu, nv = self.shape
        return f"Weights({self.kind!r}, {nu}x{nv}, {'separable' if self.factors is not None else 'per edge'})"

    @property
    def wu(self) -> np.ndarray:
        if self._wu is None:
            assert self.factors is not None           # (the constructor's rule)
            cu, dv, _, _ = self.factors
            self._wu = np.outer(cu, dv)
        return self._wu

    @property
    def wv(self) -> np.ndarray:
        if self._wv is None:
            assert self.factors is not None
            _, _, du, cv = self.factors
            self._wv = np.outer(du, cv)
        return self._wv

    @property
    def shape(self) -> tuple[int, int]:
        """``(nu, nv)`` of the grid the weights belong to."""
        if self.factors is not None:
            return len(self.factors[2]), len(self.factors[1])
        return self.wv.shape[0], self.wu.shape[1]

    @property
    def unit_stencil(self) -> bool:
        """True when separable with constant ``cu`` and ``cv`` (paper, uniform).

        Then ``w[i, j] = i (nu-1-i) + j (nv-1-j)`` satisfies ``D^-1 A w = 1``
        exactly, which gives a free a-posteriori error bound
        (:mod:`clothgrid.solvers.bounds`).
        """
        if self.factors is None:
            return False
        cu, _, _, cv = self.factors
        return bool(np.all(cu == cu[0]) and np.all(cv == cv[0]))

    @classmethod
    def from_factors(cls, cu, dv, du, cv, kind: str) -> "Weights":
        """Separable weights from their four 1D factors."""
        cu, dv, du, cv = (np.ascontiguousarray(a, dtype=np.float64) for a in (cu, dv, du, cv))
        return cls(kind=kind, factors=(cu, dv, du, cv))


def interior_diagonal(wu: np.ndarray, wv: np.ndarray) -> np.ndarray:
    """``(nu-2, nv-2)`` diagonal of the SPD system: the sum of each interior node's four edge weights."""
    return wu[:-1, 1:-1] + wu[1:, 1:-1] + wv[1:-1, :-1] + wv[1:-1, 1:]


def edge_contrast(wu: np.ndarray, wv: np.ndarray) -> float:
    """The largest ratio between two neighbouring edges' weights (u-edges with u-edges, v-edges with
    v-edges, along either direction): 5-9 for the paper's weights and smooth fields times them, the
    jump itself (and more) for blocks. :func:`clothgrid.solvers.choose_solver` reads it."""
    r = 1.0
    for w in (np.asarray(wu, dtype=np.float64), np.asarray(wv, dtype=np.float64)):
        for a, b in ((w[1:], w[:-1]), (w[:, 1:], w[:, :-1])):
            if a.size:
                q = a / b
                r = max(r, float(q.max()), float(1.0 / q.min()))
    return r


def paper_lengths(n: int, k: float = 1.0) -> np.ndarray:
    """The paper's ``L`` of eq. (2), 0-based: ``0.01 + k (0.5 (n-1) - i)^2 / n``."""
    i = np.arange(n, dtype=np.float64)
    return 0.01 + k * (0.5 * (n - 1) - i) ** 2 / n


class WeightField:
    """A positive field over a piece's parameter square that scales its edge weights.

    The field's value at an edge's midpoint (in the grid's ``(u, v)``, both
    in ``[0, 1]``) multiplies the ``base`` weight of that edge: every edge
    gets its own weight (the paper's "four weights per node"), and the grid
    is finer where the field is larger (an edge of weight ``w`` shortens about
    as ``1 / sqrt(w)`` against its neighbours). Any resolution: the field is
    sampled bilinearly, so one field serves every grid size.

    Parameters
    ----------
    values : array_like
        ``(mu, mv)`` positive finite values at the centres of an ``mu x mv``
        raster over the square, indexed ``[i, j]``: ``i`` along u (the
        bottom side, left to right), ``j`` along v (the left side, bottom to
        top). :func:`clothgrid.fields.load_field` reads one from a ``.npy``
        file or a grayscale image (its top row along the top side).
    base : {"uniform", "paper"}
        The weights it multiplies.
    """

    __slots__ = ("values", "base")

    def __init__(self, values, base: str = "uniform"):
        arr = checked_field(values, name="the weight field")
        if base not in ("uniform", "paper"):
            raise InputError(f"a weight field scales 'uniform' or 'paper' weights, not {base!r}")
        self.values, self.base = arr, base

    def __repr__(self) -> str:
        return f"WeightField({self.values.shape[0]}x{self.values.shape[1]}, base={self.base!r})"


def sample_field(values: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear samples of a raster ``values`` ``(mu, mv)`` (values at its cells' centres over the
    unit square) at ``u[:, None], v[None, :]`` (each in ``[0, 1]``; constant beyond the outer
    centres): an ``(len(u), len(v))`` array."""
    def axis(t: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x = np.clip(np.asarray(t, dtype=np.float64) * m - 0.5, 0.0, m - 1.0)
        i0 = np.minimum(np.floor(x).astype(np.intp), max(m - 2, 0))
        return i0, np.minimum(i0 + 1, m - 1), x - i0

    i0, i1, fu = axis(u, values.shape[0])
    j0, j1, fv = axis(v, values.shape[1])
    rows = values[i0] * (1.0 - fu)[:, None] + values[i1] * fu[:, None]
    return rows[:, j0] * (1.0 - fv)[None, :] + rows[:, j1] * fv[None, :]


def make_weights(spec, nu: int, nv: int, k: float = 1.0) -> Weights:
    """Build :class:`Weights` for an ``nu x nv`` grid.

    Parameters
    ----------
    spec : {"paper", "uniform"} or tuple of array_like or WeightField or Weights
        ``"paper"`` (eq. 2 with parameter ``k``), ``"uniform"`` (all ones),
        ``(wu, wv)`` arbitrary positive per-edge weights of shapes
        ``(nu-1, nv)`` and ``(nu, nv-1)`` (the paper's "four weights per node"),
        or a :class:`WeightField` sampled at every edge's midpoint (kind ``"field"``).
    nu, nv : int
        Grid size.
    k : float
        The paper's ``k`` (anisotropy of the v weights); only for ``"paper"``.
    """
    if isinstance(spec, Weights):
        if spec.shape != (nu, nv):
            raise InputError(f"weights are for a {spec.shape[0]}x{spec.shape[1]} grid, not {nu}x{nv}")
        return spec
    if isinstance(spec, WeightField):
        base = make_weights(spec.base, nu, nv, k)
        u, v = np.linspace(0.0, 1.0, nu), np.linspace(0.0, 1.0, nv)
        um, vm = 0.5 * (u[:-1] + u[1:]), 0.5 * (v[:-1] + v[1:])
        return Weights(wu=base.wu * sample_field(spec.values, um, v),
                       wv=base.wv * sample_field(spec.values, u, vm), kind="field")
    if isinstance(spec, str):
        if spec == "paper":
            if not (np.isfinite(k) and k > 0):
                raise InputError(f"k must be a positive finite number, not {k!r}")
            from .limits import MAX_K, MIN_K

            if not MIN_K <= k <= MAX_K:
                raise InputError(f"k must be between {MIN_K:g} and {MAX_K:g}, not {k!r}: beyond, the "
                                 "squared weights of eq. 2 overflow or lose the boundary's influence")
            lu, lv = paper_lengths(nu), paper_lengths(nv, k)
            return Weights.from_factors(np.ones(nu - 1), lv**2, lu**2, np.ones(nv - 1), "paper")
        if spec == "uniform":
            return Weights.from_factors(np.ones(nu - 1), np.ones(nv), np.ones(nu), np.ones(nv - 1), "uniform")
        raise InputError(f"unknown weights {spec!r}: use 'paper', 'uniform' or a (wu, wv) pair of arrays")
    try:
        wu, wv = spec
    except (TypeError, ValueError):
        raise InputError("custom weights must be a pair (wu, wv) of arrays") from None
    wu = np.ascontiguousarray(wu, dtype=np.float64)
    wv = np.ascontiguousarray(wv, dtype=np.float64)
    for name, w, shape in (("wu", wu, (nu - 1, nv)), ("wv", wv, (nu, nv - 1))):
        if w.shape != shape:
            raise InputError(f"{name} must have shape {shape} for a {nu}x{nv} grid, not {w.shape}")
        if not np.all(np.isfinite(w)):
            raise InputError(f"{name} holds NaN or infinite values")
        if not np.all(w > 0):
            bad = np.argwhere(~(w > 0))[0]
            raise InputError(f"{name} must be positive everywhere; {name}[{bad[0]}, {bad[1]}] = {w[tuple(bad)]!r}")
    return Weights(wu=wu, wv=wv, kind="custom")
