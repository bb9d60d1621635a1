"""Plane geometry shared by the boundary, quality, plotting and fold-free code."""

from __future__ import annotations

import numpy as np

__all__ = ["PLANAR_TOL", "boundary_loop", "signed_area", "vector_area", "best_fit_plane", "plane_axes", "plane_frame"]

#: A point set is planar when no point is farther than this (relative to its size) from its plane.
PLANAR_TOL = 1e-9


def boundary_loop(points: np.ndarray) -> np.ndarray:
    """The boundary nodes of an ``(nu, nv, d)`` grid as one closed loop, each once.

    Bottom (``i`` increasing, ``j = 0``), right (``j`` increasing at ``i = nu-1``),
    top reversed, left reversed: counter-clockwise for a counter-clockwise piece.
    """
    return np.concatenate([points[:-1, 0], points[-1, :-1], points[:0:-1, -1], points[0, :0:-1]])


def signed_area(loop: np.ndarray) -> float:
    """Signed area of a closed polygon from its first two coordinates (positive: counter-clockwise)."""
    p = np.asarray(loop)
    q = np.roll(p, -1, axis=0)
    return 0.5 * float((p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]).sum())


def vector_area(loop: np.ndarray) -> np.ndarray:
    """Vector area ``1/2 sum p_k x p_{k+1}`` of a closed 3D polygon ``(n, 3)``."""
    p = loop - loop.mean(axis=0)
    return 0.5 * np.cross(p, np.roll(p, -1, axis=0)).sum(axis=0)


def best_fit_plane(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares plane through ``(n, 3)`` points.

    Returns
    -------
    centre, normal, distance : numpy.ndarray, numpy.ndarray, float
        A point of the plane, its unit normal (sign arbitrary) and the largest
        distance of a point from it.
    """
    centre = pts.mean(axis=0)
    d = pts - centre
    _, vecs = np.linalg.eigh(d.T @ d)
    normal = vecs[:, 0]
    return centre, normal, float(np.abs(d @ normal).max(initial=0.0))


def plane_axes(normal: np.ndarray) -> np.ndarray:
    """``(2, 3)`` orthonormal in-plane axes ``e1, e2`` with ``e1 x e2 = normal`` (a unit vector)."""
    e1 = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(normal, e1)])


def plane_frame(points: np.ndarray, fit: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """The oriented best-fit plane of a grid: centre, in-plane axes and the farthest distance from it.

    Parameters
    ----------
    points : numpy.ndarray
        ``(nu, nv, 3)`` nodes.
    fit : numpy.ndarray, optional
        ``(n, 3)`` points the plane is fitted to (default: the boundary loop).

    Returns
    -------
    centre : (3,) array
    basis : (2, 3) array
        Orthonormal in-plane axes, chosen so that the boundary loop (bottom,
        right, top reversed, left reversed) turns counter-clockwise in the
        coordinates ``(p - centre) @ basis.T``.
    distance : float
        The largest distance of a fitted point from the plane.
    """
    loop = boundary_loop(points)
    centre, normal, dist = best_fit_plane(loop if fit is None else fit)
    if vector_area(loop) @ normal < 0:
        normal = -normal
    return centre, plane_axes(normal), dist
