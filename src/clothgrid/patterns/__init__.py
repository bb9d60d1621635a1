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

from ..boundary import Boundary
from ..errors import BoundaryError, InputError
from .corners import (MIN_TURN_DEG, CornerCandidate, CornerChoice, choose_corners,
                      corner_candidates, turn_angles)
from .piece import Piece
from .sampling import DEFAULT_REL_TOL
from ..units import UNITS, parse_length

__all__ = [
    "Piece", "CornerCandidate", "CornerChoice", "choose_corners", "corner_candidates", "turn_angles",
    "piece_boundary", "piece_info", "nodes_for_edge_length", "grid_line_lengths",
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
        return Boundary.from_outline(choice.outline, list(choice.corners), name=piece.name)
    except BoundaryError as exc:
        raise BoundaryError(f"piece {piece.name!r}: {exc}") from None


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
