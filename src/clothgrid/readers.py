"""Read a :class:`~clothgrid.boundary.Boundary` from a file.

Readers are chosen by file extension from :data:`READERS`; add a format with
:func:`register_reader`. Every error names the file and is an
:class:`~clothgrid.errors.InputError` (a :class:`~clothgrid.errors.BoundaryError`
when the file is readable but its curves are not a valid piece).

JSON (``.json``) is one object in either of two forms, with an optional
``name`` (default: the file's stem)::

    {"bottom": [[x, y], ...], "right": [...], "top": [...], "left": [...]}
    {"outline": [[x, y], ...], "corners": [i_bl, i_br, i_tr, i_tl]}

the second being the format of the test regions (see ``MATH.md``).
"""

from __future__ import annotations

import json

import numpy as np
from pathlib import Path
from typing import Callable

from .boundary import SIDES, Boundary
from .errors import BoundaryError, InputError
from .grid import Grid

__all__ = ["READERS", "register_reader", "load_boundary", "read_json", "load_npz"]

Reader = Callable[[Path], Boundary]


def read_json(path: str | Path) -> Boundary:
    """Read a boundary from a JSON file (sides, or outline and corners)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a UTF-8 text file ({exc})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: invalid JSON at line {exc.lineno}, column {exc.colno}: "
                         f"{exc.msg}") from None
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
            if data.get("corners") is None:
                raise InputError(f"{path}: the region has an 'outline' but no 'corners': the four "
                                 "corner indices (bottom-left, bottom-right, top-right, top-left) "
                                 "must be given; automatic corner choice is not implemented yet")
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


#: file extension (lower case, with the dot) -> reader
READERS: dict[str, Reader] = {".json": read_json}


def register_reader(ext: str, func: Reader) -> None:
    """Register ``func(path) -> Boundary`` as the reader for extension ``ext`` (e.g. ``".svg"``)."""
    ext = ext.lower()
    READERS[ext if ext.startswith(".") else "." + ext] = func


def reader_for(path: Path, registry: dict, kind: str):
    """The reader in ``registry`` for ``path``'s extension, after checking the file exists.

    Raises :class:`InputError` naming the problem for a missing file, a
    directory, or an extension no reader is registered for.
    """
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if path.is_dir():
        raise InputError(f"{path}: is a directory, not a {kind} file")
    reader = registry.get(path.suffix.lower())
    if reader is None:
        raise InputError(f"{path}: unknown {kind} file type {path.suffix or '(no extension)'!r}; "
                         f"known: {', '.join(sorted(registry))}")
    return reader


def load_boundary(path: str | Path) -> Boundary:
    """Read a boundary from ``path``, the format chosen by its extension.

    Raises
    ------
    InputError
        The file does not exist, has an unknown extension, or cannot be parsed.
    BoundaryError
        The file's curves are not a valid piece.
    """
    path = Path(path)
    return reader_for(path, READERS, "boundary")(path)


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
