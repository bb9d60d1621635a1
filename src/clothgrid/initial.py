"""Initial grids: ``zero``, ``average`` (the contour mean) and ``tfi`` (eq. 4)."""

from __future__ import annotations

import numpy as np

from .boundary import Boundary
from .errors import InputError

__all__ = ["INITS", "initial_grid", "boundary_grid", "transfinite"]


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


#: grids of at least this many nodes are interpolated by one Numba pass (:mod:`clothgrid.initial_kernels`,
#: the same bits; 17-24 -> ~3 ms at 1024^2)
KERNEL_NODES = 1 << 18


def transfinite(r: np.ndarray) -> np.ndarray:
    """Fill the interior of ``r`` (``(nu, nv, d)``, any ``d``) from its boundary by eq. (4), in place."""
    # Eq. (4) regrouped: (1-u) L'(v) + u R'(v) + (1-v) B(u) + v T(u), where L' and R' are the
    # left and right sides less the corners' linear interpolation; written into the interior.
    nu, nv = r.shape[:2]
    if nu * nv >= KERNEL_NODES and r.flags.c_contiguous and r.dtype == np.float64 and nu > 2 and nv > 2:
        from .initial_kernels import transfinite_into     # one pass, the same bits

        transfinite_into(r, np.linspace(0.0, 1.0, nu), np.linspace(0.0, 1.0, nv))
        return r
    u = np.linspace(0.0, 1.0, nu)[1:-1, None, None]
    v = np.linspace(0.0, 1.0, nv)[None, 1:-1, None]
    vv = v[0]
    left = r[0, 1:-1] - ((1 - vv) * r[0, 0] + vv * r[0, -1])
    right = r[-1, 1:-1] - ((1 - vv) * r[-1, 0] + vv * r[-1, -1])
    bottom, top = r[1:-1, 0][:, None], r[1:-1, -1][:, None]
    out = r[1:-1, 1:-1]
    step = max(1, (1 << 18) // max(1, out[0].size))   # blocks of rows: temporaries stay in cache
    for a in range(0, out.shape[0], step):
        ua, o = u[a:a + step], out[a:a + step]
        np.multiply(1 - ua, left[None], out=o)
        o += ua * right[None]
        o += (1 - v) * bottom[a:a + step]
        o += v * top[a:a + step]
    return r


INITS = {"zero": _zero, "average": _average, "tfi": transfinite}


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
