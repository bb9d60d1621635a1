"""Pattern files in: SVG, DXF (plain and AAMA/ASTM D6673) and GarmentCode JSON.

A pattern file holds one or more pieces; each reader returns a list of
:class:`Piece` (a closed counter-clockwise outline in millimetres with the
file's turn points and grain line). Then :func:`choose_corners` picks the
four grid corners, :func:`piece_boundary` makes the :class:`~clothgrid.Boundary`
and :func:`clothgrid.pipeline.generate_piece` the grid::

    from clothgrid.patterns import read_pieces
    from clothgrid.pipeline import generate_piece
    for piece in read_pieces("pattern.svg"):
        grid = generate_piece(piece, edge_length="5mm")
        grid.save(f"{piece.name}.obj")

Readers are chosen by extension from :data:`PATTERN_READERS` (``.svg``,
``.dxf``; ``.json`` files are GarmentCode patterns when they have a
``"pattern"`` object, else single-boundary files for
:func:`clothgrid.load_boundary`); add one with :func:`register_pattern_reader`.
See ``docs/patterns.md``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ..boundary import Boundary
from ..errors import BoundaryError, InputError
from ..readers import reader_for
from .corners import (MIN_TURN_DEG, CornerCandidate, CornerChoice, choose_corners,
                      corner_candidates, turn_angles)
from .piece import Piece
from .sampling import DEFAULT_REL_TOL
from ..units import UNITS, parse_length

__all__ = [
    "Piece", "CornerCandidate", "CornerChoice", "PATTERN_READERS", "register_pattern_reader",
    "read_pieces", "is_pattern_file", "choose_corners", "corner_candidates", "turn_angles",
    "piece_boundary", "piece_info", "nodes_for_edge_length", "load_single_boundary",
    "parse_length", "UNITS", "DEFAULT_EDGE_LENGTH_MM", "DEFAULT_REL_TOL", "MIN_TURN_DEG",
]

#: grid edge length used when neither nodes nor an edge length is asked for (mm)
DEFAULT_EDGE_LENGTH_MM = 10.0

PatternReader = Callable[..., list[Piece]]


def _read_svg(path: Path, **kw: Any) -> list[Piece]:
    from .svg import read_svg

    return read_svg(path, **kw)


def _read_dxf(path: Path, **kw: Any) -> list[Piece]:
    from .dxf import read_dxf

    return read_dxf(path, **kw)


def _read_json(path: Path, **kw: Any) -> list[Piece]:
    from .garmentcode import read_garmentcode

    return read_garmentcode(path, **kw)


#: extension (lower case, with the dot) -> ``reader(path, *, units=None, rel_tol=1e-7)``
PATTERN_READERS: dict[str, PatternReader] = {".svg": _read_svg, ".dxf": _read_dxf,
                                             ".json": _read_json}


def register_pattern_reader(ext: str, func: PatternReader) -> None:
    """Register ``func(path, *, units=None, rel_tol=1e-7) -> list[Piece]`` for ``ext``."""
    ext = ext.lower()
    PATTERN_READERS[ext if ext.startswith(".") else "." + ext] = func


def is_pattern_file(path: str | Path) -> bool:
    """Is ``path`` a pattern file (rather than a single-boundary JSON)?

    True for the registered extensions other than ``.json``; a ``.json`` file
    is a pattern when it parses to an object with a ``"pattern"`` member
    (GarmentCode). Unreadable files give False (the boundary reader then
    reports the problem).
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in PATTERN_READERS:
        return False
    if ext != ".json":
        return True
    try:
        text = path.read_text(encoding="utf-8")
        if '"pattern"' not in text:          # cheap: most boundary files never parse twice
            return False
        data = json.loads(text)
    except (OSError, ValueError):
        return False
    return isinstance(data, dict) and "pattern" in data


def read_pieces(path: str | Path, *, units: str | None = None,
                rel_tol: float = DEFAULT_REL_TOL) -> list[Piece]:
    """Read all pieces of a pattern file, the format chosen by extension.

    Parameters
    ----------
    path : str or Path
        An ``.svg``, ``.dxf`` or GarmentCode ``.json`` file.
    units : str, optional
        Read the file's coordinates in these units (``"mm"``, ``"cm"``,
        ``"in"``, ``"px"``, ...) instead of the ones it states; needed for a
        DXF that states none.
    rel_tol : float
        Largest distance of an outline chord from the true curve, relative to
        the piece's size (default ``1e-7``).

    Returns
    -------
    list of Piece
        In file order; outlines in millimetres, counter-clockwise.

    Raises
    ------
    InputError
        A missing or unreadable file, an unknown extension, malformed content
        (a truncated file), unknown units, no closed piece, or a piece with
        fewer than 4 points.
    """
    path = Path(path)
    reader = reader_for(path, PATTERN_READERS, "pattern")
    if units is not None:
        from ..units import unit_to_mm

        unit_to_mm(units, what="--units")
    if isinstance(rel_tol, bool) or not isinstance(rel_tol, (int, float)) \
            or not 0 < rel_tol <= 1e-2:
        raise InputError(f"rel_tol must be a number in (0, 0.01], not {rel_tol!r}")
    return reader(path, units=units, rel_tol=rel_tol)


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


def nodes_for_edge_length(boundary: Boundary, edge_length: float) -> tuple[int, int]:
    """``(nu, nv)`` so that grid edges along the sides are at most ``edge_length`` long.

    ``nu - 1`` edges on the longer of bottom and top, ``nv - 1`` on the longer
    of left and right, each at least 2 (3 nodes).
    """
    h = float(edge_length)
    if not (math.isfinite(h) and h > 0):
        raise InputError(f"the edge length must be positive and finite, not {edge_length!r}")
    b, r, t, l = boundary.side_lengths
    nu = max(3, math.ceil(max(b, t) / h * (1 - 1e-12)) + 1)
    nv = max(3, math.ceil(max(l, r) / h * (1 - 1e-12)) + 1)
    return nu, nv


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


def load_single_boundary(path: str | Path, **kwargs: Any) -> Boundary:
    """The :class:`~clothgrid.Boundary` of a pattern file with exactly one piece (automatic corners).

    (:func:`clothgrid.load_boundary` reads boundary JSON only; register this
    function with :func:`clothgrid.readers.register_reader` for ``.svg`` /
    ``.dxf`` to make it read single-piece pattern files too.)

    Raises
    ------
    InputError
        The file has several pieces (use :func:`read_pieces`), or any error
        of :func:`read_pieces`.
    """
    pieces = read_pieces(path, **kwargs)
    if len(pieces) != 1:
        names = ", ".join(p.name for p in pieces[:8]) + (", ..." if len(pieces) > 8 else "")
        raise InputError(f"{path}: has {len(pieces)} pieces ({names}); load them with "
                         "clothgrid.patterns.read_pieces() and piece_boundary(), or pick one with "
                         "--piece NAME")
    return piece_boundary(pieces[0])
