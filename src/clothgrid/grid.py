"""The result of a grid generation: :class:`Grid`."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import numpy as np

from . import cloth, writers

__all__ = ["Grid", "quad_indices", "arc_length_uv"]


def quad_indices(nu: int, nv: int, *, flip: bool = False) -> np.ndarray:
    """Quads of an ``nu x nv`` structured grid as flat node indices ``i*nv + j``.

    Each quad is ``(i, j), (i+1, j), (i+1, j+1), (i, j+1)``: counter-clockwise in
    the (u, v) parameter plane, and so in the xy-plane for a counter-clockwise
    boundary. ``flip=True`` reverses the order (for clockwise pieces).

    Returns
    -------
    numpy.ndarray
        ``((nu-1)*(nv-1), 4)`` int64 array, cells ordered by ``i`` then ``j``.
    """
    q = np.empty((max(nu - 1, 0) * max(nv - 1, 0), 4), dtype=np.int64)
    return _quad_rows_into(q, nv, 0, max(nu - 1, 0), flip)


def _quad_rows_into(q: np.ndarray, nv: int, i0: int, i1: int, flip: bool) -> np.ndarray:
    """The quads of cell rows ``i0 <= i < i1`` (:func:`quad_indices`' order) written into ``q``."""
    q = q.reshape(i1 - i0, max(nv - 1, 0), 4)
    a = np.add.outer(np.arange(i0, i1, dtype=np.int64) * nv, np.arange(nv - 1, dtype=np.int64))
    offsets = (0, nv, nv + 1, 1)
    for corner, offset in enumerate(offsets[::-1] if flip else offsets):
        np.add(a, offset, out=q[..., corner])
    return q.reshape(-1, 4)


#: grids of at least this many nodes get their ``uv`` from one Numba pass
#: (:mod:`clothgrid.grid_kernels`, the same bits; 53 -> 5 ms at 1024^2)
KERNEL_NODES = 1 << 18


def arc_length_uv(points: np.ndarray) -> np.ndarray:
    """Normalised arc-length parameters of every node along its grid lines.

    ``uv[i, j, 0]`` is the length of grid line ``j`` from node ``(0, j)`` to
    ``(i, j)`` divided by the whole line's length; ``uv[i, j, 1]`` likewise
    along line ``i`` in v. On the boundary these are the sides' own
    normalised arc-length parameters.
    """
    nu, nv = points.shape[:2]
    uv = np.empty((nu, nv, 2))
    if nu * nv >= KERNEL_NODES and points.shape[2] == 3:
        from .grid_kernels import arc_length_uv_into

        flat = np.zeros(nv, dtype=bool), np.zeros(nu, dtype=bool)
        arc_length_uv_into(np.ascontiguousarray(points, dtype=np.float64), uv, *flat)
        for axis in (0, 1):
            if flat[axis].any():
                s = np.moveaxis(uv[..., axis], axis, 0)
                s[:, flat[axis]] = np.linspace(0.0, 1.0, s.shape[0])[:, None]
        return uv
    for axis in (0, 1):
        d = np.diff(points, axis=axis)
        seg = np.sqrt(sum(d[..., k] * d[..., k] for k in range(d.shape[-1])))    # left to right
        s = np.moveaxis(uv[..., axis], axis, 0)               # view: the parameter runs along axis 0
        s[0] = 0.0
        np.cumsum(np.moveaxis(seg, axis, 0), axis=0, out=s[1:])
        total = s[-1].copy()
        n = s.shape[0]
        flat = total <= 0                                     # a line of coincident nodes: uniform
        s /= np.where(flat, 1.0, total)
        if flat.any():
            s[:, flat] = np.linspace(0.0, 1.0, n)[:, None]
    return uv


class Grid:
    """A structured quad grid.

    Attributes
    ----------
    points : numpy.ndarray
        ``(nu, nv, 3)`` float64 node positions, indexed ``[i, j]`` (``i`` along u).
    uv : numpy.ndarray
        ``(nu, nv, 2)`` normalised arc-length parameters in ``[0, 1]``.
    quads : numpy.ndarray
        ``(M, 4)`` int64 quads, counter-clockwise, flat node index ``i*nv + j``.
    info : dict
        What produced the grid: ``solver``, ``backend``, ``iterations``,
        ``error_estimate`` (relative to the bounding-box diagonal), ``tol``,
        ``seconds``, ``nodes`` and more.
    dim : int
        2 if the boundary was planar input given in 2D, else 3.

    ``uv`` and ``quads`` not given are computed from ``points`` on first use
    (at 4096 x 4096 they take about 0.5 s and 800 MB together).
    For simulation, :attr:`pattern_uv` gives the flat rest shape,
    :meth:`springs` Provot's springs, :meth:`node_masses` lumped masses and
    :attr:`sides` / :attr:`corners` node indices for pinning and sewing (see
    :mod:`clothgrid.cloth`).
    """

    def __init__(self, points: np.ndarray, uv: np.ndarray | None = None, quads: np.ndarray | None = None,
                 info: dict[str, Any] | None = None, dim: int = 3, *, flip: bool = False):
        self.points = points
        self.info = {} if info is None else info
        self.dim = dim
        self._uv = uv
        self._quads = quads
        self._flip = flip
        self._quality: Any = None     # generate's measure of these points, where it made one (a Quality)

    @classmethod
    def from_points(cls, points: np.ndarray, *, info: dict | None = None, dim: int = 3,
                    flip: bool = False) -> "Grid":
        """A grid of an ``(nu, nv, 3)`` array of nodes (quads reversed if ``flip``: clockwise pieces)."""
        return cls(np.ascontiguousarray(points, dtype=np.float64), info=dict(info or {}), dim=dim, flip=flip)

    @property
    def uv(self) -> np.ndarray:
        if self._uv is None:
            self._uv = arc_length_uv(self.points)
        return self._uv

    @uv.setter
    def uv(self, value: np.ndarray) -> None:
        self._uv = value

    @property
    def quads(self) -> np.ndarray:
        if self._quads is None:
            nu, nv = self.shape
            self._quads = quad_indices(nu, nv, flip=self._flip)
        return self._quads

    @quads.setter
    def quads(self, value: np.ndarray) -> None:
        self._quads = value

    def quad_blocks(self, cells: int = 1 << 16) -> Iterator[np.ndarray]:
        """:attr:`quads` in consecutive blocks of whole cell rows (about ``cells`` quads each).

        Where the quads have not been made, each block is made in one reused buffer (so yield
        it to a writer, not to a list): a writer streams a 4096^2 grid's 537 MB of int64 quads
        in 2 MB. Where they have, the blocks are views of :attr:`quads`.
        """
        nu, nv = self.shape
        if nu < 2 or nv < 2:
            return
        rows, per = nu - 1, nv - 1
        step = max(1, cells // per)
        buf = None if self._quads is not None else np.empty((min(step, rows) * per, 4), dtype=np.int64)
        for i0 in range(0, rows, step):
            i1 = min(rows, i0 + step)
            if buf is None:
                assert self._quads is not None
                yield self._quads[i0 * per:i1 * per]
            else:
                yield _quad_rows_into(buf[:(i1 - i0) * per], nv, i0, i1, self._flip)

    @property
    def shape(self) -> tuple[int, int]:
        """``(nu, nv)``: nodes along u and along v."""
        return int(self.points.shape[0]), int(self.points.shape[1])

    @property
    def vertices(self) -> np.ndarray:
        """``(nu*nv, 3)`` node positions in flat index order ``i*nv + j``."""
        return self.points.reshape(-1, 3)

    def triangles(self, diagonal: str = "fixed") -> np.ndarray:
        """Split every quad into two counter-clockwise triangles.

        Parameters
        ----------
        diagonal : {"fixed", "alternate"}
            ``fixed`` cuts every quad along its ``a-c`` diagonal; ``alternate``
            alternates the diagonal in a checkerboard (less directional bias).

        Returns
        -------
        numpy.ndarray
            ``(2M, 3)`` int64 triangles.
        """
        q = self.quads
        if diagonal == "fixed":
            t = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]], axis=0)
            return t.reshape(2, -1, 3).transpose(1, 0, 2).reshape(-1, 3)
        if diagonal == "alternate":
            nu, nv = self.shape
            i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
            odd = ((i + j).ravel() % 2).astype(bool)
            first = np.where(odd[:, None], q[:, [0, 1, 3]], q[:, [0, 1, 2]])
            second = np.where(odd[:, None], q[:, [1, 2, 3]], q[:, [0, 2, 3]])
            return np.stack([first, second], axis=1).reshape(-1, 3)
        raise ValueError(f"diagonal must be 'fixed' or 'alternate', not {diagonal!r}")

    # ------------------------------------------------------------ simulation
    @property
    def planar(self) -> bool:
        """True for a planar piece (2D input, or a 3D boundary lying in a plane)."""
        return cloth.is_planar(self)

    @property
    def pattern_uv(self) -> np.ndarray:
        """``(nu, nv, 2)`` node positions in the piece's flat pattern coordinates (length units).

        For 2D input ``x, y``; for a planar 3D piece the coordinates in its
        plane; for a curved piece (:attr:`planar` False) the arc lengths along
        the grid lines. See :func:`clothgrid.cloth.pattern_uv`.
        """
        return cloth.pattern_uv(self)

    @property
    def sides(self) -> dict[str, np.ndarray]:
        """Flat node indices of the sides ``bottom``, ``right``, ``top``, ``left``, in their directions."""
        return cloth.sides(self)

    @property
    def corners(self) -> dict[str, int]:
        """Flat node indices of the corners ``bottom-left``, ``bottom-right``, ``top-right``, ``top-left``."""
        return cloth.corners(self)

    def springs(self):
        """Provot's structural, shear and bend springs with rest lengths (:class:`clothgrid.cloth.Springs`)."""
        return cloth.springs(self)

    def node_areas(self) -> np.ndarray:
        """``(nu*nv,)`` lumped rest area per node (a quarter of each adjacent cell), length unit squared."""
        return cloth.node_areas(self)

    def node_masses(self, density: float | str, length_unit: str | None = None) -> np.ndarray:
        """``(nu*nv,)`` lumped node masses in kg for an areal density (kg/m^2, or text like ``"150gsm"``).

        ``length_unit`` is the unit of the coordinates (default
        ``info["length_unit"]``, else metres); see :func:`clothgrid.cloth.node_masses`.
        """
        return cloth.node_masses(self, density, length_unit)

    def save(self, path: str | Path, **options: Any) -> Path:
        """Write the grid to ``path``, the format chosen by extension.

        See :func:`clothgrid.writers.save` for the formats and their
        ``options``. The file is written to a temporary name and renamed on
        success, so a failure leaves no partial file.
        """
        return writers.save(self, path, **options)

    def __repr__(self) -> str:
        nu, nv = self.shape
        keys = ("solver", "backend", "iterations", "error_estimate", "seconds")
        shown = ", ".join(f"{k}={self.info[k]!r}" for k in keys if k in self.info)
        return f"Grid({nu}x{nv}, {shown})"
