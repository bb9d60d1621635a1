"""Write grids to files: NPZ, Wavefront OBJ, ASCII PLY and JSON.

The format is chosen by the file's extension through :data:`WRITERS`, which
:func:`register_writer` extends. :func:`save` writes to a temporary file in the
target directory and renames it on success, so a failure never leaves a partial
file behind.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any, BinaryIO, Callable, Iterator

import numpy as np

from .errors import InputError
from .grid import Grid

__all__ = [
    "WRITERS",
    "Writer",
    "register_writer",
    "save",
    "atomic_write",
    "write_npz",
    "write_obj",
    "write_ply",
    "write_json",
    "load_npz",
    "info_json",
]

#: A writer gets the grid and a binary file open for writing.
Writer = Callable[[Grid, BinaryIO], None]

# Read once at import (os.umask can only be read by setting it, which is not thread-safe).
_UMASK = os.umask(0o022)
os.umask(_UMASK)

_CHUNK = 1 << 16  # rows formatted at a time by the text writers


def _jsonable(obj: Any) -> Any:
    """``json.dumps`` fallback for numpy scalars and arrays, paths and sets."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (set, frozenset, tuple)):
        return list(obj)
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    return repr(obj)


def info_json(info: dict[str, Any]) -> str:
    """The info dict as one line of JSON (numpy values converted, anything else ``repr``'d)."""
    return json.dumps(info, default=_jsonable, sort_keys=True)


@contextlib.contextmanager
def atomic_write(path: str | Path) -> Iterator[BinaryIO]:
    """Open a temporary file next to ``path`` for writing; rename it to ``path`` on success.

    On any exception the temporary file is removed and ``path`` is left as it was.

    Raises
    ------
    InputError
        If the directory of ``path`` does not exist.
    """
    path = Path(path)
    directory = path.parent
    if not directory.is_dir():
        raise InputError(f"cannot write {str(path)!r}: directory {str(directory)!r} does not exist")
    fh = tempfile.NamedTemporaryFile(dir=directory, prefix=f".{path.name}.", suffix=".tmp",
                                     delete=False)
    try:
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(fh.name, 0o666 & ~_UMASK)
        os.replace(fh.name, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(fh.name)
        raise


def _write_rows(fh: BinaryIO, fmt: str, rows: np.ndarray) -> None:
    """Write ``fmt % row`` for every row of a 2D array, formatted a chunk at a time."""
    for start in range(0, len(rows), _CHUNK):
        chunk = rows[start:start + _CHUNK]
        fh.write(((fmt * len(chunk)) % tuple(chunk.ravel().tolist())).encode("ascii"))


def write_npz(grid: Grid, fh: BinaryIO) -> None:
    """Compressed NumPy archive: ``points``, ``uv``, ``quads``, ``dim`` and ``info`` (JSON text)."""
    np.savez(fh, points=grid.points, uv=grid.uv, quads=grid.quads,
                        dim=np.int64(grid.dim), info=np.array(info_json(grid.info)))


def write_obj(grid: Grid, fh: BinaryIO) -> None:
    """Wavefront OBJ: ``v x y z``, ``vt u v`` (same index) and ``f a/a b/b c/c d/d`` (1-based)."""
    nu, nv = grid.shape
    fh.write(f"# clothgrid grid {nu} x {nv}\n# info: {info_json(grid.info)}\n".encode("ascii"))
    _write_rows(fh, "v %.17g %.17g %.17g\n", grid.points.reshape(-1, 3))
    _write_rows(fh, "vt %.17g %.17g\n", grid.uv.reshape(-1, 2))
    q = np.repeat(np.asarray(grid.quads, dtype=np.int64) + 1, 2, axis=1)
    _write_rows(fh, "f %d/%d %d/%d %d/%d %d/%d\n", q)


def write_ply(grid: Grid, fh: BinaryIO) -> None:
    """ASCII PLY: vertices ``x y z s t`` (s, t the texture coordinates) and quad faces."""
    nu, nv = grid.shape
    header = "\n".join([
        "ply",
        "format ascii 1.0",
        f"comment clothgrid grid {nu} x {nv}",
        f"comment info: {info_json(grid.info)}",
        f"element vertex {nu * nv}",
        *(f"property double {name}" for name in "xyzst"),
        f"element face {len(grid.quads)}",
        "property list uchar int vertex_indices",
        "end_header",
        "",
    ])
    fh.write(header.encode("ascii"))
    vertices = np.concatenate([grid.points.reshape(-1, 3), grid.uv.reshape(-1, 2)], axis=1)
    _write_rows(fh, "%.17g %.17g %.17g %.17g %.17g\n", vertices)
    _write_rows(fh, "4 %d %d %d %d\n", np.asarray(grid.quads, dtype=np.int64))


def write_json(grid: Grid, fh: BinaryIO) -> None:
    """JSON: ``shape``, ``dim``, ``points`` and ``uv`` (nested lists), ``quads`` and ``info``."""
    doc = {"shape": list(grid.shape), "dim": int(grid.dim), "points": grid.points.tolist(),
           "uv": grid.uv.tolist(), "quads": np.asarray(grid.quads).tolist(),
           "info": json.loads(info_json(grid.info))}
    fh.write(json.dumps(doc).encode("utf-8"))


#: Writers by lower-case file extension (with the dot).
WRITERS: dict[str, Writer] = {
    ".npz": write_npz,
    ".obj": write_obj,
    ".ply": write_ply,
    ".json": write_json,
}


def register_writer(extension: str, writer: Writer) -> Writer:
    """Add (or replace) the writer for files ending in ``extension`` (e.g. ``".vtk"``).

    Returns ``writer``, so this may wrap a function definition.
    """
    ext = extension.lower() if extension.startswith(".") else "." + extension.lower()
    WRITERS[ext] = writer
    return writer


def save(grid: Grid, path: str | Path) -> Path:
    """Write ``grid`` to ``path``, the format chosen by the extension (see :data:`WRITERS`).

    The file is written to a temporary file in the same directory and renamed
    on success; on failure nothing is left behind.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        For an unknown extension or a directory that does not exist.
    """
    path = Path(path)
    writer = WRITERS.get(path.suffix.lower())
    if writer is None:
        known = ", ".join(sorted(WRITERS))
        raise InputError(f"cannot write {str(path)!r}: unknown extension {path.suffix!r} "
                         f"(known: {known})")
    with atomic_write(path) as fh:
        writer(grid, fh)
    return path


def load_npz(path: str | Path) -> Grid:
    """Read a grid written by :func:`write_npz`.

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
