"""The pipeline: boundary -> initial grid -> weights -> solver -> :class:`Grid`."""

from __future__ import annotations

import math
import time
from typing import Callable

import numpy as np

from .backends import get_backend
from .boundary import Boundary
from .errors import InputError, NotConvergedError, SizeError
from .limits import MAX_NODES_PER_SIDE
from .grid import Grid
from .initial import INITS, boundary_grid, initial_grid
from .memory import check_memory, estimate_bytes, format_bytes
from .blas_threads import one_blas_thread
from .pages import small_pages
from .solvers import SOLVERS, Problem, choose_solver, solve
from .weights import WeightField, Weights, edge_contrast, make_weights

__all__ = ["generate", "parse_nodes", "check_size"]

STOPS = ("error", "paper")
FUNCTIONALS = ("length", "foldfree", "auto")


def parse_nodes(nodes) -> tuple[int, int]:
    """``(nu, nv)`` from an int ``n``, a pair, or text ``"NUxNV"`` / ``"N"``; each at least 2."""
    if isinstance(nodes, str):
        parts = nodes.lower().replace("*", "x").split("x")
        try:
            vals = [int(p) for p in parts]
        except ValueError:
            raise InputError(f"nodes must look like NUxNV (e.g. 64x48) or N, not {nodes!r}") from None
    elif isinstance(nodes, (int, np.integer)):
        vals = [int(nodes)]
    else:
        try:
            vals = list(nodes)
        except TypeError:
            raise InputError(f"nodes must be an int or a pair (nu, nv), not {nodes!r}") from None
    if len(vals) == 1:
        vals = vals * 2
    if len(vals) != 2 or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in vals):
        raise InputError(f"nodes must be two integers (nu, nv), not {nodes!r}")
    nu, nv = (int(v) for v in vals)
    if nu < 2 or nv < 2:
        raise InputError(f"each node count must be an integer >= 2 (at least 2 nodes along each side), not {nu}x{nv}")
    if max(nu, nv) > MAX_NODES_PER_SIDE:
        raise SizeError(f"a {nu}x{nv} grid has more than {MAX_NODES_PER_SIDE:,} nodes along a side, the "
                        "limit: use fewer nodes or a longer edge length")
    return nu, nv


def _check_options(init: str, solver: str, stop: str, tol: float, max_iter) -> None:
    if init not in INITS:
        raise InputError(f"unknown init {init!r}: use one of {', '.join(INITS)}")
    if solver != "auto" and solver not in SOLVERS:
        raise InputError(f"unknown solver {solver!r}: use one of auto, {', '.join(SOLVERS)}")
    if stop not in STOPS:
        raise InputError(f"unknown stop rule {stop!r}: use one of {', '.join(STOPS)}")
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and 0 < tol < 1):
        raise InputError(f"tol must be a number between 0 and 1 (relative to the piece's size), not {tol!r}")
    if max_iter is not None and (not isinstance(max_iter, (int, np.integer)) or max_iter < 1):
        raise InputError(f"max_iter must be a positive integer, not {max_iter!r}")


@small_pages()         # 4 KB pages: their first touch costs a fifth of huge pages' here (pages.small_pages)
@one_blas_thread()     # Numba's threads are the parallel layer: OpenBLAS's spinning ones only slow them
def generate(boundary: Boundary, nodes=None, *, init: str = "tfi",
             weights: str | tuple[np.ndarray, np.ndarray] | WeightField | Weights = "paper", k: float = 1.0,
             solver: str = "auto", backend: str = "auto", tol: float = 2.0**-12, stop: str = "error",
             max_iter: int | None = None, allow_unconverged: bool = False,
             progress: Callable[[str], None] | None = None, functional: str = "length") -> Grid:
    """Generate the structured grid inside ``boundary``.

    Parameters
    ----------
    boundary : Boundary
        The four sides.
    nodes : int or (int, int) or str, optional
        Grid size ``(nu, nv)``; sides with other point counts are resampled
        uniformly by arc length. Default: the sides' own points.
    init : {"tfi", "average", "zero"}
        Initial grid (eq. 4, the contour mean, or zeros). Only iterative
        solvers start from it; exact ones (direct, fdm) do not build it.
    weights : {"paper", "uniform"} or (wu, wv) or WeightField or Weights
        Edge weights (:func:`clothgrid.weights.make_weights`). A
        :class:`~clothgrid.weights.WeightField` grades the grid on purpose
        (finer where it is larger): ``functional="auto"`` then evens only the
        edges further out than the field explains, its bands widened by the
        square root of the field's contrast (``info["evened"]["widened"]``).
    k : float
        The paper's ``k`` for ``weights="paper"``.
    solver : {"auto", "direct", "fdm", "jacobi", "multigrid"}
        ``auto`` picks the fastest solver that meets ``tol`` for the size and
        weights (:func:`clothgrid.solvers.choose_solver`).
    backend : {"auto", "cpu", "gl", "cuda"}
        Where the array operations run: ``gl`` is OpenGL through headless EGL
        (the GPU's driver, or Mesa's llvmpipe), for solvers ``multigrid``
        (``auto``) and ``jacobi``; ``cuda`` is an NVIDIA GPU through CuPy and
        numba.cuda (``pip install 'clothgrid[cuda]'``), for solvers
        ``multigrid`` (``auto``) and ``fdm``. Both raise
        :class:`~clothgrid.errors.BackendUnavailableError` with the reason when
        the device cannot be used; the grid's info then records
        ``gl_renderer`` or ``cuda_device``. ``auto`` is ``cuda`` where it finds
        a GPU and runs ``solver`` and the grid has at least
        :data:`~clothgrid.backends.AUTO_GPU_MIN_NODES` nodes (about 724^2), else ``cpu``.
    tol : float
        Required accuracy: every node within ``tol`` times the boundary's
        bounding-box diagonal of the exact solution (default ``2**-12``).
    stop : {"error", "paper"}
        Jacobi's stopping rule: the true ``error`` bound, or the paper's
        "last step < tol" (not an error bound; for reproducing the paper).
    max_iter : int, optional
        Sweep (Jacobi) or V-cycle (multigrid) limit of iterative solvers
        (default: enough for Jacobi in theory; 100 cycles for multigrid).
    allow_unconverged : bool
        Return an unconverged grid (``info["converged"]`` False) instead of
        raising :class:`NotConvergedError`.
    progress : callable, optional
        Called with a line of text at each stage and during long iterations.
    functional : {"length", "foldfree", "auto"}
        ``length``: the weighted length functional (eq. 1), which can fold
        cells on non-convex pieces. ``auto``: its folded and poorly shaped
        cells (a corner angle under about 20 degrees) and the nodes near them
        are then relaxed by :func:`clothgrid.foldfree.relax`, and the nodes
        near its outlying edges (longer or shorter than 1.4 times the
        geometric mean) moved to even the edge lengths out, no angle made
        smaller than 25 degrees (:func:`clothgrid.evening.even_edges`; a
        simulator's time step follows its shortest edge). Planar pieces only:
        the length grid is returned unchanged when no cell is poor and no
        edge outlying, and a curved piece keeps its length grid, with
        ``info["foldfree_skipped"]`` saying why. ``foldfree``: every interior
        node is relaxed, then the edges evened.

    Returns
    -------
    Grid
        With ``info``: solver, backend, init, weights, k, tol, stop,
        iterations, error_estimate (relative; a guaranteed bound when
        ``error_bound`` is True), converged, seconds, nodes, shape,
        functional (the one used: ``length``, ``foldfree``, or ``evened``
        when only the edge evening moved nodes); with ``functional`` auto or
        foldfree also folded_before (folded cells of the length grid), folded
        (of the grid returned) and ``evened`` (the edge evening's info:
        spread before and after, nodes, sweeps, seconds); after the fold-free method
        also ``foldfree`` (its :func:`~clothgrid.foldfree.untangle` info) and
        ``quality_before`` (the length grid's :meth:`Quality.as_dict`).

    Raises
    ------
    InputError
        Bad options or boundary (:class:`BoundaryError`), a grid that does not
        fit in memory (:class:`SizeError`).
    NotConvergedError
        ``max_iter`` sweeps did not meet the stopping rule; the grid reached
        is attached as ``.grid``.
    """
    t0 = time.perf_counter()
    say = progress or (lambda _msg: None)
    _check_options(init, solver, stop, tol, max_iter)
    if not isinstance(functional, str) or functional not in FUNCTIONALS:
        raise InputError(f"unknown functional {functional!r}: use one of {', '.join(FUNCTIONALS)}")
    nu, nv = boundary.shape if nodes is None else parse_nodes(nodes)
    be = get_backend(backend, solver, nu * nv)   # before the resampling: an unavailable backend says so first
    if nodes is not None:
        boundary = boundary.resampled(nu, nv)
    if nu < 3 or nv < 3:
        raise InputError(f"a {nu}x{nv} grid has no interior nodes to place: use at least 3x3 nodes")
    if functional == "foldfree" and not boundary.planar:
        raise InputError("functional 'foldfree' is for planar pieces: this 3D piece is curved; "
                         "use functional 'length' (or 'auto', which keeps the length grid of a curved piece)")
    name, need, device_need = _plan(be, nu, nv, solver, weights, stop, boundary.dim)
    on_device = be.solvers
    separable = isinstance(weights, str) or (isinstance(weights, Weights) and weights.factors is not None)
    own = estimate_bytes(name, nu, nv, coords=2 if boundary.dim == 2 else 3, separable=separable, outputs=False)
    say(f"{nu}x{nv} grid, solver {name}: about {format_bytes(own)} of memory ({format_bytes(need)} with "
        "the outputs)")
    if on_device:
        say(f"backend {be.name}: {be.summary()}; about {format_bytes(device_need)} of device memory")
    w = make_weights(weights, nu, nv, k)
    # Exact solvers read only the boundary nodes: the initial grid matters to iterative ones.
    r0 = initial_grid(boundary, init) if name in ("jacobi", "multigrid") else boundary_grid(boundary)
    problem = Problem(r0, w, boundary.size, overwrite=True)
    t_solve = time.perf_counter()
    name, res = solve(problem, name, backend=be, tol=tol, stop=stop, max_iter=max_iter, progress=progress)
    seconds = time.perf_counter() - t0
    solve_seconds = time.perf_counter() - t_solve
    info = {
        "solver": name, "backend": be.name, "init": init, "weights": w.kind,
        "k": float(k) if w.kind == "paper" else None, "tol": float(tol), "stop": stop,
        "iterations": int(res.iterations), "error_estimate": float(res.error_estimate),
        "error_bound": bool(res.bound), "converged": bool(res.converged), "seconds": seconds,
        "solve_seconds": solve_seconds,
        "nodes": nu * nv, "shape": [nu, nv], "memory_estimate": own,
    }
    if res.extra:
        info.update(res.extra)
    info.update(be.describe())  # e.g. the GL renderer: EGL falls back to llvmpipe silently ({} on the cpu)
    flip = boundary.dim == 2 and boundary.orientation < 0
    grid = Grid.from_points(res.points, info=info, dim=boundary.dim, flip=flip)
    how = f" by {info['bound_method']}" if info.get("bound_method") in ("band barriers", "residual solve") else ""
    say(f"{name}: {res.iterations} iterations, error bound{how} {res.error_estimate:.3g} (tol {tol:.3g}), "
        f"{seconds:.3f} s")
    _check_finite(res.points, f"solver '{name}'")
    if not res.converged:
        rule = "last step < tol (the paper's rule)" if stop == "paper" and name == "jacobi" else f"error <= {tol:.3g}"
        # 'auto' picks multigrid on large grids: past its iterations the exact solve is the way out
        other = "'direct' (exact; slower and larger on big grids)" if name == "multigrid" else "'auto'"
        if name == "multigrid" and be.name == "gl" and not w.unit_stencil:
            # the gl backend keeps V-cycles (protocol.NoVectors), which stall on jumps of per-edge weights
            other += ", or backend 'cpu' (conjugate gradients where V-cycles stall)"
        msg = (f"solver '{name}' did not reach {rule} in {res.iterations} iterations: error bound "
               f"{res.error_estimate:.3g} of the piece's size; raise max_iter or use solver {other}")
        if name in ("direct", "fdm"):
            msg = (f"solver '{name}' solves exactly up to rounding, but its error bound "
                   f"{res.error_estimate:.3g} of the piece's size is above tol {tol:.3g}: the "
                   "tolerance is below what float64 rounding allows; use a larger tol")
        if not allow_unconverged:
            raise NotConvergedError(msg, grid)
        say("warning: " + msg)
    if functional == "length":
        grid.info["functional"] = "length"
        return grid
    widen = (math.sqrt(float(weights.values.max() / weights.values.min())) if isinstance(weights, WeightField)
             else 1.0)
    return _apply_functional(grid, functional, say, t0, flip, widen=widen)     # its grid's nodes checked finite there


def _check_finite(points: np.ndarray, who: str) -> None:
    """No non-finite coordinate may reach an output: raise InputError if the grid has one."""
    if np.isfinite(points.min()) and np.isfinite(points.max()):   # NaN and inf show there: no temporaries
        return
    ok = np.isfinite(points)
    if not ok.all():
        i, j = (int(x) for x in np.argwhere(~ok.all(axis=-1))[0][:2])
        raise _not_finite(who, i, j)


def _not_finite(who: str, i: int, j: int) -> InputError:
    """The error for a grid whose node ``(i, j)`` (the first such) has a non-finite coordinate."""
    return InputError(f"{who} gave a grid with non-finite coordinates (NaN or inf; first at node "
                      f"({i}, {j})): the boundary's coordinates or the weights are too extreme "
                      "for float64; nothing written")


def _plan(be, nu: int, nv: int, solver: str, weights, stop: str, dim: int, *, kept: int = 0,
          what: str = "") -> tuple[str, int, int]:
    """The solver that will run and the host and device bytes it needs, checked (SizeError) before
    anything is allocated; ``kept`` and ``what`` as for :func:`clothgrid.memory.check_memory`."""
    separable = isinstance(weights, str) or (isinstance(weights, Weights) and weights.factors is not None)
    on_device = be.solvers  # the solvers a device backend runs (gl, cuda); () on the CPU: all
    if on_device and solver != "auto" and solver not in on_device:
        raise InputError(f"solver {solver!r} does not run on backend {be.name!r}: use one of auto, "
                         f"{', '.join(on_device)} (or backend 'cpu')")
    if solver != "auto":
        name = solver
    elif on_device:  # the paper's rule is Jacobi's: on a device, auto with stop="paper" is the paper's method
        name = "jacobi" if stop == "paper" and "jacobi" in on_device else on_device[0]
    else:
        def contrast() -> float:   # per-edge arrays: the size of their jumps may pick too (read where it does)
            w = make_weights(weights, nu, nv)
            return edge_contrast(w.wu, w.wv)

        name = choose_solver(separable, nu, nv, None if isinstance(weights, str) else contrast)
    device_need = 0
    if on_device:  # the device's texture size and memory, before anything is allocated (SizeError)
        device_need = be.check_size(nu, nv, name, estimate_bytes(name, nu, nv),
                                    coords=2 if dim == 2 else 3, separable=separable)
    need = check_memory(name, nu, nv, kept=kept, what=what, coords=2 if dim == 2 else 3, separable=separable)
    if name == "jacobi" and not separable and stop == "error":  # the bound's barrier takes one direct solve
        need = max(need, check_memory("direct", nu, nv, kept=kept, what=what))
    return name, need, device_need


def check_size(nodes, *, solver: str = "auto", backend: str = "auto", weights="paper", stop: str = "error",
               dim: int = 2, kept: int = 0, what: str = "") -> tuple[str, int]:
    """Check, allocating nothing, that :func:`generate` can make an ``nodes`` grid with these options.

    The same check :func:`generate` makes first: host memory (and a device's
    memory and texture size). ``kept`` bytes are counted as already taken
    (grids made before, not yet written); ``what`` starts the message.

    Returns
    -------
    (str, int)
        The solver that would run and its host memory estimate in bytes.

    Raises
    ------
    SizeError
        The grid does not fit; the message says how much it needs, how much is
        available and the rule (90 % of it).
    InputError
        Bad nodes, an unknown solver, a solver the backend does not run.
    """
    nu, nv = parse_nodes(nodes)
    _check_options("tfi", solver, stop, 0.5, None)
    be = get_backend(backend, solver, nu * nv)
    name, need, _ = _plan(be, nu, nv, solver, weights, stop, dim, kept=kept, what=what)
    return name, need


def _fold_free_points(R: np.ndarray, X: np.ndarray, centre: np.ndarray, basis: np.ndarray, dim: int,
                      moved: np.ndarray | None, touched: list[np.ndarray]):
    """The fold-free grid's nodes from its plane coordinates ``X``, a function that puts the length
    grid ``R`` back as it was, and the ``(K, 2)`` nodes that may differ from ``R``'s where they were
    written into ``R`` (else None). Only the nodes the relax (``moved``) or the evening
    (``touched``) may have moved differ from ``R``'s: where they are at most a quarter of the grid,
    and the piece lies in the xy-plane, they are written into ``R`` itself (their old values kept
    to put back), not into a new grid-size array whose pages cost more than the rest of the write
    (5 ms at 1024^2); else a new array (:func:`~clothgrid.foldfree._with_interior`)."""
    from .foldfree import _axis_map, _with_interior
    from .grid_kernels import mask_places

    if moved is None and not touched:
        return R.copy(), lambda: None, None
    nu, nv = R.shape[:2]
    mask = np.zeros((nu, nv), bool) if moved is None else moved.copy()
    for t in touched:
        mask[t[:, 0], t[:, 1]] = True
    nodes = mask_places(mask)
    axes = _axis_map(centre, basis) if dim == 2 else None
    if axes is None or len(nodes) > nu * nv // 4:
        points = _with_interior(R, X, centre, basis, dim)
        _check_finite(points, "the fold-free step")
        return points, lambda: None, None
    i, j = nodes[:, 0], nodes[:, 1]
    old = R[i, j]                                # a copy (fancy indexing)
    for r, (k, sign) in enumerate(axes):         # _with_interior's values: X's coordinates, swapped and negated
        R[i, j, k] = X[i, j, r] * sign
    R[i, j, 3 - axes[0][0] - axes[1][0]] = 0.0

    def put_back() -> None:
        R[i, j] = old

    finite = np.isfinite(R[i, j]).all(axis=-1)   # the rest is the length grid's, checked already
    if not finite.all():
        put_back()
        q = int(np.argmin(finite))
        raise _not_finite("the fold-free step", int(i[q]), int(j[q]))
    return R, put_back, nodes


#: The auto step relaxes the nodes near poor cells (and smooths only those, also where it untangled
#: every node from a coarser grid). Where that leaves a smallest angle (as cell sines measure it,
#: corner cells aside) below this, it also relaxes every node of the length grid, evens that, and
#: keeps it where it is better on both counts (a larger smallest angle, an edge spread no larger).
#: On hooked pieces (racer, tank and GLX backs) the local relax squeezes the cells of a narrow neck
#: between two outline curves: 6.4 -> 10.7 degrees and spread 15.2 -> 6.9 on an AAMA racer back,
#: 4.1 -> 25 degrees and 173 -> 23 on a tank back. Over the survey's 455 pieces at 10 mm 33 retry
#: and 30 keep the whole relax, for 0.74 s more in all (docs/performance.md, seventeenth pass).
WHOLE_RETRY_DEG = 15.0
#: ... on grids of at most this many nodes (a whole relax costs seconds at 1024^2) ...
WHOLE_RETRY_MAX_NODES = 1 << 15
#: ... and only where the smallest angle is below this fraction of what the outline allows
#: (:func:`outline_cap_deg`): at a dart's tip the two cells share the outline's reflex angle, and
#: no relax raises their smaller one (the survey's pants, skirt and torso backs retried for nothing:
#: 3.88 -> 3.88 degrees, 0.4 s in all).
WHOLE_RETRY_ROOM = 0.9


def _even(X: np.ndarray, touched: list, say: Callable[[str], None], widen: float = 1.0) -> dict:
    """:func:`~clothgrid.evening.even_in_plane` of ``X``, with its progress line. ``widen`` > 1 (a
    :class:`~clothgrid.weights.WeightField`'s grading: the square root of its contrast) widens its
    bands and the spread it leaves alone by that factor: only edges further out than the field
    explains are evened."""
    from .evening import BAND, SPREAD_OK, WIDE_BAND, even_in_plane

    if widen > 1.0:
        ev = even_in_plane(X, touched=touched, band=BAND * widen, wide_band=WIDE_BAND * widen,
                           spread_ok=SPREAD_OK * widen)
        ev["widened"] = widen
    else:
        ev = even_in_plane(X, touched=touched)
    kept = f"; kept, the sweeps reached {ev['rejected_spread']:.3g}" if "rejected_spread" in ev else ""
    say(f"edge spread: {ev['spread_before']:.3g} -> {ev['spread_after']:.3g} "
        f"({ev['active']} nodes near outlying edges, {ev['sweeps']} sweeps, {ev['seconds']:.3f} s{kept})")
    return ev


def _local(ff: dict, R: np.ndarray) -> bool:
    """Whether the relax moved some nodes but did not smooth every interior one (its active sets, or
    every node untangled from a coarser grid and only the nodes near poor cells smoothed)."""
    nu, nv = R.shape[:2]
    return ff.get("moved", 0) > 0 and ff.get("smoothed", 0) < (nu - 2) * (nv - 2)


def _smallest_deg(X: np.ndarray) -> float:
    """The smallest corner angle of the plane grid ``X`` (degrees; the four grid-corner cells aside)."""
    from .foldfree_kernels import smallest_cell_sine

    return math.degrees(math.asin(min(1.0, max(-1.0, smallest_cell_sine(X)))))


def forced_by_outline(X: np.ndarray) -> bool:
    """Whether the plane grid ``X``'s smallest cell angle (as the sines measure it, grid-corner cells
    aside) is at least :data:`WHOLE_RETRY_ROOM` of what its outline allows (:func:`outline_cap_deg`):
    no relax, and no other grid of that outline, raises it much."""
    return _smallest_deg(X) >= WHOLE_RETRY_ROOM * outline_cap_deg(X)


def outline_cap_deg(X: np.ndarray) -> float:
    """An upper bound of any grid's smallest cell angle (degrees, as the sines measure it: an angle
    and 180 less it alike; grid-corner cells aside) on this outline: the two cells at a side's
    inner node share the outline's angle ``t`` there, so one of them has at most ``t / 2`` and, for
    ``t > 180`` (a dart's tip, a notch), one at least ``t / 2``, whose sine is that of ``180 - t / 2``.
    Where a grid's smallest angle is at this cap, no relax can raise it."""
    from .geometry import boundary_loop, turn_angles

    nu, nv = X.shape[:2]
    inner = 180.0 - np.degrees(turn_angles(boundary_loop(X)[:, :2]))   # the outline's angle inside
    inner[[0, nu - 1, nu + nv - 2, 2 * nu + nv - 3]] = np.nan           # the grid corners (loop order)
    if np.isnan(inner).all():
        return 90.0
    half = inner / 2.0
    return float(np.nanmin(np.minimum(half, 180.0 - half)))


def _whole_if_better(R, dim, X, centre, basis, ff, moved, ev, touched, say, widen=1.0):
    """:data:`WHOLE_RETRY_DEG`: the local result ``(X, centre, basis, ff, moved, ev, touched)``, or,
    where its smallest angle is below that, every node relaxed and evened from the length grid ``R``
    (not changed), if that is better (a larger smallest angle, an edge spread no larger, no fold).
    Starting from the local result instead took 1.5-2.7x fewer node steps and gave the same grids
    at 10 mm, but at 2 mm it kept a racer back in the local result's squeezed state (4.9 degrees
    against 9.3 from the length grid)."""
    from .foldfree import relax_in_plane

    local_deg = _smallest_deg(X)
    if not local_deg < min(WHOLE_RETRY_DEG, WHOLE_RETRY_ROOM * outline_cap_deg(X)):
        return X, centre, basis, ff, moved, ev, touched
    t = time.perf_counter()
    X2, centre2, basis2, ff2, moved2 = relax_in_plane(R, dim=dim, whole=True, progress=say)
    touched2: list[np.ndarray] = []
    ev2 = _even(X2, touched2, say, widen)
    whole_deg = _smallest_deg(X2)
    better = bool(ff2.get("untangled")) and whole_deg > local_deg and ev2["spread_after"] <= ev["spread_after"]
    record = {"smallest_deg_local": local_deg, "smallest_deg_whole": whole_deg,
              "spread_local": ev["spread_after"], "spread_whole": ev2["spread_after"], "kept": better,
              "seconds": time.perf_counter() - t}
    say(f"relax: the active sets left a smallest angle of {local_deg:.3g} deg (spread {ev['spread_after']:.3g}); "
        f"every node: {whole_deg:.3g} deg (spread {ev2['spread_after']:.3g}), "
        + ("kept" if better else "not kept"))
    if not better:
        ff["whole_retry"] = record
        return X, centre, basis, ff, moved, ev, touched
    ff2["whole_retry"] = record
    ff2["seconds"] = ff.get("seconds", 0.0) + ff2.get("seconds", 0.0)
    return X2, centre2, basis2, ff2, moved2, ev2, touched2


def _apply_functional(grid: Grid, functional: str, say: Callable[[str], None], t0: float, flip: bool,
                      widen: float = 1.0) -> Grid:
    """Record the length grid's folds; for ``foldfree`` / poor ``auto`` relax it; then even its edges
    (with bands ``widen`` times as wide: a weight field's grading, :func:`_even`)."""
    from .quality import quality, quality_record

    q, record = quality_record(grid)
    grid.info.update(functional="length", folded_before=q.folded, folded=q.folded)
    from .foldfree import check_grid_shape, relax_in_plane, to_plane

    # finite (generate checked), C-contiguous float64 (Grid's); the fold-free grid's nodes may be
    # written into it (_fold_free_points), put back where the length grid is handed back
    R = grid.points
    try:
        check_grid_shape(R, "relax")
        # relax and the evening both in the plane's coordinates, the 3D grid made once at the end
        X, centre, basis, ff, moved = relax_in_plane(R, dim=grid.dim, whole=functional == "foldfree",
                                                     progress=say)
    except InputError as exc:
        if functional == "foldfree":
            raise
        grid.info["foldfree_skipped"] = str(exc)
        say(f"warning: {q.folded} folded cells kept: {exc}")
        grid._quality = q
        return grid
    relaxed = not (functional == "auto" and ff.get("moved", 0) == 0)
    if X is None:
        X = np.ascontiguousarray(to_plane(R, centre, basis))
    touched: list[np.ndarray] = []
    ev = _even(X, touched, say, widen)
    if functional == "auto" and _local(ff, R) and R.shape[0] * R.shape[1] <= WHOLE_RETRY_MAX_NODES:
        X, centre, basis, ff, moved, ev, touched = _whole_if_better(R, grid.dim, X, centre, basis, ff, moved,
                                                                    ev, touched, say, widen)
    if not relaxed and ev["moved"] == 0:     # nothing poor, nothing to even: the length grid as it is
        grid.info.update(relax=ff, evened=ev)
        grid._quality = q                    # measured once (pipeline.run_job reads it)
        return grid
    if ev["moved"] == 0:
        touched.clear()             # a rejected evening put its nodes back
    points, put_back, changed = _fold_free_points(R, X, centre, basis, grid.dim, moved, touched)
    info = dict(grid.info)
    new = Grid.from_points(points, info=info, dim=grid.dim, flip=flip)
    # where the moved nodes were written into the length grid, only their blocks of cells are measured again
    q_after = quality(new) if record is None or changed is None else record.remeasure(new.points, changed)
    if q_after.folded > q.folded:
        put_back()
        # a wild outline (far from any four-sided shape) where untangling made it worse: never
        # hand back more folds than the length solve had
        grid.info.update(foldfree=ff, foldfree_rejected=f"it left {q_after.folded} folded cells, "
                         f"the length grid {q.folded}", seconds=time.perf_counter() - t0)
        say(f"fold-free: {q.folded} -> {q_after.folded} folded cells in {ff['seconds']:.3f} s; "
            f"the length grid is kept")
        grid._quality = q
        return grid
    new._quality = q_after   # measured once: pipeline.run_job reads it instead of measuring again
    new.info.update(functional="foldfree" if relaxed else "evened", folded=q_after.folded, evened=ev,
                    quality_before=q.as_dict(), seconds=time.perf_counter() - t0)
    if relaxed:
        new.info["foldfree"] = ff
        say(f"fold-free: {q.folded} -> {q_after.folded} folded cells in {ff['seconds']:.3f} s")
    else:
        new.info["relax"] = ff
    return new
