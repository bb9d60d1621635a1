"""Write grids to files: NPZ, Wavefront OBJ, ASCII PLY, JSON and VTK structured grid.

The format is chosen by the file's extension through :data:`WRITERS`, which
:func:`register_writer` extends. :func:`save` writes to a temporary file in the
target directory and renames it on success, so a failure never leaves a partial
file behind.

Writers may take keyword-only options (:func:`writer_options` lists them):
``triangles`` (``"fixed"`` or ``"alternate"``: triangle faces instead of quads,
see :meth:`Grid.triangles`), ``uv`` (``"normalised"`` or ``"pattern"``: which
texture coordinates to write), ``cloth`` (NPZ: add springs, triangles, pattern
coordinates and areas), ``density`` (areal density, for masses) and
``length_unit`` (the coordinates' unit, see :mod:`clothgrid.cloth`).
"""

from __future__ import annotations

import base64
import contextlib
import inspect
import json
import os
import tempfile
import zipfile
from pathlib import Path
from typing import Any, BinaryIO, Callable, Iterator, Protocol, cast

import numpy as np

from .errors import InputError
from .pages import small_pages
from . import cloth as sim
from .cloth import GridLike as _ClothGrid

__all__ = [
    "WRITERS",
    "Writer",
    "register_writer",
    "save",
    "atomic_write",
    "savez",
    "Streamed",
    "write_npz",
    "write_obj",
    "write_ply",
    "write_json",
    "write_vts",
    "writer_options",
    "info_json",
]

#: A writer gets the grid and a binary file open for writing.
class GridLike(_ClothGrid, Protocol):
    """What the writers read of a grid (:class:`clothgrid.Grid` is one): the cloth functions' grid,
    and its pattern coordinates and whether it is flat."""

    @property
    def pattern_uv(self) -> Any: ...

    @property
    def planar(self) -> bool: ...


Writer = Callable[[GridLike, BinaryIO], None]

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
            yield cast(BinaryIO, fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(fh.name, 0o666 & ~_UMASK)
        os.replace(fh.name, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(fh.name)
        raise


class Streamed:
    """An array that :func:`savez` writes block by block, never whole in memory.

    Parameters
    ----------
    shape : tuple of int
        The whole array's shape.
    dtype : numpy.dtype
        Its dtype (a plain one, no objects).
    blocks : callable
        Returns an iterator over C-contiguous blocks whose concatenation along the first axis
        is the array (a block may be reused once the next one is asked for).
    """

    def __init__(self, shape: tuple[int, ...], dtype: Any, blocks: Callable[[], Iterator[np.ndarray]]):
        self.shape = tuple(int(n) for n in shape)
        self.dtype = np.dtype(dtype)
        self.blocks = blocks


def savez(fh: BinaryIO, **arrays: Any) -> None:
    """``numpy.savez`` (uncompressed, readable by ``numpy.load``) without copying the arrays.

    NumPy writes each array into the zip archive through ``tobytes`` copies of up to 16 MB; this
    writes the ``.npy`` header and then the array's own memory (C-contiguous arrays of plain
    dtypes; anything else goes through ``numpy.lib.format.write_array``). The same members, bytes
    and CRCs as ``numpy.savez``; 13 ms less on a 1024^2 grid's 75 MB in a fresh process. A
    :class:`Streamed` value is written block by block.
    """
    fmt = np.lib.format
    with zipfile.ZipFile(fh, mode="w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
        for name, value in arrays.items():
            streamed = isinstance(value, Streamed)
            a = value if streamed else np.asanyarray(value)
            with zf.open(name + ".npy", "w", force_zip64=True) as member:
                if not streamed and (a.ndim == 0 or a.dtype.hasobject or not a.flags.c_contiguous
                                     or type(a) is not np.ndarray):
                    fmt.write_array(member, a, allow_pickle=False)
                    continue
                header = {"descr": fmt.dtype_to_descr(a.dtype), "fortran_order": False, "shape": a.shape}
                try:
                    fmt.write_array_header_1_0(member, header)
                except ValueError:              # a header over 64 KB (a record dtype with many fields)
                    fmt.write_array_header_2_0(member, header)
                written = 0
                for block in (a.blocks() if streamed else (a,)):
                    block = np.ascontiguousarray(block, dtype=a.dtype)
                    member.write(memoryview(block.reshape(-1)).cast("B"))  # type: ignore[arg-type]  # an ndarray is a buffer
                    written += block.nbytes
                expected = int(np.prod(a.shape, dtype=np.int64)) * a.dtype.itemsize
                if written != expected:
                    raise ValueError(f"savez: {name!r} got {written} bytes of data, its shape needs {expected}")


def _write_rows(fh: BinaryIO, fmt: str, rows: np.ndarray) -> None:
    """Write ``fmt % row`` for every row of a 2D array, formatted a chunk at a time."""
    for start in range(0, len(rows), _CHUNK):
        chunk = rows[start:start + _CHUNK]
        fh.write(((fmt * len(chunk)) % tuple(chunk.ravel().tolist())).encode("ascii"))


UV_CHOICES = ("normalised", "pattern")
TRIANGLE_CHOICES = ("fixed", "alternate")


def _faces(grid: GridLike, triangles: str | None) -> np.ndarray:
    """The quads, or with ``triangles`` the triangles with that diagonal choice."""
    if triangles is None:
        return np.asarray(grid.quads, dtype=np.int64)
    if triangles not in TRIANGLE_CHOICES:
        raise InputError(f"triangles must be one of {', '.join(TRIANGLE_CHOICES)}, not {triangles!r}")
    return np.asarray(grid.triangles(triangles), dtype=np.int64)


def texture_coordinates(grid: GridLike, uv: str) -> np.ndarray:
    """``(N, 2)`` texture coordinates: the normalised ``uv`` or the pattern's (length units)."""
    if uv == "normalised":
        return grid.uv.reshape(-1, 2)
    if uv == "pattern":
        return grid.pattern_uv.reshape(-1, 2)
    raise InputError(f"uv must be one of {', '.join(UV_CHOICES)}, not {uv!r}")


def _quads(grid: GridLike) -> Any:
    """The grid's quads for :func:`savez`: streamed in blocks where the grid can make them so."""
    blocks = getattr(grid, "quad_blocks", None)
    if blocks is None:
        return grid.quads
    nu, nv = grid.shape
    return Streamed((max(nu - 1, 0) * max(nv - 1, 0), 4), np.int64, blocks)


def write_npz(grid: GridLike, fh: BinaryIO, *, cloth: bool = False, triangles: str = "fixed",
              density: float | str | None = None, length_unit: str | None = None) -> None:
    """NumPy archive (uncompressed, fast to write).

    Always: ``points`` ``(nu, nv, 3)``, ``uv`` ``(nu, nv, 2)`` (normalised),
    ``quads``, ``dim``, ``info`` (JSON text), ``length_unit``, ``planar``,
    ``side_bottom``, ``side_right``, ``side_top``, ``side_left`` (flat indices
    in each side's direction) and ``corners`` (bottom-left, bottom-right,
    top-right, top-left, named in ``corner_names``).

    With ``cloth=True`` (implied by ``density``) also what a simulator needs:
    ``pattern_uv`` ``(nu, nv, 2)`` (flat pattern coordinates, length unit);
    ``triangles`` ``(2M, 3)`` (diagonal choice ``triangles``, recorded in
    ``triangle_diagonal``); the springs ``spring_pairs`` ``(m, 2)``,
    ``spring_kind`` (int8 codes into ``spring_kind_names``), ``spring_axis``
    and ``spring_rest_length``; ``node_area`` ``(N,)`` (length unit squared)
    and, with ``density``, ``masses`` ``(N,)`` in kg and ``density`` in kg/m^2.
    These are about 15 numbers per node: opt-in, so that the plain archive of
    a 1024 x 1024 grid stays quick to write.
    """

    unit = sim.resolve_length_unit(grid, length_unit)
    side = sim.sides(grid)
    corner = sim.corners(grid)
    arrays: dict[str, Any] = {
        "points": grid.points, "uv": grid.uv, "quads": _quads(grid), "dim": np.int64(grid.dim),
        "info": np.array(info_json(grid.info)), "length_unit": np.array(unit),
        "planar": np.bool_(grid.planar), **{f"side_{k}": v for k, v in side.items()},
        "corners": np.array([corner[k] for k in sim.CORNER_NAMES], dtype=np.int64),
        "corner_names": np.array(sim.CORNER_NAMES),
    }
    if cloth or density is not None:
        tris = _faces(grid, triangles)
        sp = sim.springs(grid)
        arrays.update(pattern_uv=grid.pattern_uv, triangles=tris, triangle_diagonal=np.array(triangles),
                      spring_pairs=sp.pairs, spring_kind=sp.kind, spring_axis=sp.axis,
                      spring_rest_length=sp.rest_length, spring_kind_names=np.array(sim.SPRING_KINDS),
                      node_area=sim.node_areas(grid))
        if density is not None:
            rho = sim.parse_density(density)
            arrays.update(masses=sim.node_masses(grid, rho, unit), density=np.float64(rho))
    savez(fh, **arrays)


def write_obj(grid: GridLike, fh: BinaryIO, *, triangles: str | None = None, uv: str = "normalised") -> None:
    """Wavefront OBJ: ``v x y z``, ``vt u v`` (same index) and ``f a/a b/b c/c d/d`` (1-based).

    ``triangles`` (``"fixed"`` or ``"alternate"``) writes triangles
    ``f a/a b/b c/c`` instead of quads; ``uv="pattern"`` writes the flat
    pattern coordinates (length units, as ARCSim's material space wants)
    instead of the normalised ones as ``vt``.
    """
    nu, nv = grid.shape
    texture = texture_coordinates(grid, uv)
    faces = _faces(grid, triangles)
    fh.write(f"# clothgrid grid {nu} x {nv}\n# info: {info_json(grid.info)}\n".encode("ascii"))
    _write_rows(fh, "v %.17g %.17g %.17g\n", grid.points.reshape(-1, 3))
    _write_rows(fh, "vt %.17g %.17g\n", texture)
    f = np.repeat(faces + 1, 2, axis=1)
    _write_rows(fh, "f" + " %d/%d" * faces.shape[1] + "\n", f)


def write_ply(grid: GridLike, fh: BinaryIO, *, triangles: str | None = None, uv: str = "normalised") -> None:
    """ASCII PLY: vertices ``x y z s t`` (s, t the texture coordinates) and quad faces.

    ``triangles`` and ``uv`` as in :func:`write_obj`.
    """
    nu, nv = grid.shape
    texture = texture_coordinates(grid, uv)
    faces = _faces(grid, triangles)
    header = "\n".join([
        "ply",
        "format ascii 1.0",
        f"comment clothgrid grid {nu} x {nv}",
        f"comment info: {info_json(grid.info)}",
        f"element vertex {nu * nv}",
        *(f"property double {name}" for name in "xyzst"),
        f"element face {len(faces)}",
        "property list uchar int vertex_indices",
        "end_header",
        "",
    ])
    fh.write(header.encode("ascii"))
    vertices = np.concatenate([grid.points.reshape(-1, 3), texture], axis=1)
    _write_rows(fh, "%.17g %.17g %.17g %.17g %.17g\n", vertices)
    k = faces.shape[1]
    _write_rows(fh, f"{k}" + " %d" * k + "\n", faces)


def write_json(grid: GridLike, fh: BinaryIO) -> None:
    """JSON: ``shape``, ``dim``, ``points`` and ``uv`` (nested lists), ``quads`` and ``info``."""
    doc = {"shape": list(grid.shape), "dim": int(grid.dim), "points": grid.points.tolist(),
           "uv": grid.uv.tolist(), "quads": np.asarray(grid.quads).tolist(),
           "info": json.loads(info_json(grid.info))}
    fh.write(json.dumps(doc).encode("utf-8"))


def _b64_block(a: np.ndarray, dtype: str) -> str:
    """A VTK XML ``format="binary"`` payload: base64 of a UInt64 byte count and the data."""
    data = np.ascontiguousarray(a, dtype=dtype).tobytes()
    return base64.b64encode(np.uint64(len(data)).astype("<u8").tobytes() + data).decode("ascii")


def write_vts(grid: GridLike, fh: BinaryIO, *, density: float | str | None = None,
              length_unit: str | None = None) -> None:
    """VTK XML structured grid (``.vts``, for ParaView), data inline in base64.

    The extent is ``0..nv-1`` by ``0..nu-1`` (VTK's first index is clothgrid's
    ``j``), so VTK point ids are clothgrid's flat indices ``i*nv + j``. Point
    data: ``uv`` (the texture coordinates), ``pattern_uv``, ``node_area`` and,
    with ``density``, ``mass`` (kg). The info and length unit are in a comment.
    """

    nu, nv = grid.shape
    unit = sim.resolve_length_unit(grid, length_unit)
    arrays: list[tuple[str, np.ndarray, int]] = [
        ("uv", grid.uv.reshape(-1, 2), 2),
        ("pattern_uv", grid.pattern_uv.reshape(-1, 2), 2),
        ("node_area", sim.node_areas(grid), 1),
    ]
    if density is not None:
        arrays.append(("mass", sim.node_masses(grid, density, unit), 1))
    extent = f"0 {nv - 1} 0 {nu - 1} 0 0"
    comment = f"clothgrid grid {nu} x {nv}, length unit {unit}; info: {info_json(grid.info)}"
    comment = comment.replace("--", "- -")
    out = [
        '<?xml version="1.0"?>',
        f"<!-- {comment} -->",
        '<VTKFile type="StructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">',
        f'  <StructuredGrid WholeExtent="{extent}">',
        f'    <Piece Extent="{extent}">',
        '      <PointData Scalars="node_area" TCoords="uv">',
    ]
    for name, a, k in arrays:
        out.append(f'        <DataArray type="Float64" Name="{name}" NumberOfComponents="{k}" '
                   f'format="binary">{_b64_block(a, "<f8")}</DataArray>')
    out += [
        "      </PointData>",
        "      <Points>",
        '        <DataArray type="Float64" Name="Points" NumberOfComponents="3" format="binary">'
        f'{_b64_block(grid.points.reshape(-1, 3), "<f8")}</DataArray>',
        "      </Points>",
        "    </Piece>",
        "  </StructuredGrid>",
        "</VTKFile>",
        "",
    ]
    fh.write("\n".join(out).encode("utf-8"))


#: Writers by lower-case file extension (with the dot).
WRITERS: dict[str, Writer] = {
    ".npz": write_npz,
    ".obj": write_obj,
    ".ply": write_ply,
    ".json": write_json,
    ".vts": write_vts,
}


def writer_options(extension: str) -> frozenset[str]:
    """Names of the keyword options the writer of ``extension`` (``".obj"``) takes.

    Empty for an unknown extension or a writer without options.
    """
    ext = extension.lower() if extension.startswith(".") else "." + extension.lower()
    writer = WRITERS.get(ext)
    if writer is None:
        return frozenset()
    try:
        params = list(inspect.signature(writer).parameters.values())
    except (TypeError, ValueError):
        return frozenset()
    return frozenset(p.name for p in params[2:]
                     if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD))


def register_writer(extension: str, writer: Writer) -> Writer:
    """Add (or replace) the writer for files ending in ``extension`` (e.g. ``".vtk"``).

    Returns ``writer``, so this may wrap a function definition.
    """
    ext = extension.lower() if extension.startswith(".") else "." + extension.lower()
    WRITERS[ext] = writer
    return writer


@small_pages()         # the output's arrays (uv, quads, springs) with 4 KB pages: 5.8 -> 2.1 s at 4096^2
def save(grid: GridLike, path: str | Path, **options: Any) -> Path:
    """Write ``grid`` to ``path``, the format chosen by the extension (see :data:`WRITERS`).

    The file is written to a temporary file in the same directory and renamed
    on success; on failure nothing is left behind. ``options`` go to the
    writer (options set to None are dropped): ``triangles`` and ``uv`` for
    .obj and .ply, ``cloth``, ``triangles``, ``density`` and ``length_unit``
    for .npz, ``density`` and ``length_unit`` for .vts (:func:`writer_options`).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        For an unknown extension, an option the format does not take, a bad
        option value or a directory that does not exist.
    """
    path = Path(path)
    writer = WRITERS.get(path.suffix.lower())
    if writer is None:
        known = ", ".join(sorted(WRITERS))
        raise InputError(f"cannot write {str(path)!r}: unknown extension {path.suffix!r} "
                         f"(known: {known})")
    options = {k: v for k, v in options.items() if v is not None}
    unknown = sorted(set(options) - writer_options(path.suffix))
    if unknown:
        takes = ", ".join(sorted(writer_options(path.suffix))) or "none"
        raise InputError(f"cannot write {str(path)!r}: the {path.suffix.lower()} writer takes no "
                         f"option {', '.join(unknown)} (its options: {takes})")
    with atomic_write(path) as fh:
        writer(grid, fh, **options)
    return path
