"""The command line for pattern files: ``clothgrid pieces`` and ``clothgrid generate PATTERN``.

:func:`add_generate_arguments` adds the pattern options to ``generate``,
:func:`add_pieces_parser` the ``pieces`` subcommand; ``cli._cmd_generate``
hands pattern inputs to :func:`generate_pattern`.

Output names: with one piece (a one-piece file or one ``--piece``) every
``-o`` / ``--plot`` path is used as given; with several, ``out.obj`` becomes
``out_<piece>.obj`` per piece, or ``{piece}`` in the path is replaced by the
piece's name (``-o meshes/{piece}.obj``). Names are made file-safe (characters
other than letters, digits, ``.``, ``_`` and ``-`` become ``_``). Every grid is
generated and checked before anything is written, and a failed write removes
what the run wrote, so a failure leaves no output.
"""

from __future__ import annotations

import argparse
import inspect
import re
import sys
import time
from pathlib import Path
from typing import Any, Sequence

from ..errors import InputError

__all__ = ["add_generate_arguments", "add_pieces_parser", "generate_pattern", "grid_nodes",
           "is_pattern_input", "output_names", "safe_name"]

_PATTERN_ONLY = ("piece", "corners", "corners_near", "min_turn")


def add_generate_arguments(g: argparse.ArgumentParser) -> None:
    """Add the pattern-file options (and ``--edge-length``) to the ``generate`` parser."""
    p = g.add_argument_group("pattern files (.svg, .dxf, GarmentCode .json)")
    p.add_argument("--edge-length", metavar="LEN",
                   help="grid size from a target edge length along the sides, e.g. 5mm, 0.5cm, "
                        "0.25in (a plain number: mm for pattern files, the file's units for a "
                        "boundary JSON); instead of --nodes (pattern default: 10mm)")
    p.add_argument("--piece", action="append", metavar="NAME",
                   help="grid only this piece (repeatable; default: every piece)")
    p.add_argument("--corners", metavar="I,J,K,L",
                   help="the grid corners as outline indices (bottom-left, bottom-right, "
                        "top-right, top-left, counter-clockwise), see 'clothgrid pieces "
                        "--candidates'; one piece only")
    p.add_argument("--corners-near", metavar="X,Y;X,Y;X,Y;X,Y",
                   help="the grid corners as the outline points nearest to four points in mm "
                        "(same order as --corners); one piece only")
    p.add_argument("--min-turn", type=float, default=None, metavar="DEG",
                   help="smallest turn (degrees) that makes a vertex a corner candidate "
                        "(default: 20)")
    # --units (the generate parser's own option) overrides the units a pattern file states


def add_pieces_parser(sub: Any) -> None:
    """Add ``clothgrid pieces FILE``: list the pieces, their size and corner candidates."""
    p = sub.add_parser("pieces", help="list the pieces of a pattern file and their corners",
                       description="List the pieces of a pattern file (.svg, .dxf, GarmentCode "
                                   ".json) with their size, units and the automatic corner "
                                   "choice.")
    p.add_argument("input", metavar="FILE", help="pattern file")
    p.add_argument("--piece", action="append", metavar="NAME", help="only this piece (repeatable)")
    p.add_argument("--candidates", action="store_true",
                   help="also list every corner candidate: outline index, point (mm), turn")
    p.add_argument("--units", metavar="UNIT",
                   help="read the coordinates in this unit instead of what the file says")
    p.add_argument("--min-turn", type=float, default=None, metavar="DEG",
                   help="smallest turn (degrees) for a corner candidate (default: 20)")
    p.add_argument("--json", action="store_true", help="print the listing as JSON")
    p.set_defaults(func=run_pieces)


def is_pattern_input(path: str | Path) -> bool:
    """Is ``path`` a pattern file (SVG, DXF, GarmentCode JSON)?"""
    from . import is_pattern_file

    return is_pattern_file(path)


def safe_name(name: str) -> str:
    """``name`` with every character other than letters, digits, ``.``, ``_``, ``-`` made ``_``."""
    out = re.sub(r"[^A-Za-z0-9._-]", "_", name).strip(".")
    return out or "piece"


def output_names(paths: Sequence[str], names: Sequence[str]) -> list[list[str]]:
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
            if "{piece}" in text:
                mine.append(text.replace("{piece}", s))
            elif len(names) == 1:
                mine.append(text)
            else:
                p = Path(text)
                mine.append(str(p.with_name(f"{p.stem}_{s}{p.suffix}")))
        out.append(mine)
    return out


def _parse_indices(text: str) -> list[int]:
    parts = [x for x in re.split(r"[,\s]+", text.strip()) if x]
    try:
        vals = [int(x) for x in parts]
    except ValueError:
        vals = []
    if len(vals) != 4:
        raise InputError(f"--corners {text!r}: expected 4 outline indices I,J,K,L "
                         "(bottom-left, bottom-right, top-right, top-left)")
    return vals


def _parse_points(text: str) -> list[tuple[float, float]]:
    pts = []
    for part in [x for x in re.split(r"\s*;\s*", text.strip()) if x]:
        xy = [x for x in re.split(r"[,\s]+", part) if x]
        try:
            pts.append((float(xy[0]), float(xy[1])) if len(xy) == 2 else None)
        except ValueError:
            pts.append(None)
    if len(pts) != 4 or any(p is None for p in pts):
        raise InputError(f"--corners-near {text!r}: expected four points X,Y;X,Y;X,Y;X,Y in mm")
    return pts


def _select(pieces: list[Any], wanted: Sequence[str] | None, source: Path) -> list[Any]:
    if not wanted:
        return pieces
    by_name = {p.name: p for p in pieces}
    missing = [w for w in wanted if w not in by_name]
    if missing:
        names = ", ".join(repr(p.name) for p in pieces)
        raise InputError(f"{source}: no piece named {', '.join(repr(m) for m in missing)}; "
                         f"the pieces are {names}")
    out = []
    for w in wanted:
        if by_name[w] not in out:
            out.append(by_name[w])
    return out


def grid_nodes(args: argparse.Namespace, boundary: Any, *, pattern: bool
               ) -> tuple[Any, float | None]:
    """The node counts for ``generate`` (``--nodes``, or from ``--edge-length``) and the edge length.

    For a pattern piece (mm) a plain ``--edge-length`` number is in mm and the
    default is 10 mm; for a boundary JSON it must be a plain number in the
    file's units, and without it the boundary's own point counts are used.
    """
    from . import DEFAULT_EDGE_LENGTH_MM, nodes_for_edge_length
    from .units import parse_length

    text = getattr(args, "edge_length", None)
    if text is not None and args.nodes is not None:
        raise InputError("give --nodes or --edge-length, not both")
    if text is None:
        if args.nodes is None and pattern:
            return nodes_for_edge_length(boundary, DEFAULT_EDGE_LENGTH_MM), DEFAULT_EDGE_LENGTH_MM
        return args.nodes, None
    if pattern:
        h = parse_length(text, "mm", what="--edge-length")
    else:
        try:
            h = float(text)
        except ValueError:
            raise InputError(f"--edge-length {text!r}: a boundary JSON file has no units, so give "
                             "the edge length as a plain number in the file's units") from None
        if not 0 < h < float("inf"):
            raise InputError(f"--edge-length {text!r} must be positive and finite")
    return nodes_for_edge_length(boundary, h), h


def check_boundary_args(args: argparse.Namespace) -> None:
    """Reject pattern-only options for a boundary JSON input."""
    used = [f"--{k.replace('_', '-')}" for k in _PATTERN_ONLY if getattr(args, k, None)]
    if used:
        raise InputError(f"{', '.join(used)} {'is' if len(used) == 1 else 'are'} for pattern "
                         f"files (.svg, .dxf, GarmentCode .json), not for the boundary file "
                         f"{args.input}")


def _read(args: argparse.Namespace) -> tuple[Path, list[Any]]:
    from . import read_pieces

    source = Path(args.input)
    pieces = read_pieces(source, units=getattr(args, "units", None))
    return source, _select(pieces, getattr(args, "piece", None), source)


def _choice(piece: Any, args: argparse.Namespace, single: bool) -> Any:
    from .corners import MIN_TURN_DEG, choose_corners

    corners = getattr(args, "corners", None)
    near = getattr(args, "corners_near", None)
    if (corners or near) and not single:
        raise InputError("--corners and --corners-near need a single piece: pick one with "
                         "--piece NAME")
    min_turn = getattr(args, "min_turn", None)
    if min_turn is not None and not (0 <= min_turn < 180):
        raise InputError(f"--min-turn {min_turn!r} must be between 0 and 180 degrees")
    return choose_corners(piece, _parse_indices(corners) if corners else None,
                          _parse_points(near) if near else None,
                          min_turn=MIN_TURN_DEG if min_turn is None else min_turn)


def generate_pattern(args: argparse.Namespace) -> int:
    """``clothgrid generate PATTERN -o OUT ...``: grid every (selected) piece."""
    import numpy as np

    from .. import cli
    from ..generate import generate
    from ..quality import Quality, quality
    from . import piece_boundary, piece_info

    progress = None if args.quiet else cli._say
    t0 = time.perf_counter()
    source, pieces = _read(args)
    if progress:
        progress(f"read {len(pieces)} piece{'s' if len(pieces) != 1 else ''} from {source} in "
                 f"{time.perf_counter() - t0:.3f} s")
    single = len(pieces) == 1
    outs = output_names(args.output, [p.name for p in pieces])
    plots = output_names([args.plot], [p.name for p in pieces]) if args.plot else None
    checked = []
    all_paths: list[Path] = []
    for k in range(len(pieces)):
        paths, plot = cli._check_outputs(outs[k], plots[k][0] if plots else None)
        for p in paths + ([plot] if plot else []):
            if p in all_paths:
                raise InputError(f"two pieces would write the same file {str(p)!r}: put {{piece}} "
                                 "in the output name")
            all_paths.append(p)
        checked.append((paths, plot))

    results = []
    folded_any = []
    for piece, (paths, plot) in zip(pieces, checked):
        choice = _choice(piece, args, single)
        boundary = piece_boundary(piece, choice=choice)
        nodes, h = grid_nodes(args, boundary, pattern=True)
        t0 = time.perf_counter()
        grid = generate(boundary, nodes, init=args.init, weights=args.weights, k=args.k,
                        solver=args.solver, backend=args.backend, tol=args.tol, stop=args.stop,
                        max_iter=args.max_iter, allow_unconverged=args.allow_unconverged,
                        progress=progress, functional=args.functional)
        t_solve = time.perf_counter() - t0
        grid.info["piece"] = piece_info(piece, choice, h)
        q = quality(grid)
        w, hh = piece.extent
        nu, nv = grid.shape
        print(f"piece {piece.name}: {w:.6g} x {hh:.6g} mm, {nu} x {nv} nodes; corners: "
              f"{choice.message}")
        if grid.info.get("functional") == "foldfree":
            before = grid.info.get("quality_before") or {}
            print("length functional:")
            print(Quality(**{**before, "folded_cells": np.asarray(
                before.get("folded_cells", []), dtype=np.int64).reshape(-1, 2)}).table())
            ff = grid.info.get("foldfree", {})
            print(f"fold-free ({cli._fmt(ff.get('iterations'), 'd')} iterations, "
                  f"{cli._fmt(ff.get('seconds'), '.3f')} s):")
        print(q.table())
        print(cli.timing_line(grid.info, t_solve), flush=True)
        if q.folded:
            folded_any.append((piece.name, q))
        if not grid.info.get("converged", True):
            cli._say(f"warning: piece {piece.name}: writing a grid that is not converged (error "
                     f"estimate {cli._fmt(grid.info.get('error_estimate'), '.2e')} > tol "
                     f"{cli._fmt(args.tol, '.2e')}) because of --allow-unconverged")
        results.append((piece, grid, q, paths, plot))

    if folded_any and args.strict:
        name, q = folded_any[0]
        cli._say(f"error: piece {name}: the grid has {cli.folded_text(q)}; no output written "
                 + ("(try --functional auto)" if args.functional == "length" else "(--strict)"))
        return 3
    for name, q in folded_any:
        hint = "; try --functional auto" if args.functional == "length" else ""
        cli._say(f"warning: piece {name}: {cli.folded_text(q)}{hint}")

    t0 = time.perf_counter()
    options = {"triangles": getattr(args, "triangles", None), "uv": getattr(args, "uv", None),
               "density": getattr(args, "density", None),
               "cloth": getattr(args, "cloth", False) or None}
    takes_options = "options" in inspect.signature(cli._write_all).parameters
    written: list[Path] = []
    try:
        for piece, grid, q, paths, plot in results:
            grid.info["length_unit"] = "mm"      # pieces are read in millimetres
            written += cli._write_all(grid, paths, plot, title=piece.name, quality=q,
                                      **({"options": options} if takes_options else {}))
    except BaseException:
        for p in written:
            p.unlink(missing_ok=True)
        raise
    if progress:
        progress(f"wrote {', '.join(map(str, written))} in {time.perf_counter() - t0:.3f} s")
    return 0


def _listing(pieces: list[Any], args: argparse.Namespace) -> list[dict[str, Any]]:
    from .corners import corner_candidates, MIN_TURN_DEG

    min_turn = MIN_TURN_DEG if args.min_turn is None else args.min_turn
    out = []
    for piece in pieces:
        choice = _choice(piece, args, True)
        w, h = piece.extent
        entry = {
            "name": piece.name, "source": piece.source, "file_units": piece.units,
            "size_mm": [w, h], "perimeter_mm": piece.perimeter, "area_mm2": piece.area,
            "outline_points": len(piece.outline), "turn_points": len(piece.turn_points),
            "sampling_tolerance_mm": piece.tolerance,
            "grain_line": None if piece.grain_line is None else piece.grain_line.tolist(),
            "corners": choice.as_dict(), "notes": list(piece.notes),
        }
        if args.candidates or args.json:
            entry["candidates"] = [c.as_dict() for c in corner_candidates(piece, min_turn)]
        out.append(entry)
    return out


def run_pieces(args: argparse.Namespace) -> int:
    """``clothgrid pieces FILE``: print the pieces with size, units and corners."""
    import json

    source, pieces = _read(args)
    listing = _listing(pieces, args)
    if args.json:
        print(json.dumps({"file": str(source), "pieces": listing}, indent=2))
        return 0
    print(f"{source}: {len(pieces)} piece{'s' if len(pieces) != 1 else ''} (coordinates in mm)")
    for e in listing:
        w, h = e["size_mm"]
        print(f"{e['name']}: {w:.6g} x {h:.6g} mm, perimeter {e['perimeter_mm']:.6g} mm, "
              f"{e['outline_points']} outline points, {e['turn_points']} turn points "
              f"[{e['source']}, file units {e['file_units']}]")
        c = e["corners"]
        pts = "; ".join(f"{x:.6g},{y:.6g}" for x, y in c["points"])
        print(f"  corners {','.join(map(str, c['indices']))} ({pts} mm): {c['message']}")
        if e["grain_line"] is not None:
            (x0, y0), (x1, y1) = e["grain_line"]
            print(f"  grain line: {x0:.6g},{y0:.6g} -> {x1:.6g},{y1:.6g} mm")
        for note in e["notes"]:
            print(f"  note: {note}")
        if args.candidates:
            cands = e["candidates"]
            print(f"  {len(cands)} corner candidate{'s' if len(cands) != 1 else ''} "
                  "(index: x, y mm, turn degrees, + convex):")
            for cand in cands:
                x, y = cand["point"]
                tp = ", turn point" if cand["turn_point"] else ""
                print(f"    {cand['index']}: {x:.6g}, {y:.6g}, turn {cand['turn']:+.1f}{tp}")
    sys.stdout.flush()
    return 0
