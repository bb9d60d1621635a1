"""Grid whole collections of pattern files on Dask: :func:`batch` (``clothgrid batch``).

Every piece of every input file is gridded with the same options as
``clothgrid generate`` (:class:`~clothgrid.pipeline.GridOptions`), through the
same pipeline (:func:`~clothgrid.pipeline.read_jobs`,
:func:`~clothgrid.pipeline.run_jobs`, :func:`~clothgrid.pipeline.write_results`),
one Dask task per input file::

    from clothgrid.batch import batch
    from clothgrid.pipeline import GridOptions

    summary = batch(["patterns/", "more/*.svg"], "meshes", options=GridOptions(edge_length="5mm"),
                    workers=4)                 # or scheduler="tcp://host:8786", or client=Client(...)
    summary.counts                             # {"ok": ..., "partial": ..., "failed": ..., "skipped": ...}

Outputs go to ``OUTDIR/<stem>/<piece>.npz`` (``templates``), one folder per
input named after its file stem; stems that collide (``a/front.svg``,
``b/front.svg``, ``front.dxf``) all get ``-<8 hex digits of the sha1 of the
absolute path>`` appended, the same on every run. ``OUTDIR/manifest.jsonl``
(:mod:`clothgrid.batch_manifest`) has one line per input, appended only
after every output of the input exists; a rerun skips inputs already done
with the same content and options. Scheduling, retries and lost workers are
Dask's: a local cluster of worker processes (one thread each) by default, or
an existing cluster. Each worker grids a small piece once when it starts
(:class:`WarmUp`), so the Numba kernels are loaded (from the on-disk cache, or
compiled) once per worker, not once per file.
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import logging
import os
import sys
import time
import types
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence

from .batch_manifest import (MANIFEST, ManifestWriter, compact_manifest, file_sha256, is_done, latest_entries,
                             options_key, read_manifest, summarise)
from .errors import InputError, MissingDependencyError, NotConvergedError
from .pipeline import GridOptions, OutputOptions, check_outputs, read_jobs, report_entry, run_jobs, safe_name, \
    size_key, write_results

__all__ = ["batch", "BatchSummary", "FileTask", "find_inputs", "assign_stems", "grid_file", "warm_up", "WarmUp",
           "ProgressLine", "DEFAULT_TEMPLATE", "DEFAULT_RETRIES", "default_workers", "worker_threads"]

#: outputs of one input, relative to its folder ``OUTDIR/<stem>/``
DEFAULT_TEMPLATE = "{piece}.npz"
#: the output of an input in garment mode, and the formats a garment is written as
GARMENT_TEMPLATE = "garment.npz"
GARMENT_FORMATS = (".npz", ".obj", ".usda", ".usd", ".usdc")
#: how often the scheduler retries a task that raised or whose worker died
DEFAULT_RETRIES = 2
#: file extensions picked up from folders (glob patterns and files given by name may be any)
PATTERN_SUFFIXES = (".json", ".svg", ".dxf")

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- inputs and names


def find_inputs(inputs: Sequence[str | Path]) -> list[Path]:
    """The input files: files as given, folders searched recursively for pattern files
    (``.json``, ``.svg``, ``.dxf``, any case), glob patterns (``**`` allowed) expanded.

    Returns absolute paths, sorted, each once. Raises :class:`InputError` for a name that
    is neither a file, a folder nor a pattern matching a file, and when nothing is found.
    """
    found: list[Path] = []
    for item in inputs:
        text = str(item)
        p = Path(text)
        if p.is_dir():
            hits = [q for q in p.rglob("*") if q.is_file() and q.suffix.lower() in PATTERN_SUFFIXES
                    and not any(part.startswith(".") for part in q.relative_to(p).parts)]
            if not hits:
                raise InputError(f"{text}: no pattern file (.json, .svg, .dxf) in this folder")
        elif p.is_file():
            hits = [p]
        elif glob.has_magic(text):
            hits = [Path(q) for q in glob.glob(text, recursive=True) if Path(q).is_file()]
            if not hits:
                raise InputError(f"{text}: no file matches this pattern")
        else:
            raise InputError(f"{text}: no such file or folder")
        found += [q.resolve() for q in hits]
    out = sorted(set(found))
    if not out:
        raise InputError("no input files")
    return out


def assign_stems(paths: Sequence[Path]) -> list[str]:
    """The output folder name of each input: its file stem made file-safe; stems that collide
    (ignoring case) all get ``-<sha1 of the absolute path, 8 hex digits>``: deterministic,
    whatever the order of the inputs."""
    stems = [safe_name(Path(p).stem) for p in paths]
    count: dict[str, int] = {}
    for s in stems:
        count[s.lower()] = count.get(s.lower(), 0) + 1
    out = []
    for p, s in zip(paths, stems):
        if count[s.lower()] > 1 or s.lower() == Path(MANIFEST).stem:
            s = f"{s}-{hashlib.sha1(str(Path(p).resolve()).encode()).hexdigest()[:8]}"
        out.append(s)
    return out


def default_workers() -> int:
    """Workers of a local cluster: the CPU cores this process may use, at most a container's CPU
    limit (:func:`clothgrid.cgroups.usable_processors`: a 2-CPU pod on a 64-core node starts 2
    workers, not 64 and their memory)."""
    from .cgroups import usable_processors

    return usable_processors()


def worker_threads(workers: int) -> int:
    """Numba threads of each of ``workers`` local workers: the cores left to share, at least one
    (one worker gridding one file on a 2-core machine uses both)."""
    return max(1, default_workers() // max(1, workers))


# --------------------------------------------------------------------------- one file (runs on a worker)


@dataclass(frozen=True)
class FileTask:
    """Everything a worker needs to grid one input file (small and picklable).

    Attributes
    ----------
    source : str
        The input file (absolute path; workers must see the same file system).
    stem : str
        Its output folder's name inside ``outdir``.
    outdir : str
        The output folder of the run.
    templates : tuple of str
        Output names relative to ``outdir/stem`` (``{piece}`` is the piece's name).
    options, output :
        How grids are made and written.
    units, line, min_turn, unfold, grade :
        Pattern-file options of :func:`clothgrid.pipeline.read_jobs`.
    key, sha256 :
        The resume key and the content hash, copied into the manifest line.
    garment, seams :
        Make the input one sewn garment (:func:`clothgrid.garment.garment`) instead of a grid
        per piece; ``seams`` is ``"keep"`` or ``"weld"`` for its outputs.
    """

    source: str
    stem: str
    outdir: str
    templates: tuple[str, ...]
    options: GridOptions
    output: OutputOptions
    units: str | None = None
    line: str | None = None
    min_turn: float | None = None
    key: str = ""
    sha256: str = ""
    garment: bool = False
    seams: str = "keep"
    unfold: bool = False
    grade: str | None = None


def _clean_stale(folder: Path) -> None:
    """Remove temporary files that a killed writer left in ``folder`` (``.NAME.XXXX.tmp``)."""
    if folder.is_dir():
        for p in folder.glob(".*.tmp"):
            p.unlink(missing_ok=True)


def _worker_name() -> str | None:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return None


def grid_file(task: FileTask) -> dict[str, Any]:
    """Grid every piece of one input and write its outputs; return its manifest line.

    Errors of the file itself (unreadable, no piece that can be gridded, not
    converged) give status ``failed`` with ``retry`` false; pieces that fail
    while others are written give ``partial``. A write error gives ``failed``
    with ``retry`` true (nothing of the file is left: the writers remove what
    they wrote). Anything else raises, for the scheduler to retry.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    folder = Path(task.outdir) / task.stem
    entry: dict[str, Any] = {"input": task.source, "stem": task.stem, "key": task.key, "sha256": task.sha256,
                             "status": "failed", "error": None, "error_type": None, "retry": False,
                             "pieces": [], "failed_pieces": [], "outputs": [], "worker": _worker_name()}
    timings: dict[str, float] = {}
    entry["timings"] = timings
    stage = "read"
    if task.garment:
        return _grid_garment(task, entry, timings, t0, c0)
    try:
        jobs = read_jobs(task.source, [str(folder / t) for t in task.templates], options=task.options,
                         units=task.units, line=task.line, min_turn=task.min_turn, unfold=task.unfold,
                         grade=task.grade)
        timings["read"] = time.perf_counter() - t0
        stage = "grid"
        results, failed = run_jobs(jobs)
        timings["grid"] = time.perf_counter() - t0 - timings["read"]
        stage = "write"
        t1 = time.perf_counter()
        _clean_stale(folder)
        write_results(results, task.output)
        timings["write"] = time.perf_counter() - t1
    except (InputError, NotConvergedError) as exc:
        entry.update(error=str(exc), error_type=type(exc).__name__, retry=stage == "write",
                     failed_pieces=[f.as_dict() for f in getattr(exc, "failed", ())])
        timings["total"] = time.perf_counter() - t0
        timings["cpu"] = time.process_time() - c0
        return entry
    outdir = Path(task.outdir)
    for r in results:
        piece = report_entry(r)
        piece["outputs"] = [p.relative_to(outdir).as_posix() for p in r.written]
        entry["pieces"].append(piece)
        entry["outputs"] += piece["outputs"]
    entry["failed_pieces"] = [f.as_dict() for f in failed]
    if jobs.warnings:
        entry["warnings"] = list(jobs.warnings)       # e.g. a piece size that suggests other units
    entry["status"] = "partial" if failed else "ok"
    if failed:
        entry["error"] = "; ".join(f.message() for f in failed)
    timings["total"] = time.perf_counter() - t0
    timings["cpu"] = time.process_time() - c0
    return entry


def _grid_garment(task: FileTask, entry: dict[str, Any], timings: dict[str, float],
                  t0: float, c0: float) -> dict[str, Any]:
    """:func:`grid_file` for ``task.garment``: one sewn garment per input, its panels as the pieces."""
    from .garment import garment, write_garment

    folder = Path(task.outdir) / task.stem
    written: list[Path] = []
    stage = "grid"
    try:
        g = garment(task.source, edge_length=task.options.edge_length or "10mm", units=task.units,
                    weights=task.options.edge_weights(), functional=task.options.functional)
        timings["grid"] = time.perf_counter() - t0
        stage = "write"
        t1 = time.perf_counter()
        _clean_stale(folder)
        folder.mkdir(parents=True, exist_ok=True)
        for t in task.templates:
            written.append(write_garment(g, folder / t.replace("{piece}", "garment"), seams=task.seams,
                                         density=task.output.density))
        timings["write"] = time.perf_counter() - t1
    except (InputError, NotConvergedError) as exc:
        for w in written:
            w.unlink(missing_ok=True)
        entry.update(error=str(exc), error_type=type(exc).__name__, retry=stage == "write")
        timings["total"] = time.perf_counter() - t0
        timings["cpu"] = time.process_time() - c0
        return entry
    outdir = Path(task.outdir)
    entry["outputs"] = [w.relative_to(outdir).as_posix() for w in written]
    entry["pieces"] = [{k: p.get(k) for k in ("name", "nodes", "folded", "min_angle_deg", "corners")}
                       for p in g.info.get("panels", [])]
    entry["garment"] = {"panels": len(g.panel_names), "stitches": len(g.spec.stitches),
                        "stitched_node_pairs": int(len(g.stitches)), "nodes": int(len(g.points))}
    entry["status"] = "ok"
    timings["total"] = time.perf_counter() - t0
    timings["cpu"] = time.process_time() - c0
    return entry


_WARM: dict[str, Any] = {}


#: a small pattern (a six-sided panel with a curved top, in mm) that :func:`warm_up` grids
_WARM_SVG = """<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="400mm" viewBox="0 0 300 400">
<path id="warm" d="M 0 0 L 150 0 L 300 0 L 280 300 Q 150 420 20 300 L 10 150 Z"/></svg>
"""


def warm_up(options: GridOptions = GridOptions()) -> float:
    """Grid a small six-sided SVG panel once in this process with ``options``, through the whole
    pipeline (reader, corner ranking, grid, fold-free step, quality), and import the other pattern
    readers, so that the Numba kernels and the readers are loaded before the first file; return
    the seconds it took (0 when done before in this process)."""
    if "seconds" in _WARM:
        return 0.0
    import importlib
    import tempfile

    t0 = time.perf_counter()
    for module in ("svg", "dxf", "garmentcode"):
        importlib.import_module(f"clothgrid.patterns.{module}")
    warm = GridOptions(edge_length="20mm", **{k: v for k, v in asdict(options).items()
                                            if k not in ("nodes", "edge_length")})
    with tempfile.TemporaryDirectory(prefix="clothgrid-warm-") as tmp:
        path = Path(tmp) / "warm.svg"
        path.write_text(_WARM_SVG)
        try:
            run_jobs(read_jobs(path, [str(Path(tmp) / "{piece}.npz")], options=warm))
        except (InputError, NotConvergedError) as exc:   # the files will say it again, one by one
            log.warning("clothgrid warm-up failed: %s", exc)
    _WARM["seconds"] = time.perf_counter() - t0
    return _WARM["seconds"]


def _warm_up_plugin_base() -> type:
    try:
        from distributed.diagnostics.plugin import WorkerPlugin
    except ImportError:             # the class is then only used where distributed is importable
        return object
    return WorkerPlugin


class WarmUp(_warm_up_plugin_base()):  # type: ignore[misc]
    """A Dask worker plugin: :func:`warm_up` once when each worker starts (and on workers that
    join later), so the kernels are loaded once per worker."""

    name = "clothgrid-warm-up"

    def __init__(self, options: GridOptions = GridOptions()) -> None:
        self.options = options

    def setup(self, worker: Any) -> None:
        try:
            warm_up(self.options)
        except Exception as exc:   # noqa: BLE001 - never keep a worker from starting
            log.warning("clothgrid warm-up failed: %s", exc)


# --------------------------------------------------------------------------- progress


@dataclass
class BatchProgress:
    """Where a run stands; passed to the progress callback after each file."""

    total: int                  # inputs to grid in this run (not counting those skipped)
    skipped: int = 0
    done: int = 0
    pieces: int = 0
    failed_files: int = 0
    failed_pieces: int = 0
    started: float = field(default_factory=time.perf_counter)
    last: dict[str, Any] | None = None

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.started

    @property
    def rate(self) -> float:
        """Files per second so far."""
        return self.done / self.elapsed if self.done and self.elapsed > 0 else 0.0

    @property
    def eta(self) -> float | None:
        """Seconds left at the rate so far (None before the first file)."""
        return (self.total - self.done) / self.rate if self.rate > 0 else None


def _clock(seconds: float | None) -> str:
    if seconds is None:
        return "--:--"
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60:02d}:{s % 60:02d}"


class ProgressLine:
    """Prints a run's progress: one line redrawn in place on a terminal (a bar, files and pieces,
    failures, rate, time left), or on other streams (logs) a plain line every ``every`` files
    and at the end (``every=0``: only at the end)."""

    def __init__(self, stream: Any = None, every: int | None = None, width: int = 24) -> None:
        self.stream = sys.stderr if stream is None else stream
        isatty = getattr(self.stream, "isatty", None)
        self.tty = bool(isatty and isatty())
        self.every = every
        self.width = width
        self._shown = 0

    def text(self, p: BatchProgress) -> str:
        fails = f", failed {p.failed_files} files / {p.failed_pieces} pieces" if (
            p.failed_files or p.failed_pieces) else ""
        piece_rate = p.pieces / p.elapsed if p.elapsed > 0 else 0.0
        return (f"{p.done}/{p.total} files, {p.pieces} pieces{fails}; {p.rate:.2f} files/s, "
                f"{piece_rate:.1f} pieces/s, {_clock(p.elapsed)} elapsed, {_clock(p.eta)} left")

    def __call__(self, p: BatchProgress) -> None:
        end = p.done >= p.total
        if self.tty:
            frac = p.done / p.total if p.total else 1.0
            fill = int(round(frac * self.width))
            bar = "#" * fill + "-" * (self.width - fill)
            self.stream.write(f"\r\033[Kclothgrid: [{bar}] {self.text(p)}" + ("\n" if end else ""))
            self.stream.flush()
            return
        every = self.every if self.every is not None else max(1, min(100, p.total // 10 or 1))
        if end or (every > 0 and p.done - self._shown >= every):
            self._shown = p.done
            self.stream.write(f"clothgrid: {self.text(p)}\n")
            self.stream.flush()


# --------------------------------------------------------------------------- the run


@dataclass
class BatchSummary:
    """What a run did.

    Attributes
    ----------
    outdir : Path
    manifest : Path
    entries : list of dict
        The latest manifest line of every input of the run, in input order.
    summary : dict
        The summary line (:func:`clothgrid.batch_manifest.summarise`).
    done_now : list of dict
        The lines of the inputs gridded in this run.
    """

    outdir: Path
    manifest: Path
    entries: list[dict[str, Any]]
    summary: dict[str, Any]
    done_now: list[dict[str, Any]]

    @property
    def counts(self) -> dict[str, int]:
        return {k: self.summary[k] for k in ("ok", "partial", "failed", "skipped")}

    @property
    def failed(self) -> list[dict[str, Any]]:
        return [e for e in self.entries if e.get("status") == "failed"]

    @property
    def partial(self) -> list[dict[str, Any]]:
        return [e for e in self.entries if e.get("status") == "partial"]


def _normalised(options: GridOptions, output: OutputOptions, templates: Sequence[str], units: str | None,
                line: str | None, min_turn: float | None, garment: bool = False,
                seams: str = "keep", unfold: bool = False, grade: str | None = None) -> dict[str, Any]:
    """The options that change an input's outputs, as plain JSON values (``"2cm"`` and ``"20mm"`` alike)."""
    from .units import parse_length

    version = getattr(sys.modules.get(__package__ or "clothgrid"), "__version__", "unknown")

    grid = asdict(options)
    field = grid.pop("weight_field", None)       # a weight field's key only where one is given (resume)
    grid.pop("weight_field_range", None)         # the field itself is read already
    if field is not None:
        import hashlib

        import numpy as np

        grid["weight_field"] = {"shape": list(field.shape),
                                "sha256": hashlib.sha256(np.ascontiguousarray(field).tobytes()).hexdigest()}
    h = grid.get("edge_length")
    if isinstance(h, str):
        try:
            grid["edge_length"] = float(h)          # a plain number: the file's units (or mm)
        except ValueError:
            grid["edge_length"] = f"{parse_length(h, None, what='--edge-length'):.12g}mm"
    if grid.get("nodes") is not None:
        grid["nodes"] = list(grid["nodes"])
    grid["tol"] = float(grid["tol"])
    out = {"grid": grid, "output": asdict(output), "templates": list(templates), "units": units,
           "line": line or "sew", "min_turn": min_turn, "clothgrid": version}
    if garment:                                  # pieces-mode keys stay as they were (resume)
        out["garment"] = {"seams": seams}
    if unfold:                                   # likewise: only where asked
        out["unfold"] = True
    if grade is not None:
        out["grade"] = size_key(grade)
    return out


def _check_templates(templates: Sequence[str], garment: bool = False) -> tuple[str, ...]:
    out = []
    for t in templates:
        p = Path(t)
        if p.is_absolute() or ".." in p.parts:
            raise InputError(f"--template {t!r}: give a name inside the input's folder, e.g. {DEFAULT_TEMPLATE}")
        if garment:
            if Path(t).suffix.lower() not in GARMENT_FORMATS:
                raise InputError(f"--template {t!r}: a garment is written as "
                                 f"{', '.join(GARMENT_FORMATS)}")
        elif "{piece}" not in t:
            raise InputError(f"--template {t!r}: put {{piece}} in the name (a file holds several pieces)")
        if t not in out:
            out.append(t)
    if not garment:
        check_outputs([t.replace("{piece}", "x") for t in out], None)  # known formats, before any work
    return tuple(out)


def _client_for(scheduler: str | None, workers: int | None, retries: int, n_tasks: int,
                stack: contextlib.ExitStack) -> Any:
    try:
        import dask
        from distributed import Client, LocalCluster
    except ImportError as exc:
        raise MissingDependencyError("clothgrid batch needs Dask: pip install 'clothgrid[batch]' "
                                     f"(dask[distributed]); {exc}") from None
    if scheduler:
        try:
            return stack.enter_context(Client(scheduler, timeout="30s"))
        except (OSError, TimeoutError) as exc:
            raise InputError(f"--scheduler {scheduler!r}: cannot connect ({exc})") from None
    n = workers or max(1, min(default_workers(), n_tasks))
    stack.enter_context(dask.config.set({"distributed.scheduler.allowed-failures": retries,
                                         "distributed.worker.daemon": True}))
    cluster = stack.enter_context(LocalCluster(
        n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
        silence_logs=logging.ERROR, env={"NUMBA_NUM_THREADS": str(worker_threads(n)), "OMP_NUM_THREADS": "1"}))
    return stack.enter_context(Client(cluster))


def _register(client: Any, plugin: Any) -> None:
    register = getattr(client, "register_plugin", None)
    if register is not None:
        register(plugin, name=plugin.name)
    else:                           # distributed < 2023.9
        client.register_worker_plugin(plugin, name=plugin.name)


def _lost_entry(task: FileTask, exc: BaseException, seconds: float) -> dict[str, Any]:
    """The manifest line of a task the scheduler gave up on (it raised, or its workers died)."""
    name = type(exc).__name__
    message = str(exc) or name
    if name == "KilledWorker":
        message = "the worker gridding this file died (out of memory or killed), on every retry"
    return {"input": task.source, "stem": task.stem, "key": task.key, "sha256": task.sha256, "status": "failed",
            "error": message, "error_type": name, "retry": True, "pieces": [], "failed_pieces": [],
            "outputs": [], "timings": {"total": seconds}, "worker": None}


def _remove_old_outputs(outdir: Path, old: Mapping[str, Any] | None, new: Mapping[str, Any]) -> None:
    """Remove the outputs an earlier line of this input listed that the new line does not."""
    if not old:
        return
    keep = set(new.get("outputs", ()))
    root = outdir.resolve()
    for rel in old.get("outputs", ()):
        if rel in keep:
            continue
        p = (outdir / rel).resolve()
        if root in p.parents:
            p.unlink(missing_ok=True)


def batch(inputs: Sequence[str | Path], outdir: str | Path, *, options: GridOptions = GridOptions(),
          output: OutputOptions = OutputOptions(), templates: Sequence[str] = (DEFAULT_TEMPLATE,),
          units: str | None = None, line: str | None = None, min_turn: float | None = None,
          workers: int | None = None, scheduler: str | None = None, client: Any = None,
          retries: int = DEFAULT_RETRIES, redo_failed: bool = False, force: bool = False,
          progress: Callable[[BatchProgress], None] | None = None,
          on_entry: Callable[[dict[str, Any]], None] | None = None,
          garment: bool = False, seams: str = "keep", unfold: bool = False,
          grade: str | None = None) -> BatchSummary:
    """Grid every piece of every input file on Dask; write ``OUTDIR/<stem>/...`` and the manifest.

    Parameters
    ----------
    inputs : sequence of str or Path
        Files, folders (searched recursively for ``.json``, ``.svg``, ``.dxf``) and glob patterns.
    outdir : str or Path
        The output folder (created if missing); holds a folder per input and ``manifest.jsonl``.
    options : GridOptions
        How every grid is made (the options of ``clothgrid generate``).
    output : OutputOptions
        How the outputs are written (triangles, uv, density, cloth arrays).
    templates : sequence of str
        Output names inside ``OUTDIR/<stem>/``, each with ``{piece}``; the extension picks the format.
    units, line, min_turn, unfold, grade :
        Pattern-file options (as for ``clothgrid generate``; a file without the size ``grade`` fails
        with that reason).
    workers : int, optional
        Worker processes of the local cluster (default: the CPU cores, at most one per file to grid).
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``) instead of a local cluster.
    client : distributed.Client, optional
        An existing client to use instead (neither ``workers`` nor ``scheduler``).
    retries : int
        How often the scheduler retries a file whose task raised or whose worker died.
    redo_failed : bool
        Also redo inputs that failed because the file is bad (by default only those that
        failed for another reason are redone).
    force : bool
        Redo every input, done or not.
    progress : callable, optional
        Called with a :class:`BatchProgress` after each file (e.g. a :class:`ProgressLine`).
    on_entry : callable, optional
        Called with each manifest line as soon as it is written.
    garment : bool
        Make each input one sewn garment (:func:`clothgrid.garment.garment`: GarmentCode
        specifications) written as ``OUTDIR/<stem>/garment.npz`` (templates without
        ``{piece}``, or with it standing for ``garment``; ``.npz``, ``.obj``, USD); its
        panels are the manifest line's pieces. The grid options used: ``edge_length``,
        ``weights`` and ``functional``.
    seams : "keep" or "weld"
        The garment outputs' seams (as ``clothgrid garment --seams``).

    Returns
    -------
    BatchSummary

    Raises
    ------
    InputError
        No input found, an output folder that cannot be made, an unknown output format or
        bad options (before any work); a scheduler that cannot be reached.
    MissingDependencyError
        Dask is not installed (and there is work to do).
    """
    if retries < 0:
        raise InputError(f"--retries {retries!r} must be 0 or more")
    if workers is not None and workers < 1:
        raise InputError(f"--workers {workers!r} must be 1 or more")
    if sum(x is not None for x in (workers, scheduler, client)) > 1:
        raise InputError("give --workers or --scheduler, not both")
    if seams not in ("keep", "weld"):
        raise InputError(f"seams must be 'keep' or 'weld', not {seams!r}")
    if garment and tuple(templates) == (DEFAULT_TEMPLATE,):
        templates = (GARMENT_TEMPLATE,)
    templates = _check_templates(templates, garment)
    paths = find_inputs(inputs)
    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise InputError(f"output folder {str(outdir)!r} is not a folder")
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder {str(outdir)!r}: {exc.strerror or exc}") from None
    if not os.access(outdir, os.W_OK | os.X_OK):
        raise InputError(f"output folder {str(outdir)!r} is not writable")
    outdir = outdir.resolve()
    manifest = outdir / MANIFEST
    norm = _normalised(options, output, templates, units, line, min_turn, garment, seams, unfold, grade)
    previous = latest_entries(read_manifest(manifest))
    stems = assign_stems(paths)

    tasks: list[FileTask] = []
    skipped: list[dict[str, Any]] = []
    for path, stem in zip(paths, stems):
        try:
            digest = file_sha256(path)
        except OSError as exc:
            raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
        key = options_key(digest, norm)
        if not force and is_done(previous.get(stem), key, outdir, redo_failed):
            skipped.append(previous[stem])
            continue
        tasks.append(FileTask(str(path), stem, str(outdir), templates, options, output, units, line, min_turn,
                              key, digest, garment, seams, unfold, grade))

    state = BatchProgress(total=len(tasks), skipped=len(skipped))
    done_now: list[dict[str, Any]] = []
    t0 = time.perf_counter()
    n_workers: int | None = None
    startup = 0.0
    if tasks:
        with contextlib.ExitStack() as stack:
            if client is None:
                client = _client_for(scheduler, workers, retries, len(tasks), stack)
            _register(client, WarmUp(options))
            n_workers = len(client.scheduler_info().get("workers", {})) or None
            startup = time.perf_counter() - t0
            state.started = time.perf_counter()      # rate and time left: from here
            writer = stack.enter_context(ManifestWriter(manifest))
            for entry in _run(client, tasks, retries):
                _remove_old_outputs(outdir, previous.get(entry["stem"]), entry)
                entry["finished"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
                writer.append(entry)
                done_now.append(entry)
                state.done += 1
                state.pieces += len(entry["pieces"])
                state.failed_files += entry["status"] == "failed"
                state.failed_pieces += len(entry["failed_pieces"])
                state.last = entry
                if on_entry is not None:
                    on_entry(entry)
                if progress is not None:
                    progress(state)
    seconds = time.perf_counter() - t0
    now = {e["stem"]: e for e in done_now}
    by_stem = {e["stem"]: e for e in skipped} | now
    entries = [by_stem[s] for s in stems if s in by_stem]
    summary = summarise(entries, skipped=len(skipped), seconds=seconds - startup, startup=startup,
                        done_now=len(done_now), pieces_now=sum(len(e["pieces"]) for e in done_now),
                        workers=n_workers)
    if tasks or not manifest.exists() or previous:
        compact_manifest(manifest, summary, order=stems)
    return BatchSummary(outdir, manifest, entries, summary, done_now)


def _run(client: Any, tasks: Sequence[FileTask], retries: int) -> Iterator[dict[str, Any]]:
    """Submit the tasks (a window at a time, so that a huge run does not flood the scheduler)
    and yield each file's manifest line as it finishes."""
    from distributed import as_completed

    nthreads = sum(client.nthreads().values()) or 1
    window = max(64, 8 * nthreads)
    started: dict[str, float] = {}
    pending = iter(tasks)
    by_key: dict[str, FileTask] = {}

    def submit(task: FileTask) -> Any:
        key = f"clothgrid-{task.stem}-{task.key[:16]}"
        by_key[key] = task
        started[key] = time.perf_counter()
        return client.submit(grid_file, task, key=key, retries=retries, pure=False)

    first = [submit(t) for _, t in zip(range(window), pending)]
    ac = as_completed(first)
    for future in ac:
        task = by_key.pop(future.key)
        try:
            entry = future.result()
        except Exception as exc:   # noqa: BLE001 - the scheduler gave up on this file: record it
            entry = _lost_entry(task, exc, time.perf_counter() - started[future.key])
        future.release()
        nxt = next(pending, None)
        if nxt is not None:
            ac.add(submit(nxt))
        yield entry


class _CallableModule(types.ModuleType):
    """``clothgrid.batch(...)`` calls :func:`batch`: the module is callable, so the package's
    attribute ``batch`` (the module, once imported) and the function are one."""

    def __call__(self, *args: Any, **kwargs: Any) -> BatchSummary:
        return batch(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
