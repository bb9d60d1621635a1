"""Draw a grid to an image file with matplotlib (Agg, no screen needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure

from .errors import InputError
from .grid import Grid
from .geometry import boundary_loop, plane_frame
from .quality import Quality
from .writers import atomic_write

__all__ = ["plot_grid", "draw_grid", "plane_coordinates", "CORNER_LABELS"]

#: Labels of the grid corners marked on a plot: nodes ``[0, 0]``, ``[-1, 0]``,
#: ``[-1, -1]``, ``[0, -1]`` (bottom-left, bottom-right, top-right, top-left).
CORNER_LABELS = ("BL", "BR", "TR", "TL")


def plane_coordinates(grid: Grid) -> np.ndarray:
    """``(nu, nv, 2)`` drawing coordinates of the nodes.

    2D grids use x and y; 3D grids are projected on the best-fit plane of all
    nodes, its axes chosen so that the boundary loop keeps its turning sense
    about the plane's normal oriented by the loop (counter-clockwise).
    """
    points = np.asarray(grid.points, dtype=np.float64)
    if grid.dim == 2:
        return points[..., :2].copy()
    centre, basis, _ = plane_frame(points, fit=points.reshape(-1, 3))
    return (points - centre) @ basis.T


def _subsample(n: int, max_lines: int) -> np.ndarray:
    """At most ``max_lines`` evenly spread indices in ``0 .. n-1``, always both ends."""
    count = min(n, max(int(max_lines), 2))
    return np.unique(np.round(np.linspace(0, n - 1, count)).astype(np.int64))


def plot_grid(grid: Grid, path: str | Path, *, title: str | None = None,
              quality: Quality | None = None, max_lines: int = 128) -> Path:
    """Draw the grid lines (boundary thicker, grid corners marked) and write the image to ``path``.

    Parameters
    ----------
    grid : Grid
        The grid; 3D grids are drawn projected on their best-fit plane.
    path : str or Path
        Output image; the format follows the extension (``.png``, ``.svg``,
        ``.pdf``, ...). Written to a temporary file and renamed on success.
    title : str, optional
        Title above the drawing.
    quality : Quality, optional
        When given, its folded cells are filled red.

    Notes
    -----
    The four grid corners (nodes ``[0, 0]``, ``[-1, 0]``, ``[-1, -1]``,
    ``[0, -1]``) are marked with blue dots labelled BL, BR, TR, TL: for a
    pattern piece they show which outline points were chosen as corners.
    max_lines : int
        Most grid lines drawn in each direction (evenly subsampled, boundary
        lines always included); each line keeps all its nodes.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    fmt = path.suffix[1:].lower() or "png"
    if fmt not in FigureCanvasAgg.get_supported_filetypes():
        known = ", ".join(sorted(FigureCanvasAgg.get_supported_filetypes()))
        raise InputError(f"cannot draw to {str(path)!r}: unknown image format {fmt!r} (known: {known})")
    fig = draw_grid(grid, title=title, quality=quality, max_lines=max_lines)
    with atomic_write(path) as fh:
        fig.savefig(fh, format=fmt, bbox_inches="tight")
    return path


def draw_grid(grid: Grid, *, title: str | None = None, quality: Quality | None = None,
              max_lines: int = 128) -> Figure:
    """The figure :func:`plot_grid` writes, for further drawing or saving by the caller.

    Parameters are those of :func:`plot_grid`. The grid corners are the
    ``PathCollection`` labelled ``"grid corners"``.
    """
    xy = plane_coordinates(grid)
    nu, nv = xy.shape[:2]

    fig = Figure(figsize=(8, 8), dpi=150)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    lines_v = [xy[i] for i in _subsample(nu, max_lines)]         # lines of constant i
    lines_u = [xy[:, j] for j in _subsample(nv, max_lines)]      # lines of constant j
    ax.add_collection(LineCollection(lines_v + lines_u, colors="0.35", linewidths=0.4))
    if quality is not None and quality.folded:
        i, j = np.asarray(quality.folded_cells, dtype=np.int64).T
        cells = np.stack([xy[i, j], xy[i + 1, j], xy[i + 1, j + 1], xy[i, j + 1]], axis=1)
        ax.add_collection(PolyCollection(cells, facecolors="red", edgecolors="darkred",
                                         linewidths=0.3, alpha=0.8, zorder=3))
    loop = boundary_loop(xy)
    ax.plot(*np.vstack([loop, loop[:1]]).T, color="black", linewidth=1.5, zorder=4)
    # The four grid corners: where the piece's outline was split into the four sides.
    corners = np.array([xy[0, 0], xy[-1, 0], xy[-1, -1], xy[0, -1]])
    ax.scatter(*corners.T, s=40, color="tab:blue", edgecolors="white", linewidths=0.8,
               zorder=5, label="grid corners")
    for (x, y), name in zip(corners, CORNER_LABELS):
        ax.annotate(name, (x, y), xytext=(4, 4), textcoords="offset points", fontsize=8,
                    color="tab:blue", zorder=6)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x" if grid.dim == 2 else "plane x")
    ax.set_ylabel("y" if grid.dim == 2 else "plane y")
    if title:
        ax.set_title(title)
    return fig
