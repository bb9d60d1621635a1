"""What a grid needs in memory, said before allocating it.

Estimates are upper bounds calibrated on measured peak resident sizes (this
repository's ``benchmarks/bench_core.py`` and ``bench_solvers.py`` print them):
about 80 bytes per node for the pipeline (initial grid, result, uv and quads
for the output file), about 200 bytes per cell of one block of quality
measurements (:data:`clothgrid.quality.BLOCK_CELLS` cells at most), plus per
solver:

- ``fdm``: two dense eigenvector matrices, ``8 (m^2 + n^2)`` bytes, and the
  dense products' work arrays;
- ``direct``: the sparse LU factors, whose fill on an ``N``-node grid was
  measured at ``N (6.5 log2 N - 52)`` entries, about 24 bytes each at peak;
- ``jacobi``: one extra grid;
- ``multigrid`` (:func:`multigrid_bytes`): the grid (24 bytes a node) and the float64 iterate's
  parity planes (8 a coordinate) throughout; the float32 coarse levels (8 a coordinate) and the
  line solves' scratch live in the grid's memory while its contents are dead (:class:`Arena`),
  only what does not fit there comes on top. Weights without a separable form add their arrays
  (16 bytes a node), the stencils (56), the barrier solve's one-coordinate operations (24) and
  conjugate gradients' three vectors (24 a coordinate).

The estimate printed before a solve is the larger of the solve's peak (``outputs=False``: what
:func:`clothgrid.generate` holds) and the outputs' (the grid, uv and quads of an output file,
one block of quality measurements). Measured (``benchmarks/bench_speed.py --memory 4096``: a fresh
process, paper weights, the 2D T-shirt front): ``generate``'s resident peak 0.69 GB above the
interpreter's (0.86 GB in all), estimate 0.67 GB; with the coarse levels in the grid's memory
0.68 GB (0.85 GB in all), estimate 0.67 GB.

The memory available is the system's (``MemAvailable``) or, when the process
runs under a resource limit (``ulimit -v``: ``RLIMIT_AS``; ``ulimit -d``:
``RLIMIT_DATA``), what that limit leaves above what the process maps already,
or, in a control group with a memory limit (a container's ``--memory``), what
that leaves above the group's working set, whichever is least: a request the
limit cannot hold is refused by the check, with the limit's figures, instead of
failing with ``MemoryError`` or being killed by the group's out-of-memory killer.
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING, NamedTuple

from .errors import SizeError

if TYPE_CHECKING:                  # annotations only: this module imports no NumPy when loaded
    import numpy as np

__all__ = ["available_bytes", "system_available_bytes", "limit_headroom", "Headroom", "estimate_bytes", "check_memory",
           "format_bytes", "discard", "release", "Arena", "FIT_FRACTION", "KEPT_BYTES_PER_NODE", "multigrid_bytes",
           "DISCARD_MIN_BYTES", "SMALL_BYTES"]

PIPELINE_BYTES_PER_NODE = 80
#: what a finished grid holds until it is written: points (24), uv (16) and quads (32 per cell)
KEPT_BYTES_PER_NODE = 72
#: a grid fits when its estimate is at most this fraction of the available memory
FIT_FRACTION = 0.9
QUALITY_BYTES_PER_CELL = 200
#: a solve's own grid of at least this size gives its pages back while the solver holds the iterate
DISCARD_MIN_BYTES = 128 << 20


def available_bytes() -> int:
    """Memory available to this process now: the least of the system's free memory
    (:func:`system_available_bytes`) and what its resource limits leave (:func:`limit_headroom`)."""
    have = system_available_bytes()
    limit = limit_headroom()
    return have if limit is None else min(have, limit.bytes)


def _status_bytes(key: str) -> int | None:
    """A ``kB`` line of ``/proc/self/status`` (``VmSize``, ``VmData``) in bytes; None if unknown."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


class Headroom(NamedTuple):
    """What a resource limit leaves: ``bytes = limit - used`` (at least 0); ``used_what`` says whose
    use ``used`` is."""

    bytes: int
    limit: int
    used: int
    what: str
    used_what: str = "this process maps already"


def limit_headroom() -> Headroom | None:
    """What the tightest of this process's limits still lets it use: the soft address-space and
    data limits (``ulimit -v``, ``ulimit -d``) and its control group's memory limit (a container's
    ``--memory``, :func:`clothgrid.cgroups.memory_headroom`), which ``MemAvailable`` does not show
    (a grid that fitted the machine was killed by the group's out-of-memory killer, without a word).

    Returns
    -------
    Headroom or None
        The limit in bytes less what is held under it (``VmSize`` for ``RLIMIT_AS``, ``VmData``
        for ``RLIMIT_DATA``, the group's working set for its limit), and which limit
        (``"address-space limit (ulimit -v)"``); None when none is set (or on a system without them).
    """
    from .cgroups import memory_headroom

    best: Headroom | None = None
    group = memory_headroom()
    if group is not None:
        best = Headroom(group.room, group.limit, group.used,
                        "memory limit of its control group (a container's --memory)",
                        "the group uses already")
    try:
        import resource
    except ImportError:                      # not a Unix system
        return best
    for name, key, what in (("RLIMIT_AS", "VmSize", "address-space limit (ulimit -v)"),
                            ("RLIMIT_DATA", "VmData", "data-segment limit (ulimit -d)")):
        res = getattr(resource, name, None)
        if res is None:
            continue
        try:
            soft, _ = resource.getrlimit(res)
        except (OSError, ValueError):
            continue
        if soft == resource.RLIM_INFINITY or soft < 0:
            continue
        used = _status_bytes(key) or 0
        room = Headroom(max(int(soft) - used, 0), int(soft), used, what)
        if best is None or room.bytes < best.bytes:
            best = room
    return best


def system_available_bytes() -> int:
    """Memory the system has available now (``MemAvailable`` on Linux)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return 1 << 62


def multigrid_bytes(nu: int, nv: int, coords: int = 3, separable: bool = False) -> int:
    """Peak bytes of a multigrid solve of an ``nu x nv`` grid with ``coords`` coordinates, its own grid included.

    The largest of its three phases (module docstring); weights without a separable form add
    their arrays throughout.
    """
    from .multigrid_levels import hierarchy_bytes

    n = nu * nv
    grid = 24 * n
    planes = 8 * coords * n
    held = hierarchy_bytes(nu, nv, coords, separable=True) - planes          # coarse levels and scratch
    # weights without a separable form: the stencils (level 0's edge weights split by parity, the coarse
    # levels' four arrays), the barrier solve's right-hand side (the diagonal, 8: its iterate, planes and
    # coarse levels are carved out of the solve's own dead coarse levels and scratch, MultigridOps.spare),
    # and conjugate gradients' three level-0 vectors where V-cycles are slow (float64, every coordinate:
    # solvers.multigrid.ConjugateGradients; the barrier solve's three, one coordinate, are freed before).
    # Measured above the start, two coordinates: 10:1 blocks (conjugate gradients) 0.582 GB at 2048^2
    # and 2.396 GB at 4096^2 against 0.604 and 2.416 counted here; a smooth field (V-cycles only)
    # 0.409 and 1.755 GB (benchmarks/bench_speed.py --memory 2048 4096 --memory-weights smooth blocks)
    extra = 0 if separable else (8 * n + hierarchy_bytes(nu, nv, coords, separable=False) - planes - held
                                 + 24 * coords * n)
    # the coarse levels and scratch live in the grid's memory (an Arena over it), what does not fit beside
    return grid + planes + max(0, held - grid) + extra


def estimate_bytes(solver: str, nu: int, nv: int, *, coords: int = 3, separable: bool = False,
                   outputs: bool = True) -> int:
    """Peak memory, in bytes, to generate an ``nu x nv`` grid with ``solver``.

    Parameters
    ----------
    solver : str
        ``multigrid``, ``fdm``, ``direct`` or ``jacobi``.
    nu, nv : int
        Nodes.
    coords : int, optional
        Coordinates solved (2 for a planar piece); ``multigrid`` only.
    separable : bool, optional
        Weights with a separable form (the paper's, uniform); ``multigrid`` only.
    outputs : bool, optional
        Also the outputs' peak: the grid, uv and quads of an output file and a block of quality
        measurements (the whole command); without it, what :func:`clothgrid.generate` holds.
    """
    n = nu * nv
    m_u, m_v = max(nu - 2, 1), max(nv - 2, 1)
    from .quality import BLOCK_CELLS

    after = PIPELINE_BYTES_PER_NODE * n + QUALITY_BYTES_PER_CELL * min(n, BLOCK_CELLS) if outputs else 0
    if solver == "multigrid":
        return int(max(multigrid_bytes(nu, nv, coords, separable), after))
    total = PIPELINE_BYTES_PER_NODE * n + QUALITY_BYTES_PER_CELL * min(n, BLOCK_CELLS)
    if solver == "fdm":
        total += 16 * (m_u**2 + m_v**2) + 48 * n
    elif solver == "direct":
        fill = n * max(6.5 * math.log2(max(n, 2)) - 52.0, 8.0)
        total += int(24 * fill) + 60 * n
    elif solver == "jacobi":
        total += 24 * n
    return int(total)


def format_bytes(b: float, digits: int = 3) -> str:
    """``1.5 GiB``-style text (``digits`` significant digits; binary units up to EiB)."""
    units = ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB")
    top = 10**digits - 0.5          # what still rounds below 10**digits
    for unit in units:
        if b < top or unit == units[-1]:
            return f"{b:.{digits}g} {unit}" if b < top else f"{b:,.0f} {unit}"
        b /= 1024
    raise AssertionError


#: A grid needing at most this many bytes (with the grids kept before it) is not checked against the
#: system's memory: reading it (``/proc/meminfo``, the process's limits, its control group's files)
#: costs 0.3-0.6 ms a check, about a third of a real piece's whole length solve at 10 mm (20-100 nodes a
#: side, under 4 MiB), and the interpreter with NumPy and Numba holds some ten times this already. 0
#: checks every grid.
SMALL_BYTES = 16 * 2**20


def check_memory(solver: str, nu: int, nv: int, available: int | None = None, *,
                 kept: int = 0, what: str = "", coords: int = 3, separable: bool = False) -> int:
    """Raise :class:`SizeError` if the grid would not fit; return the estimate.

    A grid fits when its estimate (plus ``kept``: bytes already held that the
    available memory does not yet show, e.g. the grids of earlier pieces kept
    until every output is written) is at most :data:`FIT_FRACTION` (90 %) of
    the available memory. ``what`` starts the message (``"piece 'front': "``).
    The message gives the numbers of that rule: what is needed, what is
    available and the 90 % of it a solve may take; when a resource limit
    (``ulimit -v``) is what leaves that little, the limit and what the process
    maps already. ``coords`` and ``separable`` as for :func:`estimate_bytes`. A grid of at most
    :data:`SMALL_BYTES` (with ``kept``) is not checked against the system unless ``available``
    is given.
    """
    need = estimate_bytes(solver, nu, nv, coords=coords, separable=separable)
    total = need + max(int(kept), 0)
    if available is None and total <= SMALL_BYTES:
        return need
    have = available_bytes() if available is None else available
    if total > FIT_FRACTION * have:
        limit = limit_headroom() if available is None else None   # which limit binds, for the message
        hint = "use fewer nodes or a longer edge length"
        if solver == "direct":
            hint = "use solver 'fdm' (separable weights) or fewer nodes"
        held = (f" ({format_bytes(need)} for the grid and {format_bytes(kept)} for the grids made "
                "before it, kept until the outputs are written)" if kept > 0 else "")
        # the two numbers of the rule in one unit and 4 digits, so that 90 % of the one is the other
        unit_of = format_bytes(have).split()[1]
        scale = 1024 ** ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB").index(unit_of)
        # under a resource limit that binds, say which and how its figure comes about
        source = ""
        if limit is not None and limit.bytes <= have:
            source = (f" under the {limit.what}: {limit.limit / scale:.4g} {unit_of} less the "
                      f"{limit.used / scale:.4g} {unit_of} {limit.used_what},")
        raise SizeError(f"{what}a {nu}x{nv} grid with solver '{solver}' needs about {format_bytes(total)} of "
                        f"memory{held}, more than a solve may take: {FIT_FRACTION:.0%} of the "
                        f"{have / scale:.4g} {unit_of} available{source} is {FIT_FRACTION * have / scale:.4g} "
                        f"{unit_of}: {hint}")
    return need


def release(spare: "np.ndarray | None") -> int:
    """:func:`discard` a dead array from :data:`DISCARD_MIN_BYTES` on (below it, faulting the pages
    in again costs more time than the memory is worth); what a backend that keeps no arrays in host
    memory does with the ``spare`` of :meth:`~clothgrid.backends.protocol.Backend.multigrid`.

    Returns
    -------
    int
        Bytes released.
    """
    if spare is None or spare.nbytes < DISCARD_MIN_BYTES:
        return 0
    return discard(spare)


class Arena:
    """Arrays carved in turn out of the memory of one array whose contents are dead, fresh ones
    once it is used up.

    The point is memory that is already resident: the first touch of a fresh page costs a page
    fault and the zeroing of the page (0.3-1.5 s a GB on the development VM, where the host backs
    the guest's memory lazily). A multigrid solve keeps its coarse levels and scratch in the
    memory of the grid it writes its solution into (:attr:`~clothgrid.solvers.problem.Problem.overwrite`)
    instead of in fresh pages, and gives none of that grid's pages back: at 4096^2, 270 MB of coarse
    levels are not faulted in, nor the grid's 400 MB a second time when the solution is written.

    Carved arrays hold whatever the memory held (as :func:`numpy.empty`); they are C-contiguous and
    start on a 128-byte boundary (two cache lines: threads writing neighbouring arrays do not share
    one).

    Parameters
    ----------
    spare : numpy.ndarray or None
        C-contiguous; its contents are overwritten. ``None`` (or a non-contiguous array): every
        array is fresh.
    """

    ALIGN = 128

    def __init__(self, spare: "np.ndarray | None") -> None:
        import numpy as np

        self._buf = (spare.reshape(-1).view(np.uint8)
                     if spare is not None and spare.flags.c_contiguous and spare.nbytes else None)
        self._pos = 0
        #: bytes carved out of ``spare`` so far
        self.used = 0

    def empty(self, shape: tuple[int, ...], dtype: "np.typing.DTypeLike" = float) -> "np.ndarray":
        """An array carved from the spare memory if it still fits there, else a fresh zeroed one."""
        import numpy as np

        dtype = np.dtype(dtype)
        n = math.prod(shape) * dtype.itemsize
        if self._buf is not None:
            base = self._buf.ctypes.data
            start = -(-(base + self._pos) // self.ALIGN) * self.ALIGN - base
            if start + n <= self._buf.size:
                self._pos = start + n
                self.used += n
                return self._buf[start:start + n].view(dtype).reshape(shape)
        return np.zeros(shape, dtype)

    @property
    def position(self) -> int:
        """Bytes of the spare memory carved so far, alignment included (where the next array starts
        at the earliest): a mark for :meth:`carved_since`."""
        return self._pos

    def carved_since(self, mark: int) -> "np.ndarray | None":
        """The spare memory carved after ``mark`` (:attr:`position` then) as one C-contiguous uint8
        array, or None if nothing was."""
        if self._buf is None or self._pos <= mark:
            return None
        return self._buf[mark:self._pos]

    def owns(self, a: "np.ndarray") -> bool:
        """Whether ``a`` was carved from the spare memory."""
        import numpy as np

        return self._buf is not None and np.may_share_memory(a, self._buf)


def discard(a) -> int:
    """Give the memory pages of ``a``'s buffer back to the system; its contents then read as zero.

    For an array whose contents are dead but which must stay allocated, e.g. the grid a solve
    writes its solution into (:attr:`clothgrid.solvers.problem.Problem.overwrite`): while the solver
    holds the iterate in its own layout, the grid costs no resident memory (400 MB at 4096^2).
    Only whole pages inside the buffer are released (the partial first and last pages keep their
    contents). Linux only (``madvise(MADV_DONTNEED)`` on a private anonymous mapping, which
    NumPy's large arrays are); elsewhere, or for a non-contiguous array, nothing happens.

    Parameters
    ----------
    a : numpy.ndarray
        A C-contiguous array that owns its memory or views all of it.

    Returns
    -------
    int
        Bytes released (0 where nothing was done).
    """
    import sys

    if not sys.platform.startswith("linux") or not a.flags.c_contiguous or a.nbytes == 0:
        return 0
    import ctypes
    import mmap

    page = mmap.PAGESIZE
    addr = a.ctypes.data
    start = -(-addr // page) * page
    end = (addr + a.nbytes) // page * page
    if end <= start:
        return 0
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.madvise.argtypes = (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int)
        if libc.madvise(ctypes.c_void_p(start), ctypes.c_size_t(end - start), 4) != 0:   # MADV_DONTNEED
            return 0
    except (OSError, AttributeError):
        return 0
    return end - start
