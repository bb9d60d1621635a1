"""Command-line interface: ``clothgrid generate``, ``demo``, ``pieces``, ``garment``, ``heat``.

Exit codes: 0 success, 2 bad input or options (including usage errors),
3 an iterative solve did not converge within ``--max-iter`` or, with
``--strict``, the grid has folded cells, 4 (:data:`EXIT_PARTIAL`) some pieces
of a pattern file failed and the others were written (``generate``) or listed
(``pieces``), 130 interrupted (SIGINT), 143 SIGTERM, 129 SIGHUP.
Any output file of a failed run is removed, so a failure leaves no output.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import math
import os
import re
import sys
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, NoReturn

from .backends import BACKENDS
from .errors import ClothgridError, InputError, NotConvergedError, PiecesError
from .limits import MAX_K, MAX_NESTING, MIN_K
from .solvers import SOLVERS

__all__ = ["main", "parse_nodes", "parse_tol", "EXIT_PARTIAL"]

#: exit code: some pieces of a pattern file failed (each named on stderr), the others were written
EXIT_PARTIAL = 4
#: ``clothgrid batch``: error lines shown on stderr at most (the manifest has them all)
BATCH_ERRORS_SHOWN = 50

DEMO_PIECE = "tshirt_front.json"
_NUM = r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"
_POWER = re.compile(rf"\s*({_NUM})\s*(?:\*\*|\^)\s*({_NUM})\s*")
_NODES = re.compile(r"\s*(\d+)\s*(?:[xX]\s*(\d+)\s*)?")


# --------------------------------------------------------------------------- parsing


def parse_nodes(text: str) -> tuple[int, int]:
    """Parse ``NUxNV`` or ``N`` (meaning ``N x N``) into ``(nu, nv)`` for argparse.

    Raises
    ------
    argparse.ArgumentTypeError
        If the text is not of that form or a count is below 2.
    """
    from .generate import parse_nodes as parse

    if _NODES.fullmatch(text) is None:
        raise argparse.ArgumentTypeError(
            f"invalid node counts {text!r}: expected NUxNV or N (integers >= 2), e.g. 257x257")
    try:
        return parse(text.strip())
    except InputError as exc:
        raise argparse.ArgumentTypeError(f"invalid node counts {text!r}: {exc}") from None


def parse_tol(text: str) -> float:
    """Parse a positive tolerance: a float (``1e-4``) or a power (``2**-12``, ``2^-12``).

    No ``eval``: only a number or ``number ** number`` / ``number ^ number``.

    Raises
    ------
    argparse.ArgumentTypeError
        If the text is not of that form or the value is not positive and finite.
    """
    value: float | None = None
    try:
        value = float(text)
    except ValueError:
        m = _POWER.fullmatch(text)
        if m is not None:
            try:
                value = float(m.group(1)) ** float(m.group(2))
            except (OverflowError, ZeroDivisionError):
                value = None
    if value is None or isinstance(value, complex) or not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(
            f"invalid tolerance {text!r}: expected a positive number such as 1e-4 or 2**-12")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"invalid value {text!r}: expected a positive number")
    return value


def _k_factor(text: str) -> float:
    value = _positive_float(text)
    if not MIN_K <= value <= MAX_K:
        raise argparse.ArgumentTypeError(f"invalid value {text!r}: k must be between {MIN_K:g} and "
                                         f"{MAX_K:g} (beyond, the squared weights overflow)")
    return value


def parse_density(text: str) -> float:
    """Parse an areal density with a unit (``0.2kg/m2``, ``150gsm``) into kg/m^2 for argparse.

    Raises
    ------
    argparse.ArgumentTypeError
        Text without a unit, an unknown unit, or a density that is not positive.
    """
    from .cloth import parse_density as parse

    try:
        float(text)
    except ValueError:
        pass
    else:
        raise argparse.ArgumentTypeError(
            f"invalid density {text!r}: give a unit, e.g. 0.2kg/m2, 150g/m2 or 150gsm")
    try:
        return parse(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _length_unit(text: str) -> str:
    from .cloth import length_scale

    try:
        length_scale(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text.strip().lower()


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"invalid value {text!r}: expected an integer >= 1")
    return value


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors read ``clothgrid: error: ...`` (exit 2)."""

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(2, f"clothgrid: error: {message}\n")


def _version() -> str:
    try:
        from importlib.metadata import PackageNotFoundError, version

        return version("clothgrid")
    except (ImportError, PackageNotFoundError):  # running from a source tree
        return str(getattr(sys.modules.get(__package__ or "clothgrid"), "__version__", "unknown"))


class _VersionAction(argparse.Action):
    """``--version``, looked up only when asked for (``importlib.metadata`` costs 15-25 ms to import,
    on every command if the parser looked it up when built)."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS,
                 default: Any = argparse.SUPPRESS, help: str = "show program's version number and exit") -> None:
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        sys.stdout.write(f"clothgrid {_version()}\n")
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    """The ``clothgrid`` argument parser with its ``generate`` and ``demo`` subcommands."""
    parser = _Parser(
        prog="clothgrid",
        description="Structured quad grids inside four boundary curves, for mass-spring cloth.")
    parser.add_argument("--version", action=_VersionAction)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    g = sub.add_parser("generate", help="generate a grid from a boundary file",
                       description="Generate a grid inside the four boundary curves of INPUT.")
    g.add_argument("input", metavar="INPUT",
                   help="boundary JSON file, or a pattern file (.svg, .dxf, GarmentCode .json)")
    g.add_argument("-o", "--output", action="append", required=True, metavar="OUT",
                   help="output file, format by extension (.npz .obj .ply .json .vts); repeatable")
    _add_grid_arguments(g)
    g.add_argument("--report", metavar="FILE.json",
                   help="write a quality report: per piece folded cells, smallest and largest angle, "
                        "edge spread, shortest edge against the edge length asked, targets missed")
    g.add_argument("--strict", action="store_true",
                   help="fail (exit 3, no output) if the final grid has folded cells")
    g.add_argument("--plot", metavar="PNG", help="also draw the grid to this PNG file")
    g.add_argument("-q", "--quiet", action="store_true", help="no progress messages on stderr")
    g.add_argument("-v", "--verbose", action="store_true",
                   help="timing lines on stderr: where the time goes (start-up and imports, read, solve, "
                        "fold-free, quality, write)")
    _add_pattern_arguments(g)  # --edge-length and the pattern-file options
    g.set_defaults(func=_cmd_generate)

    d = sub.add_parser("demo", help="grid a bundled T-shirt front and write OBJ, NPZ and PNG",
                       description="Grid the bundled T-shirt front panel and write the results.")
    d.add_argument("-o", "--output-dir", default="clothgrid-demo", metavar="DIR",
                   help="output folder, created if missing (default: clothgrid-demo)")
    d.add_argument("--nodes", type=parse_nodes, default=(257, 257), metavar="NUxNV",
                   help="grid size (default: 257x257)")
    d.add_argument("--weights", choices=("paper", "uniform"), default="uniform",
                   help="edge weights (default: uniform: the paper's weights fold cells under "
                        "the neckline of this piece)")
    d.set_defaults(func=_cmd_demo)
    _add_pieces_parser(sub)  # clothgrid pieces FILE
    _add_garment_parser(sub)  # clothgrid garment SPEC
    _add_heat_parser(sub)    # clothgrid heat
    _add_batch_parser(sub)   # clothgrid batch INPUTS... -o OUTDIR
    return parser


def _size(text: str) -> tuple[float, float]:
    from .heat import _parse_size

    try:
        return _parse_size(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _range(text: str) -> tuple[float, float]:
    parts = [x for x in re.split(r"[,:\s]+", text.strip()) if x]
    try:
        lo, hi = (float(x) for x in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid range {text!r}: expected LO,HI (black, white)") from None
    return lo, hi


def _add_heat_parser(sub: Any) -> None:
    """Add ``clothgrid heat``: temperature in a non-uniform medium (docs/heat.md)."""
    h = sub.add_parser(
        "heat", help="temperature in a non-uniform medium (steady or transient heat conduction)",
        description="Heat conduction on a rectangle of cells, SI units: -div(k grad T) = q (steady) or "
                    "rho c dT/dt = div(k grad T) + q (with --dt and --steps). Finite volumes with the "
                    "harmonic mean of the cells' conductivity on each face, solved by conjugate gradients "
                    "preconditioned with a black-box multigrid V-cycle, on the cpu, an OpenGL device (gl) or "
                    "a CUDA GPU (cuda). A field is a number, a .npy array of shape "
                    "(nx, ny) (index [i, j], i along x), or a grayscale image mapped to a range (top row: "
                    "top side). Sides not named are insulated. See docs/heat.md.")
    h.add_argument("--conductivity", required=True, metavar="K",
                   help="conductivity per cell, W/(m K): a number, a .npy file or an image")
    h.add_argument("--conductivity-range", type=_range, metavar="LO,HI",
                   help="an image's conductivity at black and white")
    h.add_argument("--size", type=_size, metavar="WxH",
                   help="width (x) and height (y) of the rectangle in metres, e.g. 0.01x0.004 (or --grid)")
    h.add_argument("--grid", metavar="GRID.npz",
                   help="instead of --size: the cells of a gridded piece, a .npz of clothgrid generate (left / "
                        "right: its i = 0 / last side, bottom / top: j = 0 / last; docs/heat.md)")
    h.add_argument("--grid-unit", type=_length_unit, metavar="UNIT",
                   help="the grid's length unit (default: the .npz's length_unit, else mm)")
    h.add_argument("--cells", type=parse_nodes, metavar="NXxNY",
                   help="cells along x and y (needed when every field is a number)")
    for side in ("left", "right", "bottom", "top"):
        h.add_argument(f"--{side}", metavar="SIDE",
                       help=f"{side} side: a temperature in C (34 or T=34), a flux into the medium in W/m2 "
                            "(q=150), convection (h=10,T=20: W/(m2 K) and ambient C) or insulated "
                            "(default)" if side == "left" else f"{side} side (as --left; default insulated)")
    h.add_argument("--source", default="0", metavar="Q",
                   help="heat source per cell, W/m3: number, .npy or image (default 0)")
    h.add_argument("--source-range", type=_range, metavar="LO,HI", help="an image's source at black and white")
    h.add_argument("--capacity", metavar="RHOC",
                   help="volumetric heat capacity rho c per cell, J/(m3 K) (transient): number, .npy or image")
    h.add_argument("--capacity-range", type=_range, metavar="LO,HI", help="an image's rho c at black and white")
    h.add_argument("--dt", type=_positive_float, metavar="S", help="time step in seconds (transient)")
    h.add_argument("--steps", type=_positive_int, metavar="N", help="number of time steps (transient)")
    h.add_argument("--scheme", choices=("crank-nicolson", "backward-euler"), default="crank-nicolson",
                   help="time stepping (default: crank-nicolson)")
    h.add_argument("--initial", default="20", metavar="T0",
                   help="initial temperature in C, number or .npy (transient; default 20)")
    h.add_argument("--save-every", type=_positive_int, metavar="N",
                   help="keep every N-th step's field in the .npz (history, times)")
    h.add_argument("--tol", type=parse_tol, default=1e-8, metavar="T",
                   help="relative residual ||b - A T|| / ||b|| to reach (default 1e-8; per step)")
    h.add_argument("--max-iter", type=_positive_int, default=500, metavar="N",
                   help="most conjugate-gradient iterations per solve (default 500)")
    h.add_argument("--error-bound", action="store_true",
                   help="steady: also compute a guaranteed bound on the temperature error (three more solves; "
                        "within a few per cent of the true error above float64's rounding, docs/heat.md)")
    h.add_argument("--backend", choices=BACKENDS, default="cpu",
                   help="where the V-cycle and CG run: cpu (Numba, float64; auto is the cpu), gl (OpenGL "
                        "shaders through headless EGL, float32, refined until the float64 residual on the host "
                        "meets --tol) or cuda (numba.cuda kernels on CuPy arrays, float64); exit 2 with the "
                        "reason where the device is missing (docs/heat.md)")
    h.add_argument("--threads", type=_positive_int, metavar="N",
                   help="Numba threads for the solve (default: all cores; 1 can be faster on a busy machine)")
    h.add_argument("-o", "--output", action="append", required=True, metavar="OUT",
                   help="output file by extension: .npz (temperature, x, y, conductivity, info), .vts "
                        "(ParaView) or .png (field and isotherms); repeatable")
    h.add_argument("-q", "--quiet", action="store_true", help="no progress messages on stderr")
    h.set_defaults(func=_cmd_heat)


def _cmd_heat(args: argparse.Namespace) -> int:
    """``clothgrid heat``: solve, print one summary line, write the outputs (all or none)."""
    import os

    # Numba's OpenMP threads sleep between kernels instead of spinning: on a machine shared with other jobs
    # spinning made each parallel kernel of the heat multigrid cost ~15 ms (a 256^2 solve 3.6 s instead of
    # 0.1 s); read by libgomp when Numba first runs a parallel kernel, so set before any (docs/heat.md)
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    from . import heat, pipeline

    outs = [Path(o) for o in args.output]
    for o in outs:   # before any work: a bad name or folder fails at once
        if o.suffix.lower() not in heat.HEAT_OUTPUTS:
            raise InputError(f"unknown heat output format {o.suffix or o.name!r}: use "
                             f"{', '.join(heat.HEAT_OUTPUTS)}")
    pipeline.check_output_folders(outs)   # missing folders are made when writing
    if (args.dt is None) != (args.steps is None):
        raise InputError("a transient run needs both --dt and --steps")
    problem = heat.HeatProblem(
        conductivity=heat.load_field(args.conductivity, name="conductivity", value_range=args.conductivity_range,
                                     shape=args.cells),
        size=args.size, grid=args.grid, grid_unit=args.grid_unit,
        left=args.left, right=args.right, bottom=args.bottom, top=args.top,
        source=heat.load_field(args.source, name="source", value_range=args.source_range, positive=False,
                               shape=args.cells),
        capacity=None if args.capacity is None else heat.load_field(
            args.capacity, name="heat capacity", value_range=args.capacity_range, shape=args.cells),
        cells=args.cells)
    progress = _progress(args.quiet)
    if args.dt is None:
        res = heat.solve_steady(problem, backend=args.backend, tol=args.tol, max_iter=args.max_iter,
                                error_bound=args.error_bound, progress=progress, threads=args.threads)
    else:
        res = heat.solve_transient(problem, dt=args.dt, steps=args.steps, initial=args.initial,
                                   scheme=args.scheme, save_every=args.save_every, backend=args.backend,
                                   tol=args.tol, max_iter=args.max_iter, progress=progress, threads=args.threads)
    info, T = res.info, res.temperature
    flows = res.heat_flows()
    bound = f", error bound {info['error_bound']:.2e} K" if "error_bound" in info else ""
    where = "" if info["backend"] == "cpu" else (
        f" on {info['backend']}" + (f" (float32, {info['refinements']} float64 refinements)" if "refinements" in info
                                    else ""))
    print(f"heat: {T.shape[0]} x {T.shape[1]} cells, T {T.min():.6g} to {T.max():.6g} C; "
          f"{info['iterations']} CG iterations{where}, relative residual {info['residual']:.2e} "
          f"(tol {info['tol']:.1e}){bound}, {info['seconds']:.3f} s")
    print("heat in (W per metre depth): " + ", ".join(f"{k} {v:.6g}" for k, v in flows.items())
          + f"; sum {sum(flows.values()):.3g}")
    written = _write_all(outs, res.save)
    if progress:
        progress(f"wrote {', '.join(map(str, written))}")
    return 0


def _add_garment_parser(sub: Any) -> None:
    """Add ``clothgrid garment SPEC``: every panel gridded, sewn node for node and placed."""
    p = sub.add_parser("garment", help="grid, sew and place every panel of a GarmentCode specification",
                       description="Grid every panel of a GarmentCode (or Garment-Pattern-Generator) "
                                   "specification so that both edges of every stitch get the same "
                                   "nodes, place the panels in 3D and write the sewn garment "
                                   "(docs/garment.md).")
    p.add_argument("input", metavar="SPEC", help="GarmentCode *_specification.json, or an .svg / .dxf pattern "
                                                "with --stitches")
    p.add_argument("-o", "--output", action="append", required=True, metavar="OUT",
                   help="output file, .npz, .obj or USD (.usda, .usd: needs usd-core, the extra "
                        "clothgrid[usd]); repeatable")
    p.add_argument("--edge-length", default="10mm", metavar="LEN",
                   help="target grid edge length, e.g. 1cm, 5mm (a plain number: mm; default 10mm)")
    p.add_argument("--seams", choices=("keep", "weld"), default="keep",
                   help="keep: every panel's own nodes, seams as node pairs (stitches) and zero-length "
                        "seam springs; weld: also the welded mesh (stitched nodes merged) and the map "
                        "from grid nodes to welded vertices (default: keep)")
    p.add_argument("--density", type=parse_density, metavar="D",
                   help="areal density, e.g. 150gsm or 0.2kg/m2: adds node masses (kg) to .npz outputs")
    p.add_argument("--units", type=_length_unit, metavar="UNIT",
                   help="the spec's length unit instead of its units_in_meter (an SVG / DXF pattern: its "
                        "coordinates' unit instead of what the file says)")
    p.add_argument("--stitches", metavar="FILE",
                   help="the seams of an SVG or DXF pattern: a JSON file of piece outline ranges sewn "
                        "together (docs/garment.md, examples/fs_cathrin_stitches.json); an SVG that lists "
                        "its seams in its <metadata> needs none")
    p.add_argument("--corners", action="append", metavar="PANEL=I,J,K,L",
                   help="grid corners of a panel as its vertex indices (bottom-left, bottom-right, "
                        "top-right, top-left); repeatable; the way out of a node-count conflict")
    p.add_argument("--fix", action="append", type=_fixed_count, metavar="PANEL:EDGE=N",
                   help="fix the node intervals of a spec edge (panel name, edge index in the spec) to N; "
                        "repeatable; the other way to loosen or steer the node counts")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages on stderr")
    p.add_argument("--weight-field", metavar="FIELD",
                   help="grade every panel's grid by a field over its (u, v) square, as generate's "
                        "--weight-field (the seams' nodes stay where the node counts put them)")
    p.add_argument("--weight-field-range", type=_range, metavar="LO,HI",
                   help="an image weight field's values at black and white")
    p.set_defaults(func=_cmd_garment)


def _fixed_count(text: str) -> tuple[tuple[str, int], int]:
    """``PANEL:EDGE=N`` -> ``((PANEL, EDGE), N)`` (the panel name may hold colons: the last one splits)."""
    left, sep, n = text.rpartition("=")
    name, sep2, edge = left.rpartition(":")
    try:
        e, k = int(edge), int(n)
    except ValueError:
        e = k = -1
    if not sep or not sep2 or not name or e < 0 or k < 1:
        raise argparse.ArgumentTypeError(f"--fix {text!r}: expected PANEL:EDGE=N (a panel name, a spec edge "
                                         "index >= 0, a number of intervals >= 1)")
    return (name, e), k


def _write_all(outs: list[Path], write: Callable[[Path], Path]) -> list[Path]:
    """Write every output with ``write`` (each atomic), making missing folders first: all or none.
    On a failure the outputs written and the folders made are removed; an OSError (a full disk, a
    folder taken away) is one ``cannot write`` line (InputError), as ``generate``'s."""
    from . import pipeline

    written: list[Path] = []
    made = pipeline.make_folders(outs)
    try:
        for o in outs:
            try:
                written.append(write(o))
            except OSError as exc:
                raise InputError(f"cannot write {str(o)!r}: {exc.strerror or exc}") from exc
    except BaseException:
        for w in written:
            w.unlink(missing_ok=True)
        pipeline.remove_folders(made)
        raise
    return written


def _cmd_garment(args: argparse.Namespace) -> int:
    from . import pipeline
    from .garment import garment, write_garment

    outs = [Path(o) for o in args.output]
    for o in outs:
        if o.suffix.lower() not in (".npz", ".obj", ".usda", ".usd", ".usdc"):
            raise InputError(f"unknown garment output format {o.suffix or '(no extension)'!r} for "
                             f"{str(o)!r}: use .npz, .obj, .usda or .usd")
        if o.suffix.lower() in (".usda", ".usd", ".usdc"):
            from .garment_usd import _pxr

            _pxr()                      # usd-core missing: say so before gridding
    pipeline.check_output_folders(outs)   # missing folders are made when writing, like generate's
    extra: dict[str, Any] = {}
    if args.weight_field is not None:     # read (and refused) before any work
        extra["weights"] = pipeline.GridOptions(weight_field=args.weight_field,
                                                weight_field_range=args.weight_field_range).edge_weights()
    t0 = time.perf_counter()
    with _first_compile_said(_progress(args.quiet)):
        g = garment(args.input, edge_length=args.edge_length, units=args.units, corners=args.corners,
                    fixed=dict(args.fix) if args.fix else None, stitches=args.stitches,
                    progress=_progress(args.quiet), **extra)
    written = _write_all(outs, lambda o: write_garment(g, o, seams=args.seams, density=args.density))
    for line in g.info["warnings"]:
        _say(f"warning: {line}")
    s = g.info["seconds"]
    print(f"{args.input}: {len(g.panel_names)} panels, {len(g.spec.stitches)} stitches, "
          f"{len(g.points)} nodes, {len(g.quads)} quads, {len(g.stitches)} stitched node pairs")
    for p in g.info["panels"]:
        print(f"  {p['name']}: {p['nodes'][0]} x {p['nodes'][1]} nodes, corners {p['corners']} "
              f"({p['corner_vertices']}), {p['folded']} folded, min angle {_fmt(p['min_angle_deg'], '.1f')} deg")
    if args.seams == "weld":
        r = g.mesh_report(welded=True)
        print(f"welded: {int(g.weld_map().max()) + 1} vertices, {len(r['boundary_loops'])} boundary loops "
              f"(openings), manifold: {r['nonmanifold_edges'] == 0 and r['nonmanifold_vertices'] == 0}")
    print(f"time: corners {s['corners']:.3f} s, node counts (MILP) {s['milp']:.3f} s, gridding "
          f"{s['gridding']:.3f} s, total {time.perf_counter() - t0:.3f} s")
    print(f"wrote {', '.join(str(w) for w in written)}")
    return 0


def _add_grid_arguments(p: argparse.ArgumentParser) -> None:
    """The gridding and output options that ``generate`` and ``batch`` share (one parser for both)."""
    p.add_argument("--nodes", type=parse_nodes, metavar="NUxNV",
                   help="grid size, NUxNV or N (default: the input's point counts)")
    p.add_argument("--init", choices=("zero", "average", "tfi"), default="tfi",
                   help="initial grid (default: tfi)")
    p.add_argument("--weights", choices=("paper", "uniform"), default="uniform",
                   help="edge weights: uniform, or the paper's eq. 2 (default: uniform; on real "
                        "patterns the paper's weights spread edge lengths more and fold more cells: "
                        "docs/patterns.md)")
    p.add_argument("--k", type=_k_factor, default=1.0, metavar="K",
                   help=f"the factor k of the v weights in eq. 2, {MIN_K:g} to {MAX_K:g} (default: 1)")
    p.add_argument("--weight-field", metavar="FIELD",
                   help="grade the grid: a positive field over each piece's (u, v) square that multiplies "
                        "--weights edge by edge, finer where it is larger (an edge shortens about as one "
                        "over its square root): a .npy array (mu, mv), index [i, j] with i along the "
                        "bottom side, or a grayscale image (its top row along the top side) with "
                        "--weight-field-range; any resolution, sampled bilinearly. With it --functional "
                        "auto evens only the edges further out than the field explains (README: Command line)")
    p.add_argument("--weight-field-range", type=_range, metavar="LO,HI",
                   help="an image weight field's values at black and white, e.g. 1,10")
    p.add_argument("--solver", choices=("auto", *SOLVERS), default="auto",
                   help="solver (default: auto)")
    p.add_argument("--backend", choices=BACKENDS, default="auto",
                   help="where the solver runs: cpu; gl (OpenGL through headless EGL: the GPU's "
                        "driver, or Mesa's llvmpipe without one; solvers multigrid and jacobi); or cuda "
                        "(an NVIDIA GPU through CuPy, pip install 'clothgrid[cuda]'; solvers multigrid "
                        "and fdm) (default: auto, cuda where it finds a GPU and the grid has at least 2^19 "
                        "nodes, else the CPU)")
    p.add_argument("--tol", type=parse_tol, default=2.0**-12, metavar="T",
                   help="tolerance relative to the bounding-box diagonal, e.g. 1e-4 or 2**-12 "
                        "(default: 2**-12)")
    p.add_argument("--stop", choices=("error", "paper"), default="error",
                   help="stop rule of the iterative solvers (jacobi, multigrid): the true error bound, "
                        "or the paper's last-step rule (default: error)")
    p.add_argument("--max-iter", type=_positive_int, default=None, metavar="N",
                   help="most iterations of an iterative solver (Jacobi sweeps or multigrid V-cycles)")
    p.add_argument("--allow-unconverged", action="store_true",
                   help="write the grid even if --max-iter is reached before --tol")
    p.add_argument("--functional", choices=("length", "foldfree", "auto"), default="auto",
                   help="length: the weighted length functional alone (the paper's; may fold cells on "
                        "non-convex pieces); auto: then relax the folded and poorly shaped cells and the "
                        "nodes near them (planar pieces); foldfree: relax every interior node "
                        "(default: auto)")
    p.add_argument("--cloth", action="store_true",
                   help="add the simulation arrays to .npz outputs: pattern coordinates, triangles, "
                        "springs with rest lengths, node areas (and masses with --density)")
    p.add_argument("--density", type=parse_density, metavar="D",
                   help="areal density with a unit, e.g. 0.2kg/m2, 150g/m2 or 150gsm: adds node "
                        "masses (kg) to .npz (implies --cloth) and .vts outputs")
    p.add_argument("--units", type=_length_unit, metavar="UNIT",
                   help="length unit of the input's coordinates: m, cm, mm, in, ft, yd, ... (default: "
                        "the unit a pattern file states; m for a boundary JSON); used for --density "
                        "masses and recorded in the outputs")
    p.add_argument("--triangles", choices=("fixed", "alternate"),
                   help="write triangle faces to .obj and .ply (quads are split along one diagonal, "
                        "or alternating ones); also the diagonal of the --cloth .npz triangles")
    p.add_argument("--uv", choices=("normalised", "pattern"),
                   help="texture coordinates of .obj and .ply: normalised arc length in [0, 1] "
                        "(default) or the flat pattern coordinates in length units")


def _add_pattern_arguments(g: argparse.ArgumentParser, one_file: bool = True) -> None:
    """Add the pattern-file options (and ``--edge-length``) to the ``generate`` parser; with
    ``one_file`` false (``batch``) only those that mean the same for every file (``--edge-length``,
    ``--line``, ``--min-turn``), not the piece names and corners of one file."""
    p = g.add_argument_group("pattern files (.svg, .dxf, GarmentCode .json)")
    p.add_argument("--edge-length", metavar="LEN",
                   help="grid size from a target edge length along the sides, e.g. 5mm, 0.5cm, "
                        "0.25in (a plain number: mm for pattern files, the file's units for a "
                        "boundary JSON); instead of --nodes (pattern default: 10mm)")
    p.add_argument("--min-turn", type=float, default=None, metavar="DEG",
                   help="smallest turn (degrees) that makes a vertex a corner candidate "
                        "(default: 20)")
    if not one_file:
        _add_line_argument(p)
        _add_unfold_argument(p, "grid")
        _add_grade_argument(p, "grid")
        return
    p.add_argument("--piece", action="append", metavar="NAME",
                   help="grid only this piece (repeatable; default: every piece); may name an "
                        "outline skipped as an annotation")
    _add_grade_argument(p, "grid")
    _add_unfold_argument(p, "grid")
    _add_annotation_arguments(p, "grid")
    p.add_argument("--corners", type=_corner_indices, metavar="I,J,K,L",
                   help="the grid corners as outline indices (bottom-left, bottom-right, "
                        "top-right, top-left, counter-clockwise), see 'clothgrid pieces "
                        "--candidates'; one piece only")
    p.add_argument("--corners-near", type=_corner_points, metavar="X,Y;X,Y;X,Y;X,Y",
                   help="the grid corners as the outline points nearest to four points in mm "
                        "(same order as --corners); one piece only")
    # --units (the generate parser's own option) overrides the units a pattern file states


def _add_grade_argument(p: Any, verb: str) -> None:
    """``--grade SIZE`` (generate, batch and pieces)."""
    p.add_argument("--grade", metavar="SIZE",
                   help=f"of a graded pattern (several sizes in one file: AAMA/ASTM blocks, a flat DXF's "
                        f"layers), {verb} only the pieces of this size (their 'Size:' text, e.g. 42, M, "
                        "Small; case aside)")


def _add_unfold_argument(p: Any, verb: str) -> None:
    """``--unfold`` (generate, batch and pieces)."""
    p.add_argument("--unfold", action="store_true",
                   help=f"{verb} each piece cut on the fold whole: the half the file draws and its mirror "
                        "image across the fold line it marks (AAMA/ASTM DXF layer 6, FreeSewing's 'cut on "
                        "fold' mark)")


def _add_annotation_arguments(p: Any, verb: str) -> None:
    """``--include NAME`` and ``--line sew|cut`` (generate and pieces)."""
    p.add_argument("--include", action="append", metavar="NAME",
                   help=f"also {verb} this closed outline, which was skipped as an annotation (text, "
                        "arrow, notch, drill hole, mark on a piece, seam-allowance outline; "
                        "'clothgrid pieces FILE' lists them with their names and reasons); repeatable")
    _add_line_argument(p)


def _add_line_argument(p: Any) -> None:
    """``--line sew|cut`` (generate, batch and pieces)."""
    p.add_argument("--line", choices=("sew", "cut"), default=None,
                   help="of a piece drawn with both a sew line and a cut (seam-allowance) line "
                        "(AAMA/ASTM DXF layer 14 and 1; an SVG outline inside another of nearly "
                        "the same shape), which to grid: sew (default), or cut; a piece with only "
                        "one is gridded along it (noted)")


def _add_pieces_parser(sub: Any) -> None:
    """Add ``clothgrid pieces FILE``: list the pieces, their size and corner candidates."""
    p = sub.add_parser("pieces", help="list the pieces of a pattern file and their corners",
                       description="List the pieces of a pattern file (.svg, .dxf, GarmentCode "
                                   ".json) with their size, units, the line used (sew or "
                                   "cut) and the automatic corner choice; then the closed "
                                   "outlines skipped as annotations, each with its reason "
                                   "(grid one with --include NAME).")
    p.add_argument("input", metavar="FILE", help="pattern file")
    p.add_argument("--piece", action="append", metavar="NAME",
                   help="only this piece (repeatable); may name an outline skipped as an annotation")
    _add_grade_argument(p, "list")
    _add_unfold_argument(p, "list")
    _add_annotation_arguments(p, "list")
    p.add_argument("--candidates", action="store_true",
                   help="also list every corner candidate: outline index, point (mm), turn")
    p.add_argument("--units", metavar="UNIT",
                   help="read the coordinates in this unit instead of what the file says")
    p.add_argument("--min-turn", type=float, default=None, metavar="DEG",
                   help="smallest turn (degrees) for a corner candidate (default: 20)")
    p.add_argument("--json", action="store_true", help="print the listing as JSON")
    p.set_defaults(func=_cmd_pieces)


def _add_batch_parser(sub: Any) -> None:
    """Add ``clothgrid batch INPUTS... -o OUTDIR``: every piece of many files, on Dask."""
    b = sub.add_parser("batch", help="grid every piece of many pattern files (Dask), with a manifest and resume",
                       description="Grid every piece of every input file with the options of 'generate', "
                                   "on a local Dask cluster or an existing one, into OUTDIR/<stem>/ "
                                   "(one folder per input, named after its file stem) with "
                                   "OUTDIR/manifest.jsonl (one line per input: status, errors, timings, "
                                   "quality per piece, outputs). A rerun skips the inputs already done "
                                   "with the same content and options. Exit code 4 when some files or "
                                   "pieces failed (each named on stderr and in the manifest).")
    b.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="pattern or boundary files, folders (searched recursively for .json, .svg, "
                        ".dxf) or glob patterns such as 'data/**/*_specification.json'")
    b.add_argument("-o", "--output-dir", required=True, metavar="OUTDIR",
                   help="output folder, created if missing")
    b.add_argument("-t", "--template", action="append", metavar="NAME",
                   help="output name inside OUTDIR/<stem>/ with {piece}, format by extension "
                        "(.npz .obj .ply .json .vts); repeatable (default: {piece}.npz)")
    _add_grid_arguments(b)
    _add_pattern_arguments(b, one_file=False)
    gm = b.add_argument_group("garments")
    gm.add_argument("--garment", action="store_true",
                    help="make each input (a GarmentCode specification) one sewn garment, as "
                         "'clothgrid garment' does, written to OUTDIR/<stem>/garment.npz (templates: "
                         ".npz .obj .usda, {piece} optional); its panels are the manifest's pieces")
    gm.add_argument("--seams", choices=("keep", "weld"), default="keep",
                    help="with --garment: seams as node pairs (keep) or welded (default: keep)")
    c = b.add_argument_group("cluster")
    where = c.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_positive_int, metavar="N",
                       help="worker processes of the local Dask cluster (default: the CPU cores, at most "
                            "a container's CPU limit and one per file; the cores left are shared "
                            "out as each worker's threads)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="use the Dask scheduler at ADDRESS (e.g. tcp://10.0.0.5:8786) instead of a "
                            "local cluster; its workers need clothgrid installed and the same paths")
    c.add_argument("--retries", type=int, default=2, metavar="N",
                   help="how often a file is retried when its task fails or its worker dies (default: 2)")
    c.add_argument("--redo-failed", action="store_true",
                   help="also redo the files that failed because they are bad (by default a rerun "
                        "redoes only changed files and those that failed for another reason)")
    c.add_argument("--force", action="store_true", help="redo every file, done or not")
    c.add_argument("--log-every", type=int, default=None, metavar="N",
                   help="when stderr is not a terminal, a progress line every N files (0: none; "
                        "default: every tenth of the run, at most every 100 files)")
    b.add_argument("-q", "--quiet", action="store_true",
                   help="no progress on stderr (errors and the summary still shown)")
    b.set_defaults(func=_cmd_batch)


def _corner_indices(text: str) -> list[int]:
    parts = [x for x in re.split(r"[,\s]+", text.strip()) if x]
    try:
        vals = [int(x) for x in parts]
    except ValueError:
        vals = []
    if len(vals) != 4:
        raise argparse.ArgumentTypeError(f"--corners {text!r}: expected 4 outline indices I,J,K,L "
                                         "(bottom-left, bottom-right, top-right, top-left)")
    return vals


def _corner_points(text: str) -> list[tuple[float, float]]:
    pts: list = []
    for part in [x for x in re.split(r"\s*;\s*", text.strip()) if x]:
        xy = [x for x in re.split(r"[,\s]+", part) if x]
        try:
            pts.append((float(xy[0]), float(xy[1])) if len(xy) == 2 else None)
        except ValueError:
            pts.append(None)
    if len(pts) != 4 or any(p is None for p in pts):
        raise argparse.ArgumentTypeError(f"--corners-near {text!r}: expected four points X,Y;X,Y;X,Y;X,Y in mm")
    return pts


# --------------------------------------------------------------------------- helpers


def _say(message: str) -> None:
    """One ``clothgrid: ...`` line on stderr; an error's line breaks (a library's exception text
    quoting a bad line of the input) become spaces, so that an error is one line."""
    if message.startswith("error:"):
        message = " ".join(message.splitlines())
    print(f"clothgrid: {message}", file=sys.stderr, flush=True)


def _fmt(value: Any, spec: str) -> str:
    try:
        return format(value, spec)
    except (TypeError, ValueError):
        return "n/a"


def timing_line(info: dict[str, Any], seconds: float) -> str:
    """One line: solver, backend, iterations, relative error estimate, tolerance, time."""
    return (f"solver {info.get('solver', '?')} ({info.get('backend', '?')}): "
            f"{info.get('iterations', 0)} iterations, "
            f"error estimate {_fmt(info.get('error_estimate'), '.2e')} relative "
            f"(tol {_fmt(info.get('tol'), '.2e')}), {seconds:.3f} s"
            + ("; the error estimate is the length solve's: the fold-free grid then moved away from it"
               if info.get("functional") == "foldfree" else ""))


def _progress(quiet: bool) -> Callable[[str], None] | None:
    return None if quiet else _say


#: What the compile listener says to (the running command's progress, None between commands) and
#: whether it is in place (one listener a process)
_COMPILE_NOTE: dict[str, Any] = {"say": None, "listening": False}


@contextlib.contextmanager
def _first_compile_said(progress: Callable[[str], None] | None) -> Iterator[None]:
    """While the block runs, say once, when Numba first compiles a kernel (its disk cache holds none:
    the installation's first run, or the first after an update), that the kernels compile now: a
    first ``clothgrid demo`` spends about half a minute on it, later runs load them in a fraction of
    a second. Numba is not imported for this (a run that needs no kernel does not load it): one
    listener a process is put in place once it is (:func:`clothgrid.lean_imports.after_import`).
    Nothing with ``-q``."""
    if progress is None:
        yield
        return
    _COMPILE_NOTE["say"] = progress
    if not _COMPILE_NOTE["listening"]:
        from .lean_imports import after_import

        _COMPILE_NOTE["listening"] = after_import("numba", _listen_for_compiles)
    try:
        yield
    finally:
        _COMPILE_NOTE["say"] = None


def _listen_for_compiles(_numba: Any) -> None:
    """Register the listener of Numba's compile events that :func:`_first_compile_said` speaks through."""
    from numba.core import event

    class FirstCompile(event.Listener):
        def on_start(self, ev: Any) -> None:
            say, _COMPILE_NOTE["say"] = _COMPILE_NOTE["say"], None
            if say is not None:
                say("compiling numerical kernels into Numba's cache: this installation's first run, "
                    "or the first after an update (about half a minute, once)")

        def on_end(self, ev: Any) -> None:
            pass

    event.register("numba:compile", FirstCompile())


def folded_text(q: Any, max_listed: int = 5) -> str:
    """``"N folded cells (i, j), ..."``: how many cells are folded and the first few."""
    shown = ", ".join(f"({i}, {j})" for i, j in list(q.folded_cells)[:max_listed])
    more = ", ..." if q.folded > max_listed else ""
    return f"{q.folded} folded cell{'s' if q.folded != 1 else ''} (first at cells {shown}{more})"


# --------------------------------------------------------------------------- commands


def _report(result: Any, pattern: bool) -> None:
    """Print one grid's lines: the piece and its corners, the quality table(s), the timing line."""
    import numpy as np

    from .quality import Quality

    job, grid = result.job, result.grid
    if pattern:
        nu, nv = grid.shape
        w, h = job.piece["size"]
        print(f"piece {job.name}: {w:.6g} x {h:.6g} mm, {nu} x {nv} nodes; corners: {job.corners}")
    if grid.info.get("functional") == "foldfree":
        before = grid.info.get("quality_before") or {}
        print("length functional:")
        print(Quality(**{**before, "folded_cells": np.asarray(before.get("folded_cells", []),
                                                                dtype=np.int64).reshape(-1, 2)}).table())
        ff = grid.info.get("foldfree", {})
        print(f"fold-free ({_fmt(ff.get('moved'), 'd')} nodes moved, {_fmt(ff.get('sweeps'), 'd')} sweeps, "
              f"{_fmt(ff.get('seconds'), '.3f')} s):")
    print(result.quality.table())
    q = grid.info.get("quality") or {}
    if q:
        vs = q.get("shortest_vs_target")
        print(f"angles {_fmt(q.get('min_angle_deg'), '.3g')} to {_fmt(q.get('max_angle_deg'), '.4g')} deg "
              f"(corner cells aside), edge spread {_fmt(q.get('edge_spread'), '.3g')}"
              + (f", shortest edge {_fmt(vs, '.2f')} of the edge length asked" if vs is not None else "")
              + (f"; misses: {'; '.join(q['missed'])}" if q.get("missed") else "; targets met"))
    print(timing_line(grid.info, result.seconds), flush=True)


def _grid_options(args: argparse.Namespace) -> Any:
    """The :class:`~clothgrid.pipeline.GridOptions` of ``generate`` and ``batch`` (checked once)."""
    from . import pipeline

    return pipeline.GridOptions(
        nodes=args.nodes, edge_length=args.edge_length, init=args.init, weights=args.weights, k=args.k,
        solver=args.solver, backend=args.backend, tol=args.tol, stop=args.stop, max_iter=args.max_iter,
        allow_unconverged=args.allow_unconverged, functional=args.functional,
        weight_field=args.weight_field, weight_field_range=args.weight_field_range)


def _output_options(args: argparse.Namespace) -> Any:
    """The :class:`~clothgrid.pipeline.OutputOptions` of ``generate`` and ``batch``."""
    from . import pipeline

    return pipeline.OutputOptions(triangles=args.triangles, uv=args.uv, density=args.density, cloth=args.cloth)


def process_seconds() -> float | None:
    """Seconds since this process started (Linux: /proc; None elsewhere), interpreter start-up included."""
    try:
        with open("/proc/self/stat") as fh:
            start = int(fh.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as fh:
            up = float(fh.read().split()[0])
        return max(0.0, up - start / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError, AttributeError):
        return None


def timing_lines(startup: float | None, imports: float, read: float, results: Sequence[Any], write: float,
                 total: float | None) -> list[str]:
    """``-v``: one line a stage, in seconds (``solve`` is the solver alone, ``generate`` all of it)."""
    lines = [f"time: start-up (interpreter and imports before the command) "
             f"{_fmt(startup, '.3f')} s, imports for generate {imports:.3f} s",
             f"time: read {read:.3f} s"]
    for r in results:
        info = r.grid.info
        ff = info.get("foldfree") or info.get("relax") or {}
        name = f"piece {r.job.name}: " if len(results) > 1 else ""
        # multigrid's set-up holds the hierarchy, its arrays and, in a fresh process, Numba's
        # start-up (importing it and its first cached kernels: about 0.4 s of a 1024^2 command)
        setup = (f" of which set-up {info['setup_seconds']:.3f} s" if isinstance(info.get("setup_seconds"), float)
                 else "")
        if isinstance(info.get("cuda_upload_seconds"), float):   # a GPU's share: the grid over the bus
            setup += (f" (upload {info['cuda_upload_seconds']:.3f} s), download "
                      f"{info['cuda_merge_seconds'] + info['cuda_download_seconds']:.3f} s")
        lines.append(f"time: {name}generate {r.seconds:.3f} s (solve {_fmt(info.get('solve_seconds'), '.3f')} s"
                     f"{setup}, fold-free {_fmt(ff.get('seconds', 0.0), '.3f')} s), quality {r.quality_seconds:.3f} s")
    lines.append(f"time: write {write:.3f} s")
    lines.append(f"time: whole command {_fmt(total, '.3f')} s")
    return lines


def _cmd_generate(args: argparse.Namespace) -> int:
    startup = process_seconds() if args.verbose else None
    t_imp = time.perf_counter()
    from . import pipeline

    t_read = time.perf_counter()
    imports = t_read - t_imp
    options = _grid_options(args)
    progress = _progress(args.quiet)
    jobs = pipeline.read_jobs(args.input, args.output, args.plot, options=options, pieces=args.piece,
                              corners=args.corners, corners_near=args.corners_near, min_turn=args.min_turn,
                              units=args.units, progress=progress, line=args.line,
                              include=args.include, grade=args.grade, unfold=args.unfold)
    for line in jobs.warnings:
        _say(f"warning: {line}")
    pattern = jobs[0].piece is not None
    many = len(jobs) > 1 or pattern

    def done(result: Any) -> None:
        _resume_collector()     # one piece made: Numba and its kernels are loaded
        _report(result, pattern)
        job = result.job
        if not result.grid.info.get("converged", True):
            _say(f"warning: {f'piece {job.name}: ' if many else ''}writing a grid that is not converged "
                 f"(error estimate {_fmt(result.grid.info.get('error_estimate'), '.2e')} > tol "
                 f"{_fmt(args.tol, '.2e')}) because of --allow-unconverged")

    read = time.perf_counter() - t_read
    with _first_compile_said(progress):
        results, failed = pipeline.run_jobs(jobs, progress, done)
    folded = [r for r in results if r.quality.folded]
    hint = "try --functional auto" if args.functional == "length" else ""
    if folded and args.strict:
        _say_failed(args.input, failed)
        r = folded[0]
        _say(f"error: {f'piece {r.job.name}: ' if many else ''}the grid has {folded_text(r.quality)}; "
             f"no output written ({hint or '--strict'})")
        return 3
    for r in folded:
        _say(f"warning: {f'piece {r.job.name}: ' if many else ''}{folded_text(r.quality)}"
             + (f"; {hint}" if hint else ""))
    t0 = time.perf_counter()
    report = None
    if args.report:   # first: a report that cannot be written leaves no grid behind
        report = pipeline.write_report(args.report, args.input, results, failed)
    out = _output_options(args)
    try:
        written = pipeline.write_results(results, out)
    except BaseException:
        if report is not None:
            report.unlink(missing_ok=True)
        raise
    if progress:
        progress(f"wrote {', '.join(map(str, written))} in {time.perf_counter() - t0:.3f} s")
    if args.verbose:
        from ._startup import thread_summary

        for line in timing_lines(startup, imports, read, results, time.perf_counter() - t0, process_seconds()):
            _say(line)
        _say(thread_summary())
    if failed:
        _say_failed(args.input, failed)
        n = len(results) + len(failed)
        _say(f"{len(failed)} of {n} pieces failed (above); the other {len(results)} "
             f"{'were' if len(results) != 1 else 'was'} written (exit code {EXIT_PARTIAL})")
        return EXIT_PARTIAL
    return 0


def _say_failed(source: Any, failed: Sequence[Any]) -> None:
    """One ``clothgrid: error: FILE: piece 'NAME': reason`` line per failed piece."""
    for f in failed:
        _say(f"error: {f.message(source)}")


def _cmd_pieces(args: argparse.Namespace) -> int:
    """``clothgrid pieces FILE``: print the pieces with size, units and corners."""
    import json

    from . import pipeline

    source = Path(args.input)
    pieces = pipeline.select_pieces(source, args.piece, units=args.units, line=args.line or "sew",
                                    include=args.include, grade=args.grade, unfold=args.unfold)
    failed = list(pieces.failed)
    listing = pipeline.piece_listing(pieces, min_turn=args.min_turn, candidates=args.candidates or args.json,
                                     failed=failed)
    doubt = pipeline.units_warning(pieces, args.units)
    if doubt:
        _say(f"warning: {doubt}")
    if not listing:
        raise pipeline.no_piece_left(source, failed, "listed")
    skipped = pipeline.skipped_listing(pieces)
    code = EXIT_PARTIAL if failed else 0
    stitches = getattr(pieces, "stitches", None)       # seams the file lists itself (svg metadata)
    if args.json:
        print(json.dumps({"file": str(source), "pieces": listing,
                          "failed": [f.as_dict() for f in failed], "skipped": skipped,
                          "stitches": stitches}, indent=2))
        sys.stdout.flush()
        _say_failed(source, failed)
        return code
    bad = f", {len(failed)} failed" if failed else ""
    print(f"{source}: {len(listing)} piece{'s' if len(listing) != 1 else ''}{bad} (coordinates in mm)"
          + (f", {len(skipped)} closed outline{'s' if len(skipped) != 1 else ''} skipped as "
             "annotations" if skipped else ""))
    if stitches:
        print(f"the file lists {len(stitches['seams'])} seams in its <metadata>: 'clothgrid garment "
              f"{source}' sews them (no --stitches needed)"
              + (f"; drawn face down: {', '.join(stitches['turned'])}" if stitches.get("turned") else ""))
    for e in listing:
        w, h = e["size_mm"]
        line = f", {e['line']} line" if e.get("line") in ("sew", "cut") else ""
        print(f"{e['name']}: {w:.6g} x {h:.6g} mm, perimeter {e['perimeter_mm']:.6g} mm, "
              f"{e['outline_points']} outline points, {e['turn_points']} turn points "
              f"[{e['source']}, file units {e['file_units']}{line}]")
        c = e["corners"]
        pts = "; ".join(f"{x:.6g},{y:.6g}" for x, y in c["points"])
        print(f"  corners {','.join(map(str, c['indices']))} ({pts} mm): {c['message']}")
        if c.get("alternatives"):       # tried where the grid is poor; any can be given with --corners
            print("  runners-up: " + "; ".join(",".join(map(str, a)) for a in c["alternatives"]))
        if e["aliases"]:
            print(f"  also answers to {', '.join(map(repr, e['aliases']))} (the name earlier releases gave it)")
        if e["grain_line"] is not None:
            (x0, y0), (x1, y1) = e["grain_line"]
            print(f"  grain line: {x0:.6g},{y0:.6g} -> {x1:.6g},{y1:.6g} mm")
        if e["cut"]:
            print(f"  cut {pipeline.cut_text(e['cut'])}")
        if e["fold_line"] is not None and not e["unfolded"]:
            (x0, y0), (x1, y1) = e["fold_line"]
            print(f"  cut on the fold: {x0:.6g},{y0:.6g} -> {x1:.6g},{y1:.6g} mm (this is half the piece; "
                  "--unfold for the whole)")
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
    for f in failed:
        print(f"{f.name}: FAILED ({'cannot be read' if f.stage == 'read' else 'no corners'}): {f.reason}")
    if skipped:
        print("skipped (not gridded; grid one with --include NAME):")
        _print_skipped(skipped)
    sys.stdout.flush()
    _say_failed(source, failed)
    return code


#: ``clothgrid pieces`` lists this many skipped outlines of one reason by name, and counts the rest
#: (a FreeSewing logo is 100-odd glyph outlines; ``--json`` lists every one)
LISTED_PER_REASON = 3


def _print_skipped(skipped: list[dict]) -> None:
    """The skipped outlines, one line each, except that a reason shared by more than
    :data:`LISTED_PER_REASON` of them names that many and counts the others in one line."""
    by_reason: dict[str, list[dict]] = {}
    for e in skipped:
        by_reason.setdefault(e["reason"], []).append(e)
    listed: dict[str, int] = {}
    for e in skipped:
        same = by_reason[e["reason"]]
        k = listed[e["reason"]] = listed.get(e["reason"], -1) + 1      # e's place among them
        if k < LISTED_PER_REASON or len(same) == LISTED_PER_REASON + 1:
            size = (f" ({e['size_mm'][0]:.3g} x {e['size_mm'][1]:.3g} mm)" if "size_mm" in e else "")
            print(f"  {e['name']}: {e['reason']}{size}")
        elif k == LISTED_PER_REASON:
            rest = same[k:]
            sizes = [max(x["size_mm"]) for x in rest if "size_mm" in x]
            span = f" (up to {max(sizes):.3g} mm)" if sizes else ""
            print(f"  ... and {len(rest)} more: {e['reason']}{span}; --json lists them")


def _cmd_batch(args: argparse.Namespace) -> int:
    """``clothgrid batch INPUTS... -o OUTDIR``: grid many files on Dask, print the summary."""
    import signal

    _resume_collector()     # a long run: collect as usual

    from . import batch

    options = _grid_options(args)
    progress = None if args.quiet else batch.ProgressLine(sys.stderr, every=args.log_every)

    def terminate(signum: int, frame: Any) -> None:   # SIGTERM: stop like Ctrl-C, closing the cluster
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, terminate)
    try:
        run = batch.batch(args.inputs, args.output_dir, options=options, output=_output_options(args),
                          templates=args.template or (batch.DEFAULT_TEMPLATE,), units=args.units,
                          line=args.line, min_turn=args.min_turn, workers=args.workers,
                          scheduler=args.scheduler, retries=args.retries, redo_failed=args.redo_failed,
                          force=args.force, progress=progress, garment=args.garment, seams=args.seams,
                          unfold=args.unfold, grade=args.grade)
    finally:
        signal.signal(signal.SIGTERM, old)
    s = run.summary
    shown = 0
    for e in run.entries:       # one error line per failed file and per failed piece (capped)
        if e["status"] == "failed":
            error = str(e.get("error"))
            lines = [error if str(e["input"]) in error else f"{e['input']}: {error}"]
        else:
            lines = [f"{e['input']}: piece {f['name']!r}: {f['reason']}" for f in e["failed_pieces"]]
        for text in lines:
            if shown < BATCH_ERRORS_SHOWN:
                _say(f"error: {text}")
            shown += 1
    if shown > BATCH_ERRORS_SHOWN:
        _say(f"... and {shown - BATCH_ERRORS_SHOWN} more errors: see {run.manifest}")
    print(f"{s['inputs']} files: {s['ok']} ok, {s['partial']} partial, {s['failed']} failed"
          f" ({s['skipped']} done before, {s['done_now']} gridded now); {s['pieces']} pieces written, "
          f"{s['pieces_failed']} failed")
    if s["done_now"]:
        print(f"{s['pieces_now']} pieces in {s['seconds']:.1f} s on {s['workers'] or '?'} workers "
              f"(after {s['startup_seconds']:.1f} s starting them): {_fmt(s['pieces_per_s'], '.2f')} pieces/s, "
              f"{_fmt(s['files_per_s'], '.2f')} files/s")
    for w in s["worst_pieces"][:3]:
        if w.get("folded") or w.get("missed"):
            print(f"worst: {w['stem']}/{w['name']}: {w['folded']} folded, min angle "
                  f"{_fmt(w['min_angle_deg'], '.3g')} deg" + (f"; misses: {'; '.join(w['missed'])}" if w["missed"] else ""))
    for f in s["slowest_files"][:3]:
        print(f"slowest: {f['stem']}: {_fmt(f['seconds'], '.2f')} s, {f['pieces']} pieces")
    print(f"manifest: {run.manifest}", flush=True)
    if s["ok"] + s["partial"] == 0:     # nothing written: bad files (2), or lost workers / write errors (1)
        return 2 if all(e.get("retry") is False for e in run.failed) else 1
    return EXIT_PARTIAL if s["failed"] or s["pieces_failed"] else 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from importlib.resources import as_file, files

    from . import pipeline

    folder = Path(args.output_dir)
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{str(folder)!r} exists and is not a folder")
    name = Path(DEMO_PIECE).stem
    options = pipeline.GridOptions(nodes=args.nodes, weights=args.weights)
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    with as_file(files("clothgrid").joinpath("data", DEMO_PIECE)) as source:
        (job,) = pipeline.read_jobs(source, [folder / f"{name}.obj", folder / f"{name}.npz"], folder / f"{name}.png",
                                    options=options)
    t_load = time.perf_counter() - t0
    with _first_compile_said(_say):
        result = pipeline.run_job(job, _say)
    t0 = time.perf_counter()
    written = pipeline.write_result(result)
    t_write = time.perf_counter() - t0

    nu, nv = result.grid.shape
    if result.quality.folded:
        _say(f"warning: {result.quality.folded} folded cells (see the quality table)")
    print(f"{job.name}: {nu} x {nv} nodes, {args.weights} weights")
    print(result.quality.table())
    print(timing_line(result.grid.info, result.seconds))
    print(f"time: load {t_load:.3f} s, solve {result.seconds:.3f} s, write {t_write:.3f} s")
    print(f"files in {folder}/: {', '.join(p.name for p in written)}")
    return 0


# --------------------------------------------------------------------------- entry point


def _quiet_stdout() -> None:
    """Point stdout at /dev/null so that the interpreter's final flush into a closed pipe is silent."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):   # no real stdout (captured in tests)
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``clothgrid`` command line and return its exit code.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 2 on bad input or usage, 3 when not converged, 4
        (:data:`EXIT_PARTIAL`) when some pieces of a pattern file failed and the
        others were written or listed, 130 when interrupted (SIGINT), 143 on
        SIGTERM, 129 on SIGHUP (temporary files removed, no output left), 141 when
        the reader of the output closed the pipe. Unexpected exceptions propagate
        with their traceback.
    """
    from .blas_threads import one_blas_thread
    from .lean_imports import preload_cython_blas, svgpathtools_without_quad
    from .pages import small_pages

    preload_cython_blas()       # Numba's BLAS check without all of scipy.linalg: 0.1 s
    svgpathtools_without_quad() # svgpathtools without scipy.integrate (clothgrid samples paths itself): 0.4 s
    # one BLAS thread for the whole command: OpenBLAS's threads spin after each change of their
    # number, so a command that restored them between pieces would slow the next piece's kernels
    with _signals_as_interrupts(), _collector_paused(), small_pages(), one_blas_thread():
        try:
            return _main(argv)
        except Interrupted as exc:          # a signal while parsing or reporting
            _say(str(exc))
            return 128 + exc.signum
        except KeyboardInterrupt:
            _say("interrupted")
            return 130


def console_main() -> int:
    """The ``clothgrid`` program (and ``python -m clothgrid``): :func:`main`, then a quick exit.

    Once :func:`main` has returned, every output file is complete and renamed into place and every
    temporary file is gone; what is left is the interpreter's teardown of some 10^5 objects
    (Numba's registries and kernels, LLVM's modules): 35 ms of a 0.65 s run (1024^2 grid to .npz),
    measured, and before that its final garbage collections (0.12 s). So the program flushes its
    two output streams and ends the process with ``os._exit`` and :func:`main`'s exit code.
    Should a flush fail, it returns the code instead and the interpreter exits the usual way
    (its objects frozen first (:func:`gc.freeze`), which skips the collections).
    """
    code = main()
    gc.freeze()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):
        return code
    os._exit(code)


#: True while :func:`_collector_paused` holds the collector off that was on when it began
_collector_held = False


@contextlib.contextmanager
def _collector_paused():
    """Hold Python's cyclic garbage collector off while a command starts up.

    Numba's import, its registries and the first cached kernels create some 10^5 long-lived
    objects, and the collector's passes over them while they are made cost 50-70 ms of a 1.1 s
    run (1024^2 grid to .npz, measured). A command that goes on past its first job calls
    :func:`_resume_collector`, so a long run never goes without collection; the collector is
    back as it was when the command ends.
    """
    global _collector_held
    held = gc.isenabled()
    gc.disable()
    _collector_held = held
    try:
        yield
    finally:
        if _collector_held:
            gc.enable()
        _collector_held = False


def _resume_collector() -> None:
    """Turn the collector that :func:`_collector_paused` holds off back on (the start-up is over)."""
    global _collector_held
    if _collector_held:
        # The objects made so far (Numba's registries, types and kernels: some 10^5) live as long as
        # the process: frozen, no collection scans them again (the first one after start-up took
        # about 30 ms of a 0.7 s run).
        gc.freeze()
        gc.enable()
        _collector_held = False


class Interrupted(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP arrived: unwind (temporary files are removed on the way) and
    exit with ``128 + signum`` (130, 143, 129)."""

    def __init__(self, signum: int):
        import signal

        self.signum = int(signum)
        name = signal.Signals(signum).name
        super().__init__("interrupted" if name == "SIGINT" else f"terminated by {name}")


#: the signals that end a run cleanly: SIGINT (Ctrl-C), SIGTERM (kill, a batch system), SIGHUP
#: (the terminal closed)
HANDLED_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")


@contextlib.contextmanager
def _signals_as_interrupts():
    """Turn the first of :data:`HANDLED_SIGNALS` into :class:`Interrupted` in the main thread.

    The ``except BaseException`` clean-ups of the writers and the pipeline then remove
    temporary and half-written files as they do for Ctrl-C. Signals after the first are
    ignored, so that a second Ctrl-C or SIGTERM cannot cut the clean-up short (and stay ignored
    once one arrived: the run is ending). Otherwise the previous handlers are restored on the
    way out (``main`` may be called from a program).
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []

    def handler(signum: int, frame: Any) -> None:
        if got:                                 # already unwinding: let the clean-up finish
            return
        got.append(signum)
        raise Interrupted(signum)

    previous = {}
    for name in HANDLED_SIGNALS:
        sig = getattr(signal, name, None)
        if sig is None:
            continue
        try:
            previous[sig] = signal.signal(sig, handler)
        except (OSError, ValueError):
            pass
    try:
        yield
    finally:
        # after a signal the run is ending: keep ignoring the next ones until the exit, so that
        # a second Ctrl-C or SIGTERM cannot kill the interpreter half-way out
        # (SIG_IGN, not a Python handler: the interpreter's finalisation puts Python handlers
        # back to the default, which would let a late second signal kill it)
        for sig, old in previous.items():
            if got:
                old = signal.SIG_IGN
            try:
                signal.signal(sig, old)
            except (OSError, ValueError, TypeError):
                pass


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(None if argv is None else list(argv))
    except SystemExit as exc:  # --help, --version, usage errors
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    if getattr(args, "func", None) is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        with warnings.catch_warnings():
            # NumPy's overflow / invalid-value warnings are no message for the user: a number
            # that overflows is refused with an error of its own, and no non-finite
            # coordinate reaches an output (generate checks the grid)
            warnings.simplefilter("ignore", RuntimeWarning)
            return args.func(args)
    except BrokenPipeError:   # `clothgrid pieces FILE | head`: the reader has what it wanted
        _quiet_stdout()
        return 141
    except Interrupted as exc:
        _say(f"{exc}; no output written" if args.func is not _cmd_pieces else str(exc))
        return 128 + exc.signum
    except KeyboardInterrupt:
        _say("interrupted")
        return 130
    except RecursionError:
        _say(f"error: {getattr(args, 'input', '')}: the input nests too deeply to be read "
             f"(limit: {MAX_NESTING} levels)")
        return 2
    except MemoryError:
        _say(f"error: {getattr(args, 'input', '')}: out of memory (the memory check did not foresee "
             "this: use fewer nodes or a smaller input); no output written")
        return 2
    except PiecesError as exc:
        if len(exc.failed) < 2 or exc.source is None:
            _say(f"error: {exc}")
        else:
            _say_failed(exc.source, exc.failed)
            _say(f"error: {exc.source}: none of its {len(exc.failed)} pieces could be used (above); "
                 "no output written")
        if exc.failed and all(isinstance(f.error, NotConvergedError) for f in exc.failed):
            return 3
        return 2
    except NotConvergedError as exc:
        _say(f"error: {exc}")
        _say("no output written; raise --max-iter or pass --allow-unconverged to keep the grid")
        return 3
    except InputError as exc:
        _say(f"error: {exc}")
        return 2
    except ClothgridError as exc:
        _say(f"error: {exc}")
        return 1
