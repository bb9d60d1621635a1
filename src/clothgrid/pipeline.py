"""One path from file to files: read -> jobs -> grids -> outputs.

A boundary JSON file is one :class:`Job`; a pattern file (SVG, DXF, GarmentCode
JSON) is one job per piece. Every job then takes the same steps, whatever file
it came from::

    from clothgrid.pipeline import GridOptions, OutputOptions, read_jobs, run_job, write_results

    jobs = read_jobs("pattern.dxf", ["meshes/{piece}.obj"], options=GridOptions(edge_length="5mm"))
    results, failed = run_jobs(jobs)                 # generate + quality, once per grid
    write_results(results, OutputOptions())          # atomic; a failure removes what it wrote
    failed                                           # jobs.failed + the pieces generate refused

One bad piece never blocks the others: a pattern piece that cannot be read,
whose corners or four-sided boundary cannot be made, whose grid would not fit
in memory, or whose gridding fails (:class:`~clothgrid.errors.InputError`,
:class:`~clothgrid.errors.NotConvergedError`) becomes a
:class:`~clothgrid.patterns.piece.PieceFailure` (name, reason, stage) and the
other pieces go on. A file with no piece left fails as a whole
(:class:`~clothgrid.errors.PiecesError`, an InputError, or the one piece's own
error). A piece asked for by name (``pieces=[...]``) that cannot be read is an
error. Writing is all or nothing, as before: a failure while writing removes
every file written.

The command line (:mod:`clothgrid.cli`) is this module plus argument parsing and
printing.

Output names: with one job every output path is used as given; with several,
``out.obj`` becomes ``out_<piece>.obj``, or ``{piece}`` in a path is replaced by
the piece's name (``-o meshes/{piece}.obj``). Names are made file-safe
(characters other than letters and digits of any script, ``.``, ``_`` and ``-`` become ``_``).
Unknown output formats, output folders that cannot be made and two jobs writing one
file are reported by :func:`read_jobs`, before any grid is made; missing output
folders are created when the outputs are written (and removed again if writing fails).
"""

from __future__ import annotations

import os
import re
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from . import writers
from .blas_threads import one_blas_thread
from .boundary import Boundary
from .errors import InputError, NotConvergedError, PiecesError, SizeError
from .generate import check_size, forced_by_outline, generate, parse_nodes
from .memory import KEPT_BYTES_PER_NODE
from .grid import Grid
from .patterns import (DEFAULT_EDGE_LENGTH_MM, MIN_TURN_DEG, CornerChoice, Piece, choose_corners,
                       nodes_for_edge_length, piece_boundary, piece_info)
from .patterns.piece import MAX_CUT_COUNT, PieceFailure, Pieces, piece_failure
from .units import parse_length, size_warning
from .quality import TARGET_EDGE_SPREAD, TARGET_MIN_ANGLE_DEG, Quality, quality, sim_figures, targets_met
from .readers import read_input, read_pieces

__all__ = ["GridOptions", "OutputOptions", "Job", "Jobs", "Result", "PieceFailure", "read_jobs", "run_job",
           "run_jobs", "no_piece_left", "write_result",
           "write_results", "generate_piece", "runners_up", "piece_listing", "skipped_listing", "select_pieces", "graded", "size_key", "unfolded_pieces", "cut_of", "corner_choice",
           "check_outputs", "check_output_folders", "make_folders", "remove_folders", "output_names", "safe_name", "PLOT_SUFFIXES", "report_entry", "write_report"]

PLOT_SUFFIXES = (".png",)


@dataclass(frozen=True)
class GridOptions:
    """How every grid of a run is made: the options of :func:`clothgrid.generate` and its size.

    ``nodes`` (``(nu, nv)``, ``N`` or ``"NUxNV"``) or ``edge_length`` (a target
    edge length, :func:`~clothgrid.patterns.nodes_for_edge_length`: a number in the input's units, or text with a
    unit such as ``"5mm"`` for pattern files) sets the size; with neither, a
    boundary file keeps its own point counts and a pattern piece gets 10 mm
    edges. ``weight_field`` (an array ``(mu, mv)``, or a ``.npy`` file or a
    grayscale image with ``weight_field_range``, read with
    :func:`clothgrid.fields.load_field`) scales ``weights`` edge by edge
    (:class:`~clothgrid.weights.WeightField`: finer where it is larger). The
    rest are :func:`clothgrid.generate`'s. Checked once, when made.
    """

    nodes: Any = None
    edge_length: float | str | None = None
    init: str = "tfi"
    weights: str = "uniform"
    k: float = 1.0
    solver: str = "auto"
    backend: str = "auto"
    tol: float = 2.0**-12
    stop: str = "error"
    max_iter: int | None = None
    allow_unconverged: bool = False
    functional: str = "auto"
    weight_field: Any = None
    weight_field_range: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        from .generate import FUNCTIONALS, _check_options

        if self.nodes is not None and self.edge_length is not None:
            raise InputError("give --nodes or --edge-length, not both")
        if self.nodes is not None:
            object.__setattr__(self, "nodes", parse_nodes(self.nodes))
        _check_options(self.init, self.solver, self.stop, self.tol, self.max_iter)
        if self.functional not in FUNCTIONALS:
            raise InputError(f"unknown functional {self.functional!r}: use one of {', '.join(FUNCTIONALS)}")
        if self.weight_field is not None:
            from .fields import load_field
            from .weights import WeightField

            field = load_field(self.weight_field, name="weight field", value_range=self.weight_field_range)
            if not isinstance(field, np.ndarray):          # a number: the same factor on every edge
                field = np.full((1, 1), field)
            object.__setattr__(self, "weight_field", WeightField(field, base=self.weights).values)

    def edge_weights(self) -> Any:
        """What :func:`clothgrid.generate` takes as ``weights``: the name, or the weight field over it."""
        if self.weight_field is None:
            return self.weights
        from .weights import WeightField

        return WeightField(self.weight_field, base=self.weights)

    def generate_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of :func:`clothgrid.generate` (all but the size)."""
        return {"init": self.init, "weights": self.edge_weights(), "k": self.k, "solver": self.solver,
                "backend": self.backend, "tol": self.tol, "stop": self.stop, "max_iter": self.max_iter,
                "allow_unconverged": self.allow_unconverged, "functional": self.functional}


@dataclass(frozen=True)
class OutputOptions:
    """How the outputs are written: each writer takes those it knows (:func:`clothgrid.writers.writer_options`)."""

    triangles: str | None = None
    uv: str | None = None
    density: float | None = None
    cloth: bool = False

    def for_writer(self, suffix: str) -> dict[str, Any]:
        takes = writers.writer_options(suffix)
        given = {"triangles": self.triangles, "uv": self.uv, "density": self.density,
                 "cloth": self.cloth or None}
        return {k: v for k, v in given.items() if k in takes and v is not None}


@dataclass
class Job:
    """One grid to make and where it goes.

    Attributes
    ----------
    name : str
        The piece's name (the boundary's, or the file's stem).
    boundary : Boundary
    nodes : (int, int) or None
        Grid size (None: the boundary's own point counts).
    outputs : list of Path
        Files to write, format by extension.
    plot : Path or None
        A PNG of the grid.
    length_unit : str
        Unit of the coordinates (written into the outputs).
    piece : dict or None
        For a pattern piece, what ``grid.info["piece"]`` records (corners, grain line, ...).
    corners : str or None
        For a pattern piece, how its corners were chosen (one line).
    edge_length : float or None
        The target edge length the size came from, if any.
    options : GridOptions
        How the grid is made.
    pattern : Piece or None
        The pattern piece the boundary was made from, and ...
    choice : CornerChoice or None
        ... its corner choice: where an automatic choice's grid misses the
        angle target, :func:`run_job` tries its runners-up.
    """

    name: str
    boundary: Boundary
    nodes: tuple[int, int] | None
    outputs: list[Path]
    plot: Path | None = None
    length_unit: str = "m"
    piece: dict[str, Any] | None = None
    corners: str | None = None
    edge_length: float | None = None
    options: GridOptions = field(default_factory=GridOptions)
    pattern: Piece | None = None
    choice: CornerChoice | None = None


class Jobs(list):
    """The jobs of one input file (a plain ``list`` of :class:`Job`), with :attr:`failed`: the
    pattern pieces that could not be made into a job (:class:`PieceFailure`, in file order),
    :attr:`source`, the file, and :attr:`warnings`: lines for the user about the whole file
    (:func:`units_warning`)."""

    def __init__(self, jobs: Any = (), failed: Any = (), source: Path | None = None,
                 warnings: Sequence[str] = ()) -> None:
        super().__init__(jobs)
        self.failed: list[PieceFailure] = list(failed)
        self.source = source
        self.warnings: list[str] = list(warnings)


def units_warning(pieces: Sequence[Piece], units: str | None) -> str | None:
    """A line for the user where the largest of ``pieces`` (mm) is outside
    :data:`~clothgrid.units.PLAUSIBLE_PIECE_MM` (:func:`~clothgrid.units.size_warning`) and the
    units were the file's own (``units`` None), naming the units it was read in; else None."""
    if units is not None or not pieces:
        return None
    size = max(float((p.outline.max(axis=0) - p.outline.min(axis=0)).max()) for p in pieces)
    return size_warning(size, pieces[0].units)


@dataclass
class Result:
    """A job's grid, its quality (computed once) and the seconds ``generate`` took."""

    job: Job
    grid: Grid
    quality: Quality
    seconds: float
    written: list[Path] = field(default_factory=list)
    folders: list[Path] = field(default_factory=list)
    #: Seconds the quality measurements took (after ``generate``).
    quality_seconds: float = 0.0


# --------------------------------------------------------------------------- names


def safe_name(name: str) -> str:
    """``name`` (NFC) with every character other than letters, digits (any script: a Chinese
    export's piece 前片 stays 前片), ``.``, ``_``, ``-`` made ``_``, cut to :data:`MAX_SAFE_NAME`
    bytes of UTF-8 (at a character's end)."""
    import unicodedata

    out = re.sub(r"[^\w.-]", "_", unicodedata.normalize("NFC", name)).strip(".")
    out = out.encode("utf-8")[:MAX_SAFE_NAME].decode("utf-8", errors="ignore").strip(".")
    return out or "piece"


#: piece names in output file names are cut to this many bytes of UTF-8 (file systems allow 255
#: bytes a name, and the temporary name adds some)
MAX_SAFE_NAME = 120
#: characters that the temporary file's name adds to an output's name (``.NAME.XXXXXXXX.tmp``)
_TEMP_EXTRA = 16


def _check_name_length(path: Path) -> None:
    """InputError if a component of ``path`` (with the temporary name's extra) or the whole path is
    longer than the file system allows."""
    try:
        name_max = os.pathconf(_existing_parent(path), "PC_NAME_MAX")
        path_max = os.pathconf(_existing_parent(path), "PC_PATH_MAX")
    except (OSError, ValueError):
        name_max, path_max = 255, 4096
    for part in path.parts:
        extra = _TEMP_EXTRA if part == path.name else 0
        if len(os.fsencode(part)) + extra > name_max:
            raise InputError(f"output name {part[:40]!r}... is {len(os.fsencode(part))} bytes long: the "
                             f"file system allows {name_max} a name ({name_max - _TEMP_EXTRA} for an "
                             "output file, whose temporary name is longer)")
    if len(os.fsencode(str(path.absolute()))) + _TEMP_EXTRA > path_max:
        raise InputError(f"output path {str(path)[:40]!r}... is longer than the file system's limit of "
                         f"{path_max} bytes")


def _existing_parent(path: Path) -> Path:
    folder = path.absolute().parent
    while folder != folder.parent:
        try:
            if folder.is_dir():
                return folder
        except OSError:
            pass
        folder = folder.parent
    return folder


def output_names(paths: Sequence[str | Path], names: Sequence[str]) -> list[list[str]]:
    """Per piece, the output paths: as given for one piece, else ``stem_<piece>.ext`` or ``{piece}``."""
    safe = [safe_name(n) for n in names]
    if len(set(safe)) != len(safe):
        seen: dict[str, int] = {}
        for k, s in enumerate(safe):
            seen[s] = seen.get(s, 0) + 1
            if seen[s] > 1:
                safe[k] = f"{s}-{seen[s]}"
    out = []
    for s in safe:
        mine = []
        for text in paths:
            text = str(text)
            if "{piece}" in text:
                mine.append(text.replace("{piece}", s))
            elif len(names) == 1:
                mine.append(text)
            else:
                p = Path(text)
                mine.append(str(p.with_name(f"{p.stem}_{s}{p.suffix}")))
        out.append(mine)
    return out


def check_outputs(outputs: Sequence[str | Path], plot: str | Path | None) -> tuple[list[Path], Path | None]:
    """The output paths, after failing fast (InputError) on an unknown extension or a missing folder."""
    known = {"." + str(k).lower().lstrip(".") for k in writers.WRITERS}
    paths: list[Path] = []
    for text in outputs:
        path = Path(text)
        _check_name_length(path)
        if path.suffix.lower() not in known:
            raise InputError(f"unknown output format {path.suffix or '(no extension)'!r} for "
                             f"{str(text)!r}: use one of {', '.join(sorted(known))}")
        if path not in paths:
            paths.append(path)
    plot_path = None
    if plot is not None:
        plot_path = Path(plot)
        _check_name_length(plot_path)
        if plot_path.suffix.lower() not in PLOT_SUFFIXES:
            raise InputError(f"--plot {str(plot)!r}: the plot must be a {'/'.join(PLOT_SUFFIXES)} file")
        if plot_path in paths:
            raise InputError(f"{str(plot)!r} is given both as an output and as the plot")
    check_output_folders(paths + ([plot_path] if plot_path is not None else []))
    return paths, plot_path


def check_output_folders(paths: Sequence[Path]) -> None:
    """Fail fast (InputError) where an output cannot be written: the nearest existing folder above
    it is not a folder or not writable, or the output is a folder. Missing folders are fine: they
    are made when writing (:func:`make_folders`) and removed again if the run fails."""
    for path in paths:
        missing = _missing_folders(path)   # made when writing
        folder = missing[-1].parent if missing else path.parent
        if not folder.is_dir():
            raise InputError(f"output folder {str(folder)!r} is not a folder (for {str(path)!r})")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise InputError(f"output folder {str(folder)!r} is not writable (for {str(path)!r})")
        if path.is_dir():
            raise InputError(f"output {str(path)!r} is a folder")


def _missing_folders(path: Path) -> list[Path]:
    """The parent folders of ``path`` that do not exist yet, deepest first."""
    missing = []
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing


def make_folders(paths: Sequence[Path]) -> list[Path]:
    """Create the missing parent folders of ``paths``; return those created, deepest first."""
    made: list[Path] = []
    for path in paths:
        for f in reversed(_missing_folders(path)):
            try:
                f.mkdir()
            except OSError as exc:
                raise InputError(f"cannot create the output folder {str(f)!r}: {exc.strerror or exc}") from exc
            made.append(f)
    return made[::-1]


def remove_folders(folders: Sequence[Path]) -> None:
    """Remove ``folders`` (deepest first) where they are still empty: those :func:`make_folders` made."""
    for f in folders:            # deepest first; only what is still empty
        try:
            f.rmdir()
        except OSError:
            pass


# --------------------------------------------------------------------------- reading


def size_key(size: Any) -> str:
    """A size as :func:`graded` matches it: case and surrounding spaces aside."""
    return str(size).strip().casefold()


def graded(pieces: list[Piece], size: str, source: Path | str) -> Pieces:
    """The pieces (and skipped outlines) of one size of a graded pattern: those whose ``meta["size"]``
    (AAMA's and flat exports' ``Size:`` text) is ``size`` (case and surrounding spaces aside).

    Raises
    ------
    InputError
        No piece of that size (the message lists the file's sizes), or a file without sizes.
    """
    sizes = list(dict.fromkeys(str(p.meta["size"]).strip() for p in pieces if p.meta.get("size")))
    if not sizes:
        raise InputError(f"{source}: --grade {size!r}: the file gives no sizes (no 'Size:' text on its "
                         "pieces): it is not graded")
    want = size_key(size)
    keep = [p for p in pieces if size_key(p.meta.get("size", "")) == want]
    if not keep:
        raise InputError(f"{source}: --grade {size!r}: no piece of that size; its sizes are "
                         + ", ".join(map(repr, sizes)))
    skipped = [x for x in getattr(pieces, "skipped", ()) if size_key(x.meta.get("size", "")) == want]
    return Pieces.like(pieces, keep, skipped=skipped)


def unfolded_pieces(pieces: list[Piece], source: Path | str) -> Pieces:
    """``pieces`` with each piece cut on the fold made whole (:func:`clothgrid.patterns.fold.unfold`:
    the pieces whose file marks a fold line); one that cannot be unfolded joins ``failed``."""
    from .patterns.fold import unfold

    kept: list[Piece] = []
    failed = list(getattr(pieces, "failed", ()))
    for p in pieces:
        if p.meta.get("fold_line") is None or p.meta.get("unfolded"):
            kept.append(p)
            continue
        try:
            kept.append(unfold(p))
        except InputError as exc:
            failed.append(piece_failure(p.name, exc, str(source), stage="unfold"))
    return Pieces.like(pieces, kept, failed=failed)


def _select(pieces: list[Piece], wanted: Sequence[str] | None, source: Path, grade: str | None = None,
            unfold: bool = False) -> Pieces:
    """The pieces named in ``wanted`` (in that order; all if None), with the failures among them;
    only those of size ``grade`` where it is given (:func:`graded`); those cut on the fold made whole
    with ``unfold`` (:func:`unfolded_pieces`).

    A name in ``wanted`` that names a piece that could not be read (or unfolded) is an error (its
    reason).
    """
    if grade is not None:
        pieces = graded(pieces, grade, source)
    if unfold:
        pieces = unfolded_pieces(pieces, source)
    failed = list(getattr(pieces, "failed", ()))
    if not wanted:
        return Pieces.like(pieces, pieces, failed=failed)
    # a name an earlier release gave (an alias: FreeSewing's "4", now "front") finds the piece
    resolve = Pieces.like(pieces, pieces, failed=failed).resolve
    wanted = [resolve(w) for w in wanted]
    skipped = {s.name for s in getattr(pieces, "skipped", ())}
    named = [w for w in wanted if w in skipped]
    if named:                         # --piece NAME of a skipped outline grids it
        pieces = Pieces.like(pieces, pieces, failed=failed).including(named, where=f"{source}: ")
    by_name = {p.name: p for p in pieces}
    bad = {f.name: f for f in failed}
    for w in wanted:
        if w not in by_name and w in bad:
            raise InputError(bad[w].message(source))
    missing = [w for w in wanted if w not in by_name]
    if missing:
        names = ", ".join([repr(p.name) for p in pieces] + [f"{f.name!r} (cannot be read)" for f in failed])
        raise InputError(f"{source}: no piece named {', '.join(repr(m) for m in missing)}; "
                         f"the pieces are {names}")
    out: list[Piece] = []
    for w in wanted:
        if by_name[w] not in out:
            out.append(by_name[w])
    return Pieces.like(pieces, out, failed=())


def no_piece_left(source: Path | str, failed: Sequence[PieceFailure], what: str = "gridded") -> Exception:
    """The error of a pattern file none of whose pieces could be used: the one failure's own
    error (its message naming the file and the piece) or a :class:`PiecesError` listing each."""
    if len(failed) == 1:
        f = failed[0]
        if isinstance(f.error, NotConvergedError):
            return f.error
        cls = type(f.error) if isinstance(f.error, InputError) else InputError
        try:
            exc = cls(f.message(source))
        except TypeError:            # an InputError subclass with another constructor
            exc = InputError(f.message(source))
        exc.failed = list(failed)    # type: ignore[attr-defined]
        return exc
    return PiecesError(f"{source}: none of its {len(failed)} pieces could be {what}: "
                       + "; ".join(f.message() for f in failed), failed, source)


def select_pieces(source: str | Path, wanted: Sequence[str] | None = None, *,
                  units: str | None = None, line: str = "sew",
                  include: Sequence[str] | None = None, grade: str | None = None,
                  unfold: bool = False) -> list[Piece]:
    """The pieces of a pattern file, only those named in ``wanted`` if given (in that order).

    A :class:`~clothgrid.patterns.piece.Pieces` list: ``failed`` holds the pieces that could not
    be read (none when ``wanted`` names pieces: naming one that cannot be read is an InputError),
    ``skipped`` the outlines skipped as annotations. ``line`` and ``include`` as for
    :func:`clothgrid.readers.read_pieces`; a name in ``wanted`` may be a skipped outline's.
    ``grade``: only the pieces of this size of a graded pattern (:func:`graded`). ``unfold``: the
    pieces cut on the fold made whole (:func:`unfolded_pieces`).
    """
    source = Path(source)
    return _select(read_pieces(source, units=units, line=line, include=include), wanted, source, grade,
                   unfold)


def corner_choice(piece: Piece, corners: Sequence[int] | None = None, near: Any = None,
                  min_turn: float | None = None) -> CornerChoice:
    """The grid corners of ``piece``: given indices, the points nearest to ``near``, or automatic."""
    if min_turn is not None and not (0 <= min_turn < 180):
        raise InputError(f"--min-turn {min_turn!r} must be between 0 and 180 degrees")
    return choose_corners(piece, corners, near, min_turn=MIN_TURN_DEG if min_turn is None else min_turn)


def _size(boundary: Boundary, options: GridOptions, pattern: bool) -> tuple[tuple[int, int] | None, float | None]:
    """Node counts and edge length of one job (see :class:`GridOptions`)."""
    text = options.edge_length
    if text is None:
        if options.nodes is None and pattern:
            return nodes_for_edge_length(boundary, DEFAULT_EDGE_LENGTH_MM), DEFAULT_EDGE_LENGTH_MM
        return options.nodes, None
    if pattern:
        h = parse_length(text, "mm", what="--edge-length")
    else:
        try:
            h = float(text)
        except (TypeError, ValueError):
            raise InputError(f"--edge-length {text!r}: a boundary JSON file has no units, so give "
                             "the edge length as a plain number in the file's units") from None
        if not 0 < h < float("inf"):
            raise InputError(f"--edge-length {text!r} must be positive and finite")
    return nodes_for_edge_length(boundary, h), h


def _corners_text(b: Boundary) -> str:
    """Where a boundary's four corners are and how many points its sides have (a line of
    ``-v``: a region file without corners has them chosen, :func:`clothgrid.patterns.outline_boundary`)."""
    at = " ".join("(" + ", ".join(f"{c:.6g}" for c in p[:b.dim]) + ")"
                  for p in (b.bottom[0], b.bottom[-1], b.top[-1], b.top[0]))
    counts = ", ".join(str(len(s)) for s in (b.bottom, b.right, b.top, b.left))
    return f"corners (bottom-left, bottom-right, top-right, top-left) {at}; sides of {counts} points"


def read_jobs(source: str | Path, outputs: Sequence[str | Path], plot: str | Path | None = None, *,
              options: GridOptions = GridOptions(), pieces: Sequence[str] | None = None,
              corners: Sequence[int] | None = None, corners_near: Any = None, min_turn: float | None = None,
              units: str | None = None, progress: Callable[[str], None] | None = None,
              line: str | None = None, include: Sequence[str] | None = None,
              grade: str | None = None, unfold: bool = False) -> list[Job]:
    """The jobs of one input file, outputs checked (nothing is gridded or written yet).

    Parameters
    ----------
    source : str or Path
        A boundary JSON file, or a pattern file (``.svg``, ``.dxf``, GarmentCode ``.json``).
    outputs, plot :
        Output paths (see the module's "Output names") and an optional PNG.
    options : GridOptions
        The size and solver options.
    pieces, corners, corners_near, min_turn :
        Pattern files only: the pieces to grid (default: all), their corners
        (one piece only) and the smallest turn of a corner candidate.
    units : str, optional
        Boundary file: the unit of its coordinates (default metres). Pattern
        file: read its coordinates in this unit instead of the one it states.
    line, include :
        Pattern files only: grid the ``"sew"`` (default) or ``"cut"`` line,
        and these outlines skipped as annotations (see
        :func:`clothgrid.readers.read_pieces`).
    grade : str, optional
        Pattern files only: the pieces of this size of a graded pattern (:func:`graded`).
    unfold : bool
        Pattern files only: grid each piece cut on the fold whole, the outline and its mirror
        image across the fold line the file marks (:func:`unfolded_pieces`).
    progress : callable, optional
        Called with a line saying what was read.

    Returns
    -------
    Jobs
        A list of :class:`Job`; its ``failed`` lists the pattern pieces that
        cannot be gridded (unreadable outline, no corners or boundary, a grid
        that does not fit in memory), each with its reason: they do not stop
        the others. The memory of every job is checked here, before any grid
        is made, counting the grids of the jobs before it (kept until written).

    Raises
    ------
    InputError
        An unreadable input, pattern options for a boundary file, an unknown
        output format, a missing output folder, two jobs writing one file, a
        piece asked for by name that cannot be read, no piece left to grid
        (:class:`PiecesError` when several failed), a boundary file's grid
        that does not fit in memory (:class:`SizeError`).
    """
    source = Path(source)
    t0 = time.perf_counter()
    got = read_input(source, units=units, line=line, include=include)
    if isinstance(got, Boundary):
        used = [name for name, v in (("--piece", pieces), ("--corners", corners), ("--corners-near", corners_near),
                                     ("--min-turn", min_turn), ("--line", line), ("--include", include),
                                     ("--grade", grade), ("--unfold", unfold)) if v]
        if used:
            raise InputError(f"{', '.join(used)} {'is' if len(used) == 1 else 'are'} for pattern files "
                             f"(.svg, .dxf, GarmentCode .json), not for the boundary file {source}")
        paths, plot_path = check_outputs(outputs, plot)
        if progress:
            progress(f"loaded {source} in {time.perf_counter() - t0:.3f} s; {_corners_text(got)}")
        nodes, h = _size(got, options, pattern=False)
        unit = units or getattr(got, "length_unit", None) or "m"
        job = Job(got.name or source.stem, got, nodes, paths, plot_path, length_unit=unit,
                  edge_length=h, options=options)
        _check_size(job)
        return Jobs([job], source=source)
    if min_turn is not None and not (0 <= min_turn < 180):
        raise InputError(f"--min-turn {min_turn!r} must be between 0 and 180 degrees")
    chosen = _select(got, pieces, source, grade, unfold)
    if progress:
        bad = f" ({len(chosen.failed)} more could not be read)" if chosen.failed else ""
        skipped = chosen.skipped
        progress(f"read {len(chosen)} piece{'s' if len(chosen) != 1 else ''} from {source} in "
                 f"{time.perf_counter() - t0:.3f} s{bad}" + (
                     f"; {len(skipped)} closed outline{'s' if len(skipped) != 1 else ''} skipped as "
                     "annotations (see 'clothgrid pieces'; --include NAME grids one)" if skipped else ""))
    if (corners is not None or corners_near is not None) and len(chosen) != 1:
        raise InputError("--corners and --corners-near need a single piece: pick one with --piece NAME")
    names = [p.name for p in chosen]
    order = {n: i for i, n in enumerate([*names, *(f.name for f in chosen.failed)])}
    outs = output_names(outputs, names)
    plots = output_names([plot], names) if plot is not None else None
    jobs: list[Job] = []
    failed: list[PieceFailure] = list(chosen.failed)
    seen: list[Path] = []
    for k, piece in enumerate(chosen):
        paths, plot_path = check_outputs(outs[k], plots[k][0] if plots else None)
        for p in paths + ([plot_path] if plot_path else []):
            if p in seen:
                raise InputError(f"two pieces would write the same file {str(p)!r}: put {{piece}} in the output name")
            seen.append(p)
        try:
            choice = corner_choice(piece, corners, corners_near, min_turn)
            boundary = piece_boundary(piece, choice=choice)
        except InputError as exc:
            if (corners is not None or corners_near is not None):
                raise          # the corners the user gave for this one piece
            failed.append(piece_failure(piece.name, exc, str(source), stage="corners"))
            continue
        nodes, h = _size(boundary, options, pattern=True)
        jobs.append(Job(piece.name, boundary, nodes, paths, plot_path, length_unit="mm",
                        piece=piece_info(piece, choice, h), corners=choice.message, edge_length=h,
                        options=options, pattern=piece, choice=choice))
    fit: list[Job] = []
    kept = 0
    for job in jobs:        # memory, before any grid is made: a piece too big is that piece's failure
        try:
            kept += _check_size(job, kept, what=f"piece {job.name!r}: ")
        except InputError as exc:
            if not isinstance(exc, SizeError):
                raise       # bad options (a solver the backend does not run): every piece's
            failed.append(piece_failure(job.name, exc, str(source), stage="size"))
            continue
        fit.append(job)
    failed.sort(key=lambda f: order.get(f.name, len(order)))
    if not fit:
        raise no_piece_left(source, failed, "read" if all(f.stage == "read" for f in failed) else "gridded")
    doubt = units_warning(chosen, units)
    return Jobs(fit, failed, source, [doubt] if doubt else [])


def _check_size(job: Job, kept: int = 0, what: str = "") -> int:
    """Check that ``job``'s grid fits (memory; SizeError), counting ``kept`` bytes held already;
    return the bytes its result keeps until it is written."""
    nodes = job.nodes if job.nodes is not None else job.boundary.shape
    o = job.options
    check_size(nodes, solver=o.solver, backend=o.backend, weights=o.edge_weights(), stop=o.stop,
               dim=job.boundary.dim, kept=kept, what=what)
    nu, nv = parse_nodes(nodes)
    return KEPT_BYTES_PER_NODE * nu * nv


# --------------------------------------------------------------------------- gridding and writing


@one_blas_thread()     # the grid and its figures on Numba's threads, OpenBLAS's kept still (clothgrid.blas_threads)
def run_job(job: Job, progress: Callable[[str], None] | None = None) -> Result:
    """Grid one job: :func:`clothgrid.generate` with the job's options, then its quality (once).

    Raises what :func:`clothgrid.generate` raises (InputError, NotConvergedError).
    """
    t0 = time.perf_counter()
    kwargs = job.options.generate_kwargs()
    grid = generate(job.boundary, job.nodes, progress=progress, **kwargs)
    seconds = time.perf_counter() - t0
    t1 = time.perf_counter()
    q = getattr(grid, "_quality", None) or quality(grid)   # the fold-free step measured its grid already
    figures = sim_figures(grid.points, job.edge_length)
    quality_seconds = time.perf_counter() - t1
    if job.pattern is not None and job.choice is not None and kwargs["functional"] != "length":
        t2 = time.perf_counter()
        better = runners_up(job.pattern, job.choice, (grid, q, figures), job.edge_length, job.nodes,
                            lambda b, n: generate(b, n, progress=progress, **kwargs), progress)
        if better is not None:
            choice, boundary, nodes, (grid, q, figures) = better
            job = replace(job, boundary=boundary, nodes=nodes, choice=choice, corners=choice.message,
                          piece=piece_info(job.pattern, choice, job.edge_length))
        seconds += time.perf_counter() - t2
    if job.piece is not None:
        grid.info["piece"] = job.piece
    # The writers read the coordinates' unit from info["length_unit"] (clothgrid.cloth).
    grid.info["length_unit"] = job.length_unit
    grid.info["quality"] = {"folded": int(q.folded), **figures, "missed": targets_met(figures, q.folded)}
    return Result(job, grid, q, seconds, quality_seconds=quality_seconds)


#: An automatic corner choice whose grid folds, or has a cell angle under this (degrees), has its
#: runners-up gridded too (:attr:`~clothgrid.patterns.CornerChoice.alternatives`), the best kept.
RUNNER_UP_BELOW_DEG = TARGET_MIN_ANGLE_DEG
#: A runner-up is kept where it folds fewer cells, or as many and its smallest angle is larger by this
#: (degrees).
RUNNER_UP_GAIN_DEG = 1.0
#: Runners-up are gridded only where the first grid has at most this many nodes (a piece of a metre at
#: 2 mm edges has about 150,000; each runner-up costs another whole grid).
RUNNER_UP_MAX_NODES = 1 << 18
#: A grid without folds or small angles whose edge spread (longest / shortest edge) is above this, of
#: a piece without darts, also has its first :data:`RUNNER_UP_SPREAD_TRIES` runners-up gridded; one is
#: kept where its spread is at most :data:`RUNNER_UP_SPREAD_GAIN` of the best so far, without folds and
#: with a smallest angle of at least the first's (up to :data:`RUNNER_UP_KEEP_DEG`). On the survey's 455
#: pieces at 10 mm, 44 such grids are above 2x the target 4: the first runner-up lowered 14 of them by
#: a third or more (AAMA racer fronts 13.1 -> 2.0, sleeves 9.7 -> 5.1, a GarmentCode dress top 10.6 ->
#: 6.9, their angles mostly larger), the second and third none further; the 7 with darts gained nothing
#: (a dart's tip sets their spread whatever the corners). docs/patterns.md has the figures.
RUNNER_UP_SPREAD = 2.0 * TARGET_EDGE_SPREAD
RUNNER_UP_SPREAD_GAIN = 2.0 / 3.0
RUNNER_UP_KEEP_DEG = 20.0
RUNNER_UP_SPREAD_TRIES = 1


def runners_up(piece: Piece, choice: CornerChoice, first: tuple[Grid, Quality, dict[str, Any]],
               edge_length: float | None, nodes: Any, make: Callable[[Boundary, Any], Grid],
               progress: Callable[[str], None] | None = None
               ) -> tuple[CornerChoice, Boundary, Any, tuple[Grid, Quality, dict[str, Any]]] | None:
    """Where ``first`` (the grid of ``choice``, its quality and :func:`sim_figures`) folds, or has a cell
    angle under :data:`RUNNER_UP_BELOW_DEG` that its outline does not force
    (:func:`~clothgrid.generate.forced_by_outline`: a dart's tip does), grid ``choice``'s
    runners-up in turn with ``make(boundary,
    nodes)`` (nodes from ``edge_length`` where given, else ``nodes``) until one meets both; return the
    best (choice, boundary, nodes, (grid, quality, figures)), or None where ``first`` is best or good.
    Where ``first`` only has an edge spread above :data:`RUNNER_UP_SPREAD`, a runner-up is kept for a
    spread of at most :data:`RUNNER_UP_SPREAD_GAIN` of the best so far with no fold and no smaller
    angle (up to :data:`RUNNER_UP_KEEP_DEG`); the first within the target spread ends the search.

    The coarse grids that rank corner sets (:func:`clothgrid.patterns.corners.coarse_grid`) are
    relaxed over every node at their own node counts; a real grid starts from the length solve at the
    piece's, and now and then one corner set ranked first does much worse there (a real Seamly2D
    front: 6.4 degrees, its runners-up 21-26). A runner-up that cannot be gridded is passed over.
    Of the survey's 455 pieces (docs/patterns.md) 13 are under 10 degrees, every one at a dart's tip
    or a notch, where other corners gained at most 1.4 degrees for 1.3 s of grids: those are left.
    """
    def key(q: Quality, f: dict[str, Any]) -> tuple[int, float]:
        return int(q.folded), -float(f["min_angle_deg"])

    def sound(q: Quality, f: dict[str, Any]) -> bool:
        return not q.folded and f["min_angle_deg"] >= RUNNER_UP_BELOW_DEG

    def good(q: Quality, f: dict[str, Any]) -> bool:
        return sound(q, f) and f["edge_spread"] <= RUNNER_UP_SPREAD

    if not choice.alternatives or good(first[1], first[2]):
        return None
    f0 = first[2]
    nodes_first = first[0].shape[0] * first[0].shape[1]
    if nodes_first > RUNNER_UP_MAX_NODES:
        if progress is not None:
            progress(f"corners' runners-up not tried: {nodes_first} nodes, more than {RUNNER_UP_MAX_NODES} "
                     "(give other corners with --corners; clothgrid pieces lists the runners-up)")
        return None
    spread_only = sound(first[1], f0)        # no fold, no small angle: only the edge spread is poor
    if spread_only and choice.darts:
        return None
    if not first[1].folded and not spread_only and forced_by_outline(np.ascontiguousarray(first[0].points[..., :2])):
        return None
    why = (f"its grid folded {first[1].folded} cells" if first[1].folded
           else f"its grid's edge spread was {f0['edge_spread']:.3g}" if spread_only
           else f"its grid's smallest angle was {f0['min_angle_deg']:.3g}°")
    best: tuple[tuple[int, float], Any] = (key(first[1], f0), None)
    spread, floor = float(f0["edge_spread"]), min(float(f0["min_angle_deg"]), RUNNER_UP_KEEP_DEG)
    for k in range(min(len(choice.alternatives), RUNNER_UP_SPREAD_TRIES) if spread_only else len(choice.alternatives)):
        alt = choice.runner_up(k, why)
        try:
            boundary = piece_boundary(piece, choice=alt)
            n = nodes_for_edge_length(boundary, edge_length) if edge_length is not None else nodes
            grid = make(boundary, n)                 # (which checks its memory first)
        except (InputError, NotConvergedError, ValueError, FloatingPointError):
            continue
        q = getattr(grid, "_quality", None) or quality(grid)
        f = sim_figures(grid.points, edge_length)
        if progress is not None:
            progress(f"corners {', '.join(map(str, alt.corners))} (runner-up {k + 2}): {q.folded} folded cells, "
                     f"smallest angle {f['min_angle_deg']:.3g}°, edge spread {f['edge_spread']:.3g}")
        if spread_only:
            if not q.folded and f["min_angle_deg"] >= floor and f["edge_spread"] <= RUNNER_UP_SPREAD_GAIN * spread:
                best, spread = (key(q, f), (alt, boundary, n, (grid, q, f))), float(f["edge_spread"])
                if f["edge_spread"] <= TARGET_EDGE_SPREAD:
                    break
            continue
        kk = key(q, f)
        if kk[0] < best[0][0] or (kk[0] == best[0][0] and kk[1] < best[0][1] - RUNNER_UP_GAIN_DEG):
            best = (kk, (alt, boundary, n, (grid, q, f)))
            if sound(q, f):
                break
    return best[1]


def report_entry(result: Result) -> dict[str, Any]:
    """One piece's line of the quality report (``--report``): figures, targets missed, corners, time."""
    info = result.grid.info
    entry: dict[str, Any] = {"name": result.job.name, "nodes": list(result.grid.shape),
                             "edge_length": result.job.edge_length, "seconds": result.seconds,
                             "functional": info.get("functional"), "weights": info.get("weights"),
                             **info.get("quality", {})}
    if result.job.piece is not None:
        corners = result.job.piece.get("corners", {})
        entry["corners"] = {"method": corners.get("method"), "indices": corners.get("indices"),
                            "points": corners.get("points")}
    return entry


def _finite(value: Any) -> Any:
    """``value`` with every non-finite float made ``None`` (JSON has no inf or NaN)."""
    if isinstance(value, float):
        return value if value == value and abs(value) != float("inf") else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def write_report(path: str | Path, source: str | Path, results: Sequence[Result],
                 failed: Sequence[Any] = ()) -> Path:
    """Write the quality report of a run as JSON, atomically (temporary file, then rename).

    Missing folders of ``path`` are created (and removed again if the write fails).

    Holds the targets (:mod:`clothgrid.quality`), one entry per piece
    (:func:`report_entry`) and the pieces that failed with their reasons.
    """
    import json

    from .quality import FLOOR_MIN_ANGLE_DEG, TARGET_EDGE_SPREAD, TARGET_MIN_ANGLE_DEG

    data = {
        "input": str(source),
        "targets": {"folded": 0, "min_angle_deg": TARGET_MIN_ANGLE_DEG,
                    "min_angle_floor_deg": FLOOR_MIN_ANGLE_DEG, "edge_spread": TARGET_EDGE_SPREAD,
                    "note": "angles leave out the four cells at the grid's corners"},
        "pieces": [_finite(report_entry(r)) for r in results],
        "failed": [{"name": getattr(f, "name", "?"), "reason": getattr(f, "reason", str(f))} for f in failed],
    }
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    made = make_folders([path])           # like the outputs' folders
    try:
        tmp.write_text(json.dumps(data, indent=1, allow_nan=False, default=float) + "\n")
        os.replace(tmp, path)
    except OSError as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:                     # e.g. a "folder" of the path is a file
            pass
        remove_folders(made)
        raise InputError(f"cannot write the report {str(path)!r}: {exc.strerror or exc}") from exc
    return path


def run_jobs(jobs: Sequence[Job], progress: Callable[[str], None] | None = None,
             done: Callable[[Result], None] | None = None) -> tuple[list[Result], list[PieceFailure]]:
    """Grid every job (:func:`run_job`); a pattern piece that fails does not stop the others.

    Parameters
    ----------
    jobs : Jobs or list of Job
        From :func:`read_jobs` (its ``failed`` are carried into the answer).
    progress : callable, optional
        Passed to :func:`clothgrid.generate`.
    done : callable, optional
        Called with each result as soon as it is made.

    Returns
    -------
    results : list of Result
        The grids made, in job order.
    failed : list of PieceFailure
        ``jobs.failed`` and then each pattern piece whose gridding raised
        :class:`InputError` or :class:`NotConvergedError` (stage ``"grid"``).

    Raises
    ------
    InputError, NotConvergedError
        A boundary-file job's error (it has no other piece to go on with), and
        the error of the only piece when no piece at all could be gridded
        (:func:`no_piece_left`: a :class:`PiecesError` when several failed).
    """
    results: list[Result] = []
    failed: list[PieceFailure] = list(getattr(jobs, "failed", ()))
    source = getattr(jobs, "source", None)
    for job in jobs:
        try:
            result = run_job(job, progress)
        except (InputError, NotConvergedError) as exc:
            if job.piece is None:
                raise
            failed.append(piece_failure(job.name, exc, "" if source is None else str(source), stage="grid"))
            continue
        if done is not None:
            done(result)
        results.append(result)
    if not results and failed:
        raise no_piece_left(source if source is not None else "input", failed)
    return results, failed


def write_result(result: Result, options: OutputOptions = OutputOptions()) -> list[Path]:
    """Write one result's outputs and plot; on any failure remove what this call wrote and re-raise.

    An OSError becomes an :class:`InputError` naming the file.
    """
    job = result.job
    written: list[Path] = []
    made: list[Path] = []
    try:
        made = make_folders(job.outputs + ([job.plot] if job.plot is not None else []))
        for path in job.outputs:
            written.append(Path(writers.save(result.grid, path, **options.for_writer(path.suffix))))
        if job.plot is not None:
            from .plot import plot_grid  # matplotlib takes ~0.7 s to import: only when asked

            written.append(Path(plot_grid(result.grid, job.plot, title=job.name, quality=result.quality)))
    except BaseException as exc:
        for path in written:
            path.unlink(missing_ok=True)
        remove_folders(made)
        if isinstance(exc, OSError):
            name = getattr(exc, "filename", None) or "output"
            raise InputError(f"cannot write {name}: {exc.strerror or exc}") from exc
        raise
    result.written = written
    result.folders = made
    return written


def write_results(results: Sequence[Result], options: OutputOptions = OutputOptions()) -> list[Path]:
    """Write every result (:func:`write_result`); on any failure remove every file this call wrote."""
    written: list[Path] = []
    folders: list[Path] = []
    try:
        for r in results:
            written += write_result(r, options)
            folders = r.folders + folders
    except BaseException:
        for p in written:
            p.unlink(missing_ok=True)
        remove_folders(folders)
        raise
    return written


def generate_piece(piece: Piece, nodes: Any = None, *, edge_length: float | str | None = None,
                   corners: Sequence[int] | None = None, near: Any = None,
                   choice: CornerChoice | None = None, **kwargs: Any) -> Grid:
    """Grid a pattern piece: corners, boundary, node counts, :func:`clothgrid.generate`.

    Where the corners are chosen automatically and the fold-free grid (any functional but
    ``"length"``, the paper's, which may fold) folds or has a cell angle under 10 degrees, the
    choice's runners-up are gridded too and the best grid returned (:func:`runners_up`).

    Parameters
    ----------
    piece : Piece
    nodes : int or (int, int) or str, optional
        Grid size; give this or ``edge_length``.
    edge_length : float or str, optional
        Target grid edge length (each direction's typical grid line over it:
        :func:`~clothgrid.patterns.nodes_for_edge_length`): millimetres, or text
        with a unit such as ``"5mm"`` or ``"0.25in"``. Default (neither given): 10 mm.
    corners, near, choice :
        Corner choice (see :func:`clothgrid.patterns.choose_corners`); default automatic.
    **kwargs :
        Passed to :func:`clothgrid.generate` (solver, weights, tol, ...).

    Returns
    -------
    Grid
        With ``info["piece"]``: name, units (``"mm"``: the grid's coordinates),
        file units, size, corner choice (indices, points, method, message),
        grain line, notes.
    """
    if nodes is not None and edge_length is not None:
        raise InputError("give the grid size as nodes or as an edge length, not both")
    if choice is None:
        choice = choose_corners(piece, corners, near)
    boundary = piece_boundary(piece, choice=choice)
    h = None
    if nodes is None:
        h = DEFAULT_EDGE_LENGTH_MM if edge_length is None else parse_length(edge_length, "mm", what="edge length")
        nodes = nodes_for_edge_length(boundary, h)
    kwargs.setdefault("weights", "uniform")
    kwargs.setdefault("functional", "auto")
    grid = generate(boundary, nodes, **kwargs)
    if choice.alternatives and kwargs["functional"] != "length":
        q = getattr(grid, "_quality", None) or quality(grid)
        better = runners_up(piece, choice, (grid, q, sim_figures(grid.points, h)), h, nodes,
                            lambda b, n: generate(b, n, **kwargs), kwargs.get("progress"))
        if better is not None:
            choice, grid = better[0], better[3][0]
    grid.info["piece"] = piece_info(piece, choice, h)
    return grid


def piece_listing(pieces: Sequence[Piece], *, min_turn: float | None = None, candidates: bool = False,
                  failed: list[PieceFailure] | None = None) -> list[dict[str, Any]]:
    """What ``clothgrid pieces`` shows of each piece: size, units, outline, corner choice and candidates.

    With a ``failed`` list, a piece whose corners cannot be chosen is appended
    to it (stage ``"corners"``) and left out of the listing; without, its
    InputError is raised.
    """
    from .patterns import corner_candidates

    out = []
    for piece in pieces:
        try:
            choice = corner_choice(piece, min_turn=min_turn)
        except InputError as exc:
            if failed is None or (min_turn is not None and not (0 <= min_turn < 180)):
                raise
            failed.append(piece_failure(piece.name, exc, stage="corners"))
            continue
        w, h = piece.extent
        entry = {
            "name": piece.name, "aliases": list(piece.aliases), "source": piece.source, "file_units": piece.units,
            "size_mm": [w, h], "perimeter_mm": piece.perimeter, "area_mm2": piece.area,
            "outline_points": len(piece.outline), "turn_points": len(piece.turn_points),
            "sampling_tolerance_mm": piece.tolerance,
            "grain_line": None if piece.grain_line is None else piece.grain_line.tolist(),
            "corners": choice.as_dict(), "line": piece.meta.get("line"), "notes": list(piece.notes),
            "fold_line": piece.meta.get("fold_line"), "unfolded": bool(piece.meta.get("unfolded")),
            "cut": cut_of(piece),
        }
        if candidates:
            entry["candidates"] = [c.as_dict() for c in
                                   corner_candidates(piece, MIN_TURN_DEG if min_turn is None else min_turn)]
        out.append(entry)
    return out


def cut_of(piece: Piece) -> list[dict[str, Any]]:
    """What the file says to cut of ``piece``: the cut instructions drawn on it (``meta["cut"]``, SVG:
    :func:`~clothgrid.patterns.piece.cut_instructions`), else its AAMA/flat DXF ``Quantity:`` (whether
    mirrored unknown: ``None``), else ``[]``."""
    if piece.meta.get("cut"):
        return [dict(c) for c in piece.meta["cut"]]
    try:
        n = int(str(piece.meta.get("quantity", "")).strip())
    except ValueError:
        return []
    if not 0 < n <= MAX_CUT_COUNT:
        return []
    return [{"count": n, "material": piece.meta.get("material"), "mirrored": None,
             "on_fold": piece.meta.get("fold_line") is not None}]


def cut_text(cut: Sequence[dict[str, Any]]) -> str:
    """:func:`cut_of`'s answer in words: ``2 mirrored from main fabric; 2 from interfacing``."""
    return "; ".join(f"{c['count']}" + (" mirrored" if c.get("mirrored") else "")
                     + (" on the fold" if c.get("on_fold") else "")
                     + (f" from {c['material']}" if c.get("material") else "") for c in cut)


def skipped_listing(pieces: Sequence[Piece]) -> list[dict[str, Any]]:
    """What ``clothgrid pieces`` shows of the outlines skipped as annotations: name, kind, reason, size."""
    return [s.as_dict() for s in getattr(pieces, "skipped", ())]
