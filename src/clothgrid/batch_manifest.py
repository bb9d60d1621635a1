"""The manifest of a batch run (``OUTDIR/manifest.jsonl``): keys, lines, resume, summary.

One JSON object a line, one line per input file, appended by the client (the
one process that writes the manifest) only after every output of that file
exists; a rerun appends again for the files it redoes, and a run that finishes
rewrites the file (temporary name, then rename) with the latest line of each
input followed by one ``{"summary": {...}}`` line. A run killed while
appending leaves at most a torn last line, which :func:`read_manifest` skips
and :class:`ManifestWriter` cuts off before appending.

An input's line::

    {"input": "/abs/path/front.svg", "stem": "front", "key": "<sha256>", "sha256": "<of the file>",
     "status": "ok" | "partial" | "failed", "error": null | "message", "error_type": null | "InputError",
     "retry": false, "pieces": [{"name": ..., "outputs": ["front/A.npz"], "folded": 0, ...}],
     "failed_pieces": [{"name": ..., "reason": ..., "stage": ...}], "outputs": ["front/A.npz", ...],
     "timings": {"read": s, "grid": s, "write": s, "total": s}, "worker": ..., "finished": ...}

Output paths are relative to the output folder. ``key`` is the sha256 of the
file's content together with the normalised options (:func:`options_key`): a
rerun skips an input whose latest line has the same key, status ``ok`` or
``partial`` and all its outputs present, or status ``failed`` with ``retry``
false (the file itself is bad: the same bytes with the same options fail the
same way); it redoes the rest (changed files or options, files that failed for
another reason: a lost worker, a write error, an unexpected exception).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

__all__ = ["MANIFEST", "MANIFEST_FORMAT", "file_sha256", "options_key", "read_manifest", "latest_entries",
           "is_done", "ManifestWriter", "compact_manifest", "summarise", "finite"]

#: the manifest's file name inside the output folder
MANIFEST = "manifest.jsonl"
#: bumped when the meaning of a key changes (every input is then redone)
MANIFEST_FORMAT = 1


def file_sha256(path: str | Path, chunk: int = 1 << 20) -> str:
    """The sha256 of a file's content (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while True:
            block = fh.read(chunk)
            if not block:
                break
            h.update(block)
    return h.hexdigest()


def options_key(content_sha256: str, options: Mapping[str, Any]) -> str:
    """The resume key of one input: sha256 of its content hash and its normalised options.

    Parameters
    ----------
    content_sha256 : str
        :func:`file_sha256` of the input.
    options : mapping
        Every option that changes the outputs, already normalised (plain JSON values).

    Returns
    -------
    str
        Hex digest; equal for equal content and options, whatever order the options came in.
    """
    text = json.dumps({"format": MANIFEST_FORMAT, "content": content_sha256, "options": options},
                      sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def finite(value: Any) -> Any:
    """``value`` with every non-finite float made ``None`` (JSON has no inf or NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    return value


def _dumps(entry: Mapping[str, Any]) -> str:
    return json.dumps(finite(dict(entry)), allow_nan=False, default=_json_default, separators=(",", ":"))


def _json_default(value: Any) -> Any:
    try:                       # NumPy scalars
        return value.item()
    except AttributeError:
        return str(value)


def read_manifest(path: str | Path) -> list[dict[str, Any]]:
    """The input lines of a manifest in file order (summary lines and torn or unreadable lines left out)."""
    path = Path(path)
    if not path.exists():
        return []
    out = []
    with open(path, "rb") as fh:
        for raw in fh:
            try:
                entry = json.loads(raw)
            except ValueError:
                continue
            if isinstance(entry, dict) and "stem" in entry and "key" in entry:
                out.append(entry)
    return out


def latest_entries(entries: Iterable[Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
    """The last line of each output folder (``stem``), in order of first appearance."""
    latest: dict[str, dict[str, Any]] = {}
    for e in entries:
        latest[e["stem"]] = dict(e)
    return latest


def is_done(entry: Mapping[str, Any] | None, key: str, outdir: str | Path, redo_failed: bool = False) -> bool:
    """Whether an input whose latest manifest line is ``entry`` needs no work for ``key``.

    Done: same key, and status ``ok``/``partial`` with every output present, or status
    ``failed`` with ``retry`` false (the file itself is bad) unless ``redo_failed``.
    """
    if entry is None or entry.get("key") != key:
        return False
    status = entry.get("status")
    if status in ("ok", "partial"):
        return all((Path(outdir) / p).is_file() for p in entry.get("outputs", ()))
    if status == "failed":
        return not redo_failed and entry.get("retry") is False
    return False


class ManifestWriter:
    """Appends input lines to ``OUTDIR/manifest.jsonl``, each flushed and synced before the next.

    A torn last line left by a killed run is cut off first, so every line stays whole.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._cut_torn_tail()
        self._fh = open(self.path, "a", encoding="utf-8")

    def _cut_torn_tail(self) -> None:
        try:
            with open(self.path, "rb+") as fh:
                data = fh.read()
                if data and not data.endswith(b"\n"):
                    fh.truncate(data.rfind(b"\n") + 1)
        except FileNotFoundError:
            pass

    def append(self, entry: Mapping[str, Any]) -> None:
        """Append one line and make it durable (flush + fsync)."""
        self._fh.write(_dumps(entry) + "\n")
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self) -> None:
        self._fh.close()

    def __enter__(self) -> "ManifestWriter":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def compact_manifest(path: str | Path, summary: Mapping[str, Any] | None = None,
                     order: Sequence[str] = ()) -> list[dict[str, Any]]:
    """Rewrite the manifest atomically: the latest line of each input (the stems in ``order``
    first, in that order, then the others as they were), then the summary line.

    Returns the input lines kept.
    """
    path = Path(path)
    latest = latest_entries(read_manifest(path))
    first = [latest.pop(s) for s in order if s in latest]
    kept = first + list(latest.values())
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            for e in kept:
                fh.write(_dumps(e) + "\n")
            if summary is not None:
                fh.write(_dumps({"summary": summary}) + "\n")
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return kept


def _badness(piece: Mapping[str, Any]) -> tuple:
    """Sort key of a piece, worst first: folded cells, then targets missed, then the smallest angle."""
    angle = piece.get("min_angle_deg")
    return (-(piece.get("folded") or 0), -len(piece.get("missed") or ()),
            angle if isinstance(angle, (int, float)) else math.inf)


def summarise(entries: Sequence[Mapping[str, Any]], *, skipped: int = 0, seconds: float = 0.0,
              startup: float = 0.0, done_now: int = 0, pieces_now: int = 0, workers: int | None = None,
              top: int = 5) -> dict[str, Any]:
    """The summary of a run over the latest line of each of its inputs.

    Parameters
    ----------
    entries : sequence of dict
        One manifest line per input of the run (done now or before).
    skipped : int
        Inputs found done by an earlier run (no work).
    seconds, startup, done_now, pieces_now, workers :
        Wall time of this run's gridding (from the cluster being ready to the last file), the time
        before (starting or reaching the cluster, warming up the workers), files and pieces
        gridded in this run, workers used.
    top : int
        How many worst pieces and slowest files to list.
    """
    counts = {"ok": 0, "partial": 0, "failed": 0}
    for e in entries:
        counts[e.get("status", "failed")] = counts.get(e.get("status", "failed"), 0) + 1
    pieces = [(e, p) for e in entries for p in e.get("pieces", ())]
    worst = sorted(pieces, key=lambda ep: _badness(ep[1]))[:top]
    slow = sorted((e for e in entries if e.get("timings")), key=lambda e: -(e["timings"].get("total") or 0))[:top]
    return {
        "inputs": len(entries), **counts, "skipped": skipped,
        "pieces": len(pieces), "pieces_failed": sum(len(e.get("failed_pieces", ())) for e in entries),
        "done_now": done_now, "pieces_now": pieces_now, "seconds": seconds, "startup_seconds": startup,
        "workers": workers,
        "files_per_s": done_now / seconds if seconds > 0 else None,
        "pieces_per_s": pieces_now / seconds if seconds > 0 else None,
        "worst_pieces": [{"input": e.get("input"), "stem": e.get("stem"), "name": p.get("name"),
                          "folded": p.get("folded"), "min_angle_deg": p.get("min_angle_deg"),
                          "edge_spread": p.get("edge_spread"), "missed": p.get("missed")} for e, p in worst],
        "slowest_files": [{"input": e.get("input"), "stem": e.get("stem"), "seconds": e["timings"].get("total"),
                           "pieces": len(e.get("pieces", ()))} for e in slow],
        "failed_inputs": [{"input": e.get("input"), "error": e.get("error")}   # the first 100
                          for e in entries if e.get("status") == "failed"][:100],
    }
