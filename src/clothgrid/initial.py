"""Initial grids: ``zero``, ``average`` (the contour mean) and ``tfi`` (eq. 4)."""

from __future__ import annotations

import numpy as np

from .boundary import Boundary
from .errors import InputError

__all__ = ["INITS", "initial_grid", "boundary_grid"]


def boundary_grid(boundary: Boundary) -> np.ndarray:
    """An ``(nu, nv, 3)`` array with the boundary nodes set and the interior zero."""
    nu, nv = boundary.shape
    r = np.zeros((nu, nv, 3))
    r[:, 0], r[:, -1] = boundary.bottom, boundary.top
    r[0, :], r[-1, :] = boundary.left, boundary.right
    return r


def _zero(r: np.ndarray) -> np.ndarray:
    return r


def _average(r: np.ndarray) -> np.ndarray:
    ring = np.concatenate([r[:, 0], r[:, -1], r[0, 1:-1], r[-1, 1:-1]])
    r[1:-1, 1:-1] = ring.mean(axis=0)
    return r


def _tfi(r: np.ndarray) -> np.ndarray:
    nu, nv = r.shape[:2]
    u = np.linspace(0.0, 1.0, nu)[:, None, None]
    v = np.linspace(0.0, 1.0, nv)[None, :, None]
    left, right = r[0][None], r[-1][None]
    bottom, top = r[:, 0][:, None], r[:, -1][:, None]
    corners = ((1 - u) * (1 - v) * r[0, 0] + u * (1 - v) * r[-1, 0]
               + (1 - u) * v * r[0, -1] + u * v * r[-1, -1])
    t = (1 - u) * left + u * right + (1 - v) * bottom + v * top - corners
    r[1:-1, 1:-1] = t[1:-1, 1:-1]
    return r


INITS = {"zero": _zero, "average": _average, "tfi": _tfi}


def initial_grid(boundary: Boundary, init: str = "tfi") -> np.ndarray:
    """The initial grid for a boundary (already resampled to the grid size).

    Parameters
    ----------
    boundary : Boundary
        Sides with ``nu`` points on bottom/top and ``nv`` on left/right.
    init : {"zero", "average", "tfi"}
        ``zero``: interior nodes at the origin; ``average``: at the mean of the
        contour nodes (the paper's Fig. 3); ``tfi``: transfinite (algebraic)
        interpolation of the four sides, eq. (4), with ``u = i/(nu-1)``,
        ``v = j/(nv-1)``.

    Returns
    -------
    numpy.ndarray
        ``(nu, nv, 3)`` float64, boundary nodes equal to the sides.
    """
    try:
        fill = INITS[init]
    except KeyError:
        raise InputError(f"unknown init {init!r}: use one of {', '.join(INITS)}") from None
    return fill(boundary_grid(boundary))
