"""Pattern files in: SVG, DXF (plain and AAMA/ASTM D6673) and GarmentCode JSON.

A pattern file holds one or more pieces; each reader returns a list of
:class:`Piece` (a closed counter-clockwise outline in millimetres with the
file's turn points and grain line). Then :func:`choose_corners` picks the
four grid corners, :func:`piece_boundary` makes the :class:`~clothgrid.Boundary`
and :func:`clothgrid.pipeline.generate_piece` the grid::

    from clothgrid.readers import read_pieces
    from clothgrid.pipeline import generate_piece
    for piece in read_pieces("pattern.svg"):
        grid = generate_piece(piece, edge_length="5mm")
        grid.save(f"{piece.name}.obj")

This package holds the formats' parsers (:mod:`.svg`, :mod:`.dxf`,
:mod:`.garmentcode`), the :class:`Piece`, the corner choice and the sampling of
curves; :mod:`clothgrid.readers` holds the one registry of input formats
(:data:`clothgrid.readers.READERS`). See ``docs/patterns.md``.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from ..boundary import Boundary, outline_points
from ..errors import BoundaryError, InputError
from ..geometry import signed_area
from .corners import (MIN_TURN_DEG, CornerCandidate, CornerChoice, choose_corners,
                      corner_candidates, turn_angles)
from .piece import Piece
from .sampling import DEFAULT_REL_TOL
from ..units import UNITS, parse_length

__all__ = [
    "Piece", "CornerCandidate", "CornerChoice", "choose_corners", "corner_candidates", "turn_angles",
    "piece_boundary", "outline_boundary", "piece_info", "nodes_for_edge_length", "grid_line_lengths",
    "parse_length", "UNITS", "DEFAULT_EDGE_LENGTH_MM", "DEFAULT_REL_TOL", "MIN_TURN_DEG",
]

#: grid edge length used when neither nodes nor an edge length is asked for (mm)
DEFAULT_EDGE_LENGTH_MM = 10.0


def piece_boundary(piece: Piece, corners: Sequence[int] | None = None, near: Any = None, *,
                   choice: CornerChoice | None = None) -> Boundary:
    """The four-sided :class:`~clothgrid.Boundary` of ``piece`` (2D, mm).

    Parameters
    ----------
    piece : Piece
    corners, near :
        As for :func:`choose_corners` (default: automatic).
    choice : CornerChoice, optional
        A choice already made (then ``corners`` and ``near`` are ignored).

    Raises
    ------
    BoundaryError
        Corners that are not in counter-clockwise order or an outline that
        crosses itself; the message names the piece.
    """
    if choice is None:
        choice = choose_corners(piece, corners, near)
    try:
        return Boundary.from_outline(choice.outline, list(choice.corners), name=piece.name, sampled=True)
    except BoundaryError as exc:
        raise BoundaryError(f"piece {piece.name!r}: {exc}") from None


def outline_boundary(points: Any, *, name: str | None = None) -> tuple[Boundary, CornerChoice]:
    """The four-sided :class:`~clothgrid.Boundary` of a plain closed outline (a region given
    without corners), its corners chosen as a pattern piece's are (:func:`choose_corners`).

    The outline's own points are the candidates (every point where it turns by at least
    :data:`MIN_TURN_DEG`); a smooth one (a circle) is cut into four sides of equal length. The
    choice does not depend on the outline's units: it is made on the outline scaled by a power of
    two to about a metre across (exact, so the outline's points come back bit for bit), as if in
    millimetres.

    Parameters
    ----------
    points : array_like
        ``(N, 2)`` points, or ``(N, 3)`` with one ``z`` for all, of the closed outline, the first
        not repeated (a last point equal to the first is dropped). A clockwise outline is taken
        in reverse, so the boundary turns counter-clockwise.
    name : str, optional
        The region's name (for messages and output files).

    Returns
    -------
    boundary : Boundary
    choice : CornerChoice
        The corners chosen (indices into ``choice.outline``, the outline counter-clockwise, in
        the scaled units, with any point the choice inserted) and how.

    Raises
    ------
    BoundaryError
        Invalid points, a ``z`` that varies, an outline that encloses no area, crosses itself, or
        whose chosen sides are not a valid boundary.
    """
    pts = outline_points(points)
    if pts.shape[1] == 3 and np.any(pts[:, 2] != pts[0, 2]):
        raise BoundaryError("automatic corners need an outline in a plane z = constant; this one's z "
                            "varies: give its four corners ('corners')")
    xy = pts[:, :2]
    if len(xy) < 3:
        raise BoundaryError(f"the outline needs at least 3 points, got {len(xy)}")
    area = signed_area(xy)
    if not abs(area) > 0:
        raise BoundaryError("the outline encloses no area")
    if area < 0:
        pts, xy = pts[::-1], xy[::-1]
    size = float(np.linalg.norm(np.ptp(xy, axis=0)))
    scale = 2.0 ** round(math.log2(1000.0 / size))
    piece = Piece(name or "outline", np.ascontiguousarray(xy * scale), np.arange(len(xy)), np.zeros(0, np.int64),
                  source="outline")
    try:
        choice = choose_corners(piece)
    except InputError as exc:
        raise BoundaryError(f"could not choose four corners: {exc}") from None
    out = choice.outline / scale
    if pts.shape[1] == 3:
        out = np.column_stack([out, np.full(len(out), pts[0, 2])])
    return Boundary.from_outline(out, list(choice.corners), name=name, sampled=True), choice


def grid_line_lengths(boundary: Boundary, samples: int = 33) -> tuple[float, float]:
    """Typical lengths of the grid's u- and v-lines, from a coarse transfinite grid.

    The sides are resampled to ``samples`` points each and the interior filled
    by eq. (4); the answer is the geometric mean of the lengths of the
    ``samples`` u-lines (bottom side, top side and the lines between) and of
    the v-lines. Interior lines count: a piece that is longer inside than
    along its sides (a sleeve cap between two corners) gets its length from them.
    """
    from ..initial import boundary_grid, transfinite
    from ..quality import line_lengths

    return line_lengths(transfinite(boundary_grid(boundary.resampled(samples, samples))))


def nodes_for_edge_length(boundary: Boundary, edge_length: float) -> tuple[int, int]:
    """``(nu, nv)`` so that grid edges are about ``edge_length`` long.

    ``nu - 1`` edges on the typical length of a u-line, ``nv - 1`` on that of
    a v-line (:func:`grid_line_lengths`: geometric means over a coarse
    transfinite grid), rounded up, each at least 2 (3 nodes). Balancing the
    two directions on their typical lines rather than on their longest side
    keeps the spread of edge lengths (longest over shortest) small: a piece
    whose bottom side is 2.5 times its top no longer gets u-edges half as long
    as its v-edges. Edges on a side longer than the typical line are longer
    than ``edge_length``; ``quality`` reports the shortest and longest.
    """
    h = float(edge_length)
    if not (math.isfinite(h) and h > 0):
        raise InputError(f"the edge length must be positive and finite, not {edge_length!r}")
    from ..errors import SizeError
    from ..limits import MAX_NODES_PER_SIDE

    counts = []
    for line in grid_line_lengths(boundary):
        edges = line / h * (1 - 1e-12)
        if not edges < MAX_NODES_PER_SIDE:          # also inf: an edge length of 1e-320
            raise SizeError(f"an edge length of {edge_length!r} puts {edges:.3g} edges along grid lines "
                            f"{line:.6g} long, more than the limit of {MAX_NODES_PER_SIDE:,} nodes "
                            "along a side: use a longer edge length")
        counts.append(max(3, math.ceil(edges) + 1))
    return counts[0], counts[1]


def piece_info(piece: Piece, choice: CornerChoice, edge_length: float | None) -> dict[str, Any]:
    """What ``grid.info["piece"]`` holds: name, units, corners, grain line, notes."""
    w, h = piece.extent
    return {
        "name": piece.name,
        "units": "mm",
        "file_units": piece.units,
        "source": piece.source,
        "size": [w, h],
        "perimeter": piece.perimeter,
        "outline_points": len(piece.outline),
        "sampling_tolerance": piece.tolerance,
        "edge_length": edge_length,
        "corners": choice.as_dict(),
        "grain_line": None if piece.grain_line is None else np.asarray(piece.grain_line).tolist(),
        "notes": list(piece.notes),
        "meta": {k: v for k, v in piece.meta.items() if v is not None},
    }
