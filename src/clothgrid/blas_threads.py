"""BLAS on one thread inside clothgrid's own work, where its threads gain nothing.

clothgrid's parallel layer is Numba's (two threads on a two-core machine).
OpenBLAS keeps threads of its own, which spin for about a tenth of a second
after each threaded call and after each change of their number; a Numba
kernel started in that while shares the cores with them. The fast
diagonalisation's products (:mod:`clothgrid.solvers.fdm`) gain nothing from
OpenBLAS's threads up to 512 x 512 nodes (74 ms either way on two cores),
while the fold-free step after them ran 20 % slower at 512^2 (0.171 against
0.141 s) and the pattern survey's ordered sweeps in parallel parts 50 %
slower (docs/performance.md, "Thirteenth pass").

:func:`generate <clothgrid.generate>` therefore runs with the BLAS libraries
on one thread (:func:`one_thread`, threadpoolctl), and gives the caller's
settings back when it returns; the fdm solve of a grid over 512 x 512 nodes,
whose products do gain from them (427 -> 327 ms at 1024^2), takes the
threads back for its products (:func:`host_threads`). Like any threadpoolctl
limit, it holds process-wide while it lasts. The command line instead starts
its BLAS libraries on one thread (:func:`clothgrid._startup.one_blas_thread_from_the_start`,
where the user set no thread variable) and asks them nothing.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from typing import Any

__all__ = ["one_thread", "host_threads", "one_blas_thread"]

_STATE: dict[str, Any] = {}
_LOCK = threading.Lock()


def _controller() -> Any:
    """threadpoolctl's controller of the BLAS libraries loaded (looked up again once SciPy's
    linear algebra, which brings its own OpenBLAS, has been imported); None without threadpoolctl."""
    if os.environ.get("CLOTHGRID_ONE_BLAS_THREAD") == "1":
        return None     # a command-line run: its BLAS libraries started on one thread (clothgrid._startup)
    scipy_in = "scipy.linalg" in sys.modules
    if "ctl" not in _STATE or (scipy_in and not _STATE["scipy"]):
        try:
            from threadpoolctl import ThreadpoolController
        except ImportError:          # pragma: no cover - a dependency; kept working without it
            _STATE.update(ctl=None, scipy=True, threads=1)
            return None
        ctl = ThreadpoolController().select(user_api="blas")
        threads = max([lib.num_threads for lib in ctl.lib_controllers] + [1])
        _STATE.update(ctl=ctl, scipy=scipy_in, threads=_STATE.get("threads", threads))
    return _STATE["ctl"]


def one_thread() -> contextlib.AbstractContextManager:
    """A context manager in which the BLAS libraries loaded run on one thread.

    The libraries are looked up once (about 3 ms); entering and leaving costs about 10 us.
    Without threadpoolctl installed it changes nothing.
    """
    ctl = _controller()
    return contextlib.nullcontext() if ctl is None else ctl.limit(limits=1)


def host_threads() -> contextlib.AbstractContextManager:
    """A context manager in which the BLAS libraries run on as many threads as they had when
    clothgrid first looked (inside :func:`one_thread`: its threads back, for large products)."""
    ctl = _controller()
    return contextlib.nullcontext() if ctl is None else ctl.limit(limits=_STATE["threads"])


@contextlib.contextmanager
def one_blas_thread():
    """:func:`one_thread` as a block or a decorator (``@one_blas_thread()``), as
    :func:`clothgrid.generate`, the fold-free functions and the command line use it.

    The blocks of all threads count together: the first to enter limits the libraries, the last to
    leave gives the caller's setting back (Python threads running ``generate`` side by side, as a
    threaded Dask worker does, do not undo each other's limit), and a block inside another asks no
    library (1 us instead of 10)."""
    with _LOCK:
        depth = _STATE.get("depth", 0)
        if depth == 0:
            limiter = one_thread()
            limiter.__enter__()
            _STATE["limiter"] = limiter
        _STATE["depth"] = depth + 1
    try:
        yield
    finally:
        with _LOCK:
            _STATE["depth"] -= 1
            if _STATE["depth"] == 0:
                _STATE.pop("limiter").__exit__(None, None, None)
