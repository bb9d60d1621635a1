"""Read the input files: boundary JSON, pattern files (SVG, DXF, GarmentCode JSON), grids (NPZ).

One registry, :data:`READERS`, chooses the reader by file extension (and a
``.json`` file by its content: GarmentCode patterns have a ``"pattern"``
object); add a format with :func:`register_reader`. :func:`read_input` gives
what a file holds, a :class:`~clothgrid.boundary.Boundary` or a list of
:class:`~clothgrid.patterns.Piece`; :func:`load_boundary` and
:func:`read_pieces` ask for one of the two. The pattern formats' parsers live in
:mod:`clothgrid.patterns`. Every error names the file and is an
:class:`~clothgrid.errors.InputError` (a :class:`~clothgrid.errors.BoundaryError`
when the file is readable but its curves are not a valid piece).

JSON (``.json``) is one object in either of two forms, with an optional
``name`` (default: the file's stem)::

    {"bottom": [[x, y], ...], "right": [...], "top": [...], "left": [...]}
    {"outline": [[x, y], ...], "corners": [i_bl, i_br, i_tr, i_tl]}

the second being the format of the test regions (see ``MATH.md``).
"""

from __future__ import annotations

import inspect
import json
from dataclasses import replace

import numpy as np
from pathlib import Path
from typing import Any, Callable

from .boundary import SIDES, Boundary
from .errors import BoundaryError, InputError, PiecesError
from .grid import Grid
from .limits import check_input_file, load_json, read_json_file
from .patterns import Piece, piece_boundary
from .patterns.piece import Pieces, pattern_pieces, split_pinched
from .patterns.sampling import DEFAULT_REL_TOL
from .units import unit_to_mm

__all__ = ["READERS", "register_reader", "read_input", "read_pieces", "load_boundary",
           "load_single_boundary", "read_json", "load_npz"]

Reader = Callable[..., "Boundary | list[Piece]"]


def read_json(path: str | Path) -> Boundary:
    """Read a boundary from a JSON file: four sides, or a closed outline and its four corners
    (without ``corners``, chosen automatically: :func:`clothgrid.patterns.outline_boundary`)."""
    path = Path(path)
    data = read_json_file(path)
    if not isinstance(data, dict):
        raise InputError(f"{path}: the JSON must be an object with keys bottom/right/top/left or "
                         f"outline/corners, not {type(data).__name__}")
    name = data.get("name", path.stem)
    if not isinstance(name, str):
        raise InputError(f"{path}: 'name' must be a string, not {type(name).__name__}")
    has_sides = [s for s in SIDES if s in data]
    try:
        if "outline" in data:
            if has_sides:
                raise InputError(f"{path}: give either 'outline' and 'corners' or the four sides "
                                 f"bottom/right/top/left, not both (found 'outline' and "
                                 f"{', '.join(repr(s) for s in has_sides)})")
            if data.get("corners") is None:       # chosen as a pattern piece's are
                if not isinstance(data["outline"], list):
                    raise InputError(f"{path}: 'outline' must be a list, not {type(data['outline']).__name__}")
                from .patterns import outline_boundary

                return outline_boundary(data["outline"], name=name)[0]
            for key in ("outline", "corners"):
                if not isinstance(data[key], list):
                    raise InputError(f"{path}: '{key}' must be a list, not "
                                     f"{type(data[key]).__name__}")
            return Boundary.from_outline(data["outline"], data["corners"], name=name)
        if has_sides:
            missing = [s for s in SIDES if s not in data]
            if missing:
                raise InputError(f"{path}: missing side(s) {', '.join(missing)}; a sides file "
                                 "needs all four of bottom, right, top, left (lists of points)")
            for s in SIDES:
                if not isinstance(data[s], list):
                    raise InputError(f"{path}: '{s}' must be a list of points, not "
                                     f"{type(data[s]).__name__}")
            return Boundary.from_sides(*(data[s] for s in SIDES), name=name)
    except BoundaryError as exc:
        raise BoundaryError(f"{path}: {exc}") from None
    keys = ", ".join(repr(k) for k in data) or "none"
    raise InputError(f"{path}: expected the keys 'bottom', 'right', 'top', 'left' (four sides) or "
                     f"'outline' and 'corners' (a region); found {keys}")


def _read_json_input(path: Path, **kw: Any) -> "Boundary | list[Piece]":
    """A ``.json`` file: a GarmentCode pattern when it has a ``"pattern"`` object, else a boundary."""
    line = kw.pop("line", None)
    if _is_garmentcode(path):
        from .patterns.garmentcode import read_garmentcode

        pieces = read_garmentcode(path, **kw)
        for p in pieces:            # GarmentCode panels are the sewn shape: no seam allowance
            p.meta.setdefault("line", "sew")
        if line == "cut":
            from dataclasses import replace

            pieces = Pieces([replace(p, notes=p.notes + ("line: sew (a GarmentCode panel has no cut "
                                                         "line; --line cut does not apply)",))
                             for p in pieces], getattr(pieces, "failed", ()),
                            getattr(pieces, "skipped", ()))
        return pieces
    return read_json(path)


def _read_svg(path: Path, **kw: Any) -> list[Piece]:
    from .patterns.svg import read_svg   # svgpathtools: only when an SVG is read

    return read_svg(path, **kw)


def _read_dxf(path: Path, **kw: Any) -> list[Piece]:
    from .patterns.dxf import read_dxf   # ezdxf: only when a DXF is read

    return read_dxf(path, **kw)


def _is_garmentcode(path: Path) -> bool:
    try:
        text = path.read_text(encoding="utf-8")
        if '"pattern"' not in text:          # cheap: most boundary files never parse twice
            return False
        data = load_json(text, str(path))
    except (OSError, ValueError):            # (InputError is a ValueError: reported by the reader)
        return False
    return isinstance(data, dict) and "pattern" in data


#: The one registry of input formats: file extension (lower case, with the dot) ->
#: ``reader(path, **options)`` returning a :class:`Boundary` (a boundary file) or a list of
#: :class:`~clothgrid.patterns.Piece` (a pattern file). Pattern readers take ``units`` and
#: ``rel_tol``.
READERS: dict[str, Reader] = {".json": _read_json_input, ".svg": _read_svg, ".dxf": _read_dxf}


def register_reader(ext: str, func: Reader) -> None:
    """Register ``func(path, **options) -> Boundary | list[Piece]`` as the reader for ``ext`` (e.g. ``".svg"``)."""
    ext = ext.lower()
    READERS[ext if ext.startswith(".") else "." + ext] = func


def reader_for(path: Path, registry: dict | None = None, kind: str = "input"):
    """The reader in ``registry`` (default :data:`READERS`) for ``path``'s extension, after checking the file.

    Raises :class:`InputError` naming the problem for a missing file, a
    directory, or an extension no reader is registered for.
    """
    registry = READERS if registry is None else registry
    check_input_file(path, kind)    # a regular file (not /dev/zero, a FIFO), not too big
    reader = registry.get(path.suffix.lower())
    if reader is None:
        raise InputError(f"{path}: unknown {kind} file type {path.suffix or '(no extension)'!r}; "
                         f"known: {', '.join(sorted(registry))}")
    return reader


def read_input(path: str | Path, *, units: str | None = None, rel_tol: float | None = None,
               line: str | None = None, include: Any = None) -> "Boundary | list[Piece]":
    """What the file holds: a :class:`Boundary` (boundary JSON) or the pieces of a pattern file.

    ``units``, ``rel_tol`` and ``line`` go to pattern readers, ``include``
    names skipped outlines to grid all the same (see :func:`read_pieces`). A
    pattern file gives a :class:`~clothgrid.patterns.piece.Pieces` list
    (the skipped outlines in ``.skipped``, the pieces that cannot be made in ``.failed``).
    """
    path = Path(path)
    if line is not None:
        from .patterns.annotations import LINES     # (5 ms to import: only when a line is asked for)

        if line not in LINES:
            raise InputError(f"--line {line!r}: use 'sew' or 'cut'")
    reader = reader_for(path, READERS, "input")
    options = {k: v for k, v in (("units", units), ("rel_tol", rel_tol), ("line", line))
               if v is not None}
    if options and reader not in (_read_svg, _read_dxf, _read_json_input):   # (a boundary JSON ignores them)
        params = inspect.signature(reader).parameters      # a registered reader takes what it names
        if not any(p.kind is p.VAR_KEYWORD for p in params.values()):
            options = {k: v for k, v in options.items() if k in params}
    got = reader(path, **options)
    if not isinstance(got, list):               # a Boundary (a boundary JSON)
        return got
    if not isinstance(got, Pieces):             # a registered reader's plain list
        got = Pieces(got)
    got = _split_pinched(got.including(include, where=f"{path}: "))
    if not got:
        listed = "; ".join(f"{s.name}: {s.reason}" for s in got.skipped[:6])
        if got.failed:                          # the failures, and the outlines taken for annotations
            try:
                pattern_pieces([], got.failed, str(path))
            except PiecesError as exc:
                if not got.skipped:
                    raise
                raise PiecesError(f"{exc}; the other closed outlines were taken for annotations "
                                  f"({listed})", exc.failed, exc.source) from None
        if not got.skipped:
            raise InputError(f"{path}: no pattern piece found")
        raise InputError(f"{path}: no pattern piece: every closed outline was taken for an "
                         f"annotation ({listed}); grid one with --include NAME")
    return got


def _split_pinched(pieces: Pieces) -> Pieces:
    """SVG and DXF pieces cut in two where their outline pinches
    (:func:`clothgrid.patterns.piece.split_pinched`), the parts' names unique in the file."""
    out: list[Piece] = []
    taken = {x.name for x in (*pieces, *pieces.skipped, *pieces.failed)}
    for p in pieces:
        parts = split_pinched(p) if p.source in ("svg", "dxf", "aama-dxf") else [p]
        if len(parts) > 1:
            for k, q in enumerate(parts):
                name, m = q.name, 2
                while name in taken:
                    name, m = f"{q.name}-{m}", m + 1
                taken.add(name)
                parts[k] = q if name == q.name else replace(q, name=name)
        out.extend(parts)
    return pieces if len(out) == len(pieces) else Pieces.like(pieces, out)


def read_pieces(path: str | Path, *, units: str | None = None, rel_tol: float = DEFAULT_REL_TOL,
                line: str = "sew", include: Any = None) -> list[Piece]:
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
    line : "sew" or "cut"
        Of a piece drawn with its sew line and its cut (seam-allowance) line
        (AAMA layer 14 and 1, an SVG outline inside another of nearly the same
        shape), which to grid (default ``"sew"``; a piece with only one is
        gridded along it, noted). ``Piece.meta["line"]`` says which.
    include : sequence of str, optional
        Names of outlines skipped as annotations to grid all the same.

    Returns
    -------
    Pieces
        A list of the pieces that could be made, in file order; outlines in
        millimetres, counter-clockwise. Its ``failed`` attribute lists the
        pieces that could not (a :class:`~clothgrid.patterns.piece.PieceFailure`
        each: name and reason, e.g. fewer than 3 distinct points or no area):
        one bad piece does not stop the others. Its ``skipped`` attribute lists
        the closed outlines taken for annotations (text, arrows, notches, drill
        holes, marks, seam-allowance outlines), each with its reason; an outline
        that cannot be made is skipped, not failed, when the file marks it as an
        annotation.

    Raises
    ------
    InputError
        A missing or unreadable file, an unknown extension, a boundary file,
        malformed content (a truncated file), unknown units, no closed piece,
        or no piece that could be made (the message gives each one's reason).
    """
    path = Path(path)
    if units is not None:
        unit_to_mm(units, what="--units")
    if isinstance(rel_tol, bool) or not isinstance(rel_tol, (int, float)) or not 0 < rel_tol <= 1e-2:
        raise InputError(f"rel_tol must be a number in (0, 0.01], not {rel_tol!r}")
    got = read_input(path, units=units, rel_tol=rel_tol, line=line, include=include)
    if isinstance(got, Boundary):
        raise InputError(f"{path}: is a boundary file (four sides, or an outline), not a pattern file: grid it "
                         "with 'clothgrid generate', or read it with clothgrid.load_boundary()")
    return got


def load_boundary(path: str | Path, **options: Any) -> Boundary:
    """Read a boundary from ``path``, the format chosen by its extension.

    A boundary file gives its boundary; a pattern file with exactly one piece
    (that could be read) gives that piece's (automatic corners; ``options`` as for :func:`read_pieces`).

    Raises
    ------
    InputError
        The file does not exist, has an unknown extension, cannot be parsed, or
        is a pattern file with several pieces.
    BoundaryError
        The file's curves are not a valid piece.
    """
    path = Path(path)
    got = read_input(path, **options)
    if isinstance(got, Boundary):
        return got
    if len(got) != 1:
        names = ", ".join(p.name for p in got[:8]) + (", ..." if len(got) > 8 else "")
        raise InputError(f"{path}: has {len(got)} pieces ({names}); load them with "
                         "clothgrid.readers.read_pieces() and piece_boundary(), or pick one with "
                         "--piece NAME")
    return piece_boundary(got[0])


load_single_boundary = load_boundary


def load_npz(path: str | Path) -> Grid:
    """Read a grid written by :func:`clothgrid.writers.write_npz`.

    Raises
    ------
    InputError
        If the file is missing or is not a clothgrid NPZ file.
    """
    try:
        with np.load(path, allow_pickle=False) as z:
            points = np.array(z["points"], dtype=np.float64)
            uv = np.array(z["uv"], dtype=np.float64)
            quads = np.array(z["quads"], dtype=np.int64)
            dim = int(z["dim"]) if "dim" in z.files else 3
            info = json.loads(str(z["info"])) if "info" in z.files else {}
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"cannot read grid from {str(path)!r}: {exc}") from exc
    if points.ndim != 3 or points.shape[2] != 3:
        raise InputError(f"{str(path)!r}: points must have shape (nu, nv, 3), not {points.shape}")
    return Grid(points=points, uv=uv, quads=quads, info=info, dim=dim)
