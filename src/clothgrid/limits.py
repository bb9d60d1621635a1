"""The readers' limits: what an input file may hold, checked up front with a message.

Pattern files come from many CAD systems and from strangers; these limits keep
every read within seconds and in memory proportional to the file (issue 15).
Each is far beyond a real pattern (a garment panel has some thousands of
outline points; a marker some hundreds of pieces) and is stated in the README
("Limits"). Every breach is an :class:`~clothgrid.errors.InputError` naming
the file and the limit.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

from .errors import InputError

__all__ = ["MAX_FILE_BYTES", "MAX_NESTING", "MAX_INT_DIGITS", "MAX_COORDINATE", "MAX_OUTLINE_POINTS",
           "MAX_ENTITIES", "MAX_DXF_RECORDS", "MAX_SEGMENT_PAIRS", "MAX_NODES_PER_SIDE", "MAX_BULGE", "MAX_K", "MIN_K", "MAX_FIELD_VALUES", "check_input_file",
           "load_json", "check_coordinates"]

#: largest input file read (bytes)
MAX_FILE_BYTES = 256 * 2**20
#: deepest nesting of JSON arrays/objects and of SVG elements (groups)
MAX_NESTING = 200
#: most digits of a JSON integer (a coordinate of 10^20 and more is no pattern)
MAX_INT_DIGITS = 20
#: largest absolute coordinate, in the file's units and in mm (1e12: a million km in mm);
#: beyond it squares and sums of coordinates lose all precision or overflow
MAX_COORDINATE = 1e12
#: most points of one outline or side, as read or as sampled
MAX_OUTLINE_POINTS = 5_000_000
#: most pairs of nearby segments the self-intersection check of one outline compares (about 1e7
#: a second): a real outline of n points gives about 1.5 n pairs, an outline whose wiggles are
#: much wider than its point spacing (noise on a densely sampled curve) about n^2 / 400 and more
#: (a circle of 10^6 points with noise of 0.1 % of its radius: 2.4e8, 24 s)
MAX_SEGMENT_PAIRS = 200_000_000
#: most entities (DXF) or elements (SVG) or edges (GarmentCode panel) in one file
MAX_ENTITIES = 1_000_000
#: most records of a DXF file (entities, polyline vertices, block and table entries: each
#: ``0`` group), counted in the text before ezdxf reads it: ezdxf reads some 10^4 records
#: a second, and the largest real pattern files at hand have about 11,000
MAX_DXF_RECORDS = 250_000
#: most grid nodes along one side (a grid's size is also checked against the memory first)
MAX_NODES_PER_SIDE = 100_000_000
#: largest |bulge| of a DXF polyline vertex (tan of a quarter of the arc's angle; 1e6 is an
#: arc 4e-6 rad short of a full circle)
MAX_BULGE = 1e6
#: the range of the factor ``k`` of the paper's v weights (eq. 2): beyond it the squared
#: weights overflow or underflow
MIN_K, MAX_K = 1e-6, 1e6
#: Values in a 2D field read from a file (a ``.npy`` array or an image: a weight field, a heat
#: problem's conductivity, source or capacity): 2^26, 512 MiB as float64; checked from the file's
#: header before it is read.
MAX_FIELD_VALUES = 2**26


def check_input_file(path: Path, kind: str = "input") -> None:
    """Raise :class:`InputError` unless ``path`` is a regular file of at most :data:`MAX_FILE_BYTES`.

    A device (``/dev/zero``), a FIFO or a socket would be read forever or block.
    """
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{path}: is a directory, not a {kind} file")
    if not stat.S_ISREG(st.st_mode):
        what = ("a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode) else
                "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else
                "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        raise InputError(f"{path}: is {what}, not a regular {kind} file")
    if st.st_size > MAX_FILE_BYTES:
        raise InputError(f"{path}: the file has {st.st_size:,} bytes, more than the limit of "
                         f"{MAX_FILE_BYTES:,} bytes ({MAX_FILE_BYTES >> 20} MiB) for an input file")


def _parse_int(text: str) -> int:
    digits = len(text.lstrip("+-"))
    if digits > MAX_INT_DIGITS:
        raise InputError(f"an integer of {digits} digits ({text[:12]}...): numbers are limited to "
                         f"{MAX_INT_DIGITS} digits")
    return int(text)


def _depth(data: Any, where: str) -> None:
    """Raise InputError if ``data`` nests deeper than :data:`MAX_NESTING` (iteratively)."""
    stack = [(data, 1)]
    while stack:
        obj, d = stack.pop()
        if d > MAX_NESTING:
            raise InputError(f"{where}: the JSON nests arrays/objects more than {MAX_NESTING} deep")
        if isinstance(obj, dict):
            stack.extend((v, d + 1) for v in obj.values() if isinstance(v, (dict, list)))
        elif isinstance(obj, list):
            # a long list (an outline's points) is checked on a sample: what nests deeper inside
            # one of its items is refused later as a malformed point (this is about time, not
            # about safety: the parse itself has succeeded)
            items = obj if len(obj) <= 64 else obj[::len(obj) // 64]
            stack.extend((v, d + 1) for v in items if isinstance(v, (dict, list)))


def load_json(text: str, where: str) -> Any:
    """``json.loads`` with the limits: nesting depth, integer digits; errors as :class:`InputError`."""
    try:
        data = json.loads(text, parse_int=_parse_int)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{where}: invalid JSON at line {exc.lineno}, column {exc.colno}: "
                         f"{exc.msg}") from None
    except RecursionError:
        raise InputError(f"{where}: the JSON nests arrays/objects more than {MAX_NESTING} deep") from None
    except (ValueError, MemoryError) as exc:
        raise InputError(f"{where}: invalid JSON ({exc})") from None
    _depth(data, where)
    return data


def check_coordinates(pts: Any, what: str) -> None:
    """Raise :class:`InputError` if a (finite) coordinate exceeds :data:`MAX_COORDINATE` in size."""
    import numpy as np

    a = np.asarray(pts)
    if a.size and a.dtype.kind == "f":
        big = np.abs(a) > MAX_COORDINATE
        if big.any():
            k = int(np.flatnonzero(big.reshape(len(a), -1).any(axis=1))[0]) if a.ndim > 1 else 0
            raise InputError(f"{what}: a coordinate of {float(np.abs(a).max()):.3g} (point {k}) is beyond "
                             f"the limit of {MAX_COORDINATE:.0e} in size")


def read_json_file(path: str | Path, kind: str = "input", check_file: bool = True) -> Any:
    """A JSON file's data, with the limits: a regular file of a sane size (:func:`check_input_file`,
    unless ``check_file`` is false), UTF-8, :func:`load_json`; every failure an :class:`InputError`
    naming the file."""
    path = Path(path)
    if check_file:
        check_input_file(path, kind)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a UTF-8 text file ({exc})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {kind} file ({exc.strerror or exc})") from None
    return load_json(text, str(path))

