"""Signals while the command line starts: a message and the exit code, not a traceback.

``python -m clothgrid`` and the ``clothgrid`` script import the package (NumPy,
SciPy: about a second) before :func:`clothgrid.cli.main` installs its signal
handlers. A Ctrl-C in that window would print a ``KeyboardInterrupt``
traceback, and SIGTERM or SIGHUP would kill the process without a word.
:func:`guard_cli_start`, run first thing by ``clothgrid/__init__.py``, installs
handlers for that window that print one ``clothgrid:`` line and exit with
``128 + signum`` (130, 143, 129) at once: nothing has been written yet, so
there is nothing to clean up. ``main`` then puts its own handlers in place.

Only a process that is starting clothgrid's command line is touched: a program
that imports clothgrid as a library keeps its signal handlers. Only the
standard library is imported here.
"""

from __future__ import annotations

import os
import signal
import sys
from typing import Any

__all__ = ["guard_cli_start", "starting_the_cli", "one_blas_thread_from_the_start", "BLAS_THREAD_VARIABLES",
           "short_openmp_spin", "OPENMP_SPIN", "threads_for_cpu_quota", "thread_summary"]

#: options of the ``python`` command that take a separate argument (``-X importtime``)
_OPTION_ARGS = ("-X", "-W", "--check-hash-based-pycs")
#: the signals of :data:`clothgrid.cli.HANDLED_SIGNALS`, with their messages
_MESSAGES = {"SIGINT": "interrupted", "SIGTERM": "terminated by SIGTERM", "SIGHUP": "terminated by SIGHUP"}


def _module_run(orig_argv: list[str]) -> str | None:
    """The module that ``python [options] -m MODULE`` runs, or None (a script, ``-c``, a REPL)."""
    k = 1
    while k < len(orig_argv):
        a = orig_argv[k]
        if a == "-m":
            return orig_argv[k + 1] if k + 1 < len(orig_argv) else None
        if a.startswith("-m"):
            return a[2:]
        if a in _OPTION_ARGS:
            k += 2
            continue
        if a == "-c" or a == "-" or not a.startswith("-"):
            return None
        k += 1
    return None


def starting_the_cli() -> bool:
    """Is this interpreter starting clothgrid's command line?

    True for ``python [options] -m clothgrid ...`` while the module is being
    located (``sys.argv[0]`` is ``"-m"`` then) and for the installed
    ``clothgrid`` script.
    """
    argv0 = sys.argv[0] if sys.argv else ""
    if argv0 == "-m":
        return _module_run(list(getattr(sys, "orig_argv", []))) == "clothgrid"
    name = os.path.basename(argv0)
    return name in ("clothgrid", "clothgrid.exe", "clothgrid-script.py")


def _stop(signum: int, frame: Any) -> None:
    """Exit at once with one line: a signal during the imports of a command-line run.

    (Also after :func:`clothgrid.cli.main` has returned and put this handler back: the
    run is over then, and the exit code says it was cut short.)
    """
    name = signal.Signals(signum).name
    try:
        os.write(2, f"clothgrid: {_MESSAGES.get(name, name)}\n".encode())
    finally:
        os._exit(128 + signum)


#: The BLAS libraries' thread variables, read once as each library loads (with NumPy and SciPy)
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread_from_the_start() -> None:
    """A command-line run: the BLAS libraries on one thread from their start (the variables set
    before NumPy loads, where the user set none), instead of threadpoolctl's lookup and limits in
    every call (:mod:`clothgrid.blas_threads`, which then asks no library: about 7 ms of the
    command's start). The command's solves gain nothing from BLAS threads but ``fdm`` forced on a
    grid over 512^2 (1024^2: 0.43 s against 0.33 s), and their spinning slowed its Numba kernels."""
    if any(v in os.environ for v in BLAS_THREAD_VARIABLES) or "numpy" in sys.modules:
        return
    for v in BLAS_THREAD_VARIABLES:
        os.environ[v] = "1"
    os.environ["CLOTHGRID_ONE_BLAS_THREAD"] = "1"


#: GNU OpenMP's spin count (``GOMP_SPINCOUNT``) that clothgrid sets where the user set neither it nor
#: ``OMP_WAIT_POLICY``: how long a Numba thread that has finished its share of a parallel loop
#: busy-waits for the next one before it sleeps. libgomp's default (300,000) is right on an idle
#: machine and ruinous on a busy one: a parallel loop ends only when its last thread does, and a
#: thread the system has parked behind other work keeps the others spinning for a whole time slice.
#: Two clothgrid runs side by side on two cores took 25x their time alone with it (the paper
#: weights' 1024^2 solve 1.7-1.9 s against 0.069 s; 91 survey pieces' fold-free grids 27 s against
#: 0.75 s), 2.4x and 1.7x with 3,000; alone, 3,000 costs nothing measurable
#: (``benchmarks/bench_contention.py``, docs/performance.md).
OPENMP_SPIN = "3000"


def short_openmp_spin() -> None:
    """Set ``GOMP_SPINCOUNT`` to :data:`OPENMP_SPIN` where the user set neither it nor
    ``OMP_WAIT_POLICY``. libgomp reads it once, when it loads: with Numba's first parallel kernel
    (Numba's ``omp`` threading layer); a process that loaded libgomp before importing clothgrid
    keeps its own setting."""
    if "GOMP_SPINCOUNT" in os.environ or "OMP_WAIT_POLICY" in os.environ:
        return
    os.environ["GOMP_SPINCOUNT"] = OPENMP_SPIN


def threads_for_cpu_quota(environ: "os._Environ[str] | dict[str, str] | None" = None,
                          quota: float | None = None, cpus: int | None = None) -> int | None:
    """Set ``NUMBA_NUM_THREADS`` to the CPUs the process's control group allows (rounded up) where
    that is fewer than the processors it may run on and the user set no thread count; returns the
    count set, or None. Numba starts a thread for every processor: under a CPU limit of one
    processor on two, the 1024^2 solve took 1.14x and the survey's fold-free grids 1.05x the time
    of one thread (1.2x and 1.3x with libgomp's own spin), and more threads over a smaller limit
    wait on each other more. Read once, when Numba loads. ``environ`` (default: this process's) with
    ``quota`` and ``cpus`` given: what would be set there."""
    env = os.environ if environ is None else environ
    if "NUMBA_NUM_THREADS" in env:
        return None
    par = sys.modules.get("numba.np.ufunc.parallel")
    if environ is None and par is not None and getattr(par, "_is_initialized", False):
        # this process's Numba imported and its threads started before clothgrid: their count is
        # fixed, and a different NUMBA_NUM_THREADS would make Numba's next compile raise (it rereads it)
        return None
    from .cgroups import cpu_quota, processors, quota_processors   # the standard library only

    if quota is None:
        quota = cpu_quota()
    if quota is None:
        return None
    if cpus is None:
        cpus = processors()
    want = quota_processors(quota)
    if want >= cpus:
        return None
    env["NUMBA_NUM_THREADS"] = str(want)
    if environ is None:
        _CAPPED[:] = [quota, cpus]
    return want


#: ``[quota, processors]`` where :func:`threads_for_cpu_quota` capped this process's Numba threads
_CAPPED: list[float] = []


def thread_summary() -> str:
    """One line (``-v``) on the threads the kernels run on: Numba's count and threading layer, what
    set the count, the OpenMP spin, and whether this process runs them serially (forked after its
    parent's OpenMP threads started). Imports nothing: a process that has not loaded Numba says so."""
    numba = sys.modules.get("numba")
    if numba is None:
        return "threads: Numba not loaded (no parallel kernel ran)"
    par = sys.modules.get("numba.np.ufunc.parallel")
    layer = getattr(par, "_threading_layer", None) if par is not None else None
    n = numba.config.NUMBA_NUM_THREADS
    if _CAPPED:
        why = f"a CPU limit of {_CAPPED[0]:g} of {int(_CAPPED[1])} processors"
    elif "NUMBA_NUM_THREADS" in os.environ:
        why = "NUMBA_NUM_THREADS"
    else:
        why = "the processors it may run on"
    parts = [f"threads: {n} Numba thread{'s' if n != 1 else ''} ({why})",
             f"threading layer {layer or 'not started'}"]
    if layer == "omp":
        parts.append(f"GOMP_SPINCOUNT {os.environ.get('GOMP_SPINCOUNT', 'libgomp default')}")
    jv = sys.modules.get("clothgrid.jit_variants")
    if jv is not None and jv.forked_from_openmp():
        parts.append("forked after the parent's OpenMP threads started: kernels run serially")
    return ", ".join(parts)


def guard_cli_start() -> None:
    """In a command-line run, end SIGINT/SIGTERM/SIGHUP during start-up with a message and 128+signum.

    Does nothing in a program that imports clothgrid, or outside the main thread.
    """
    if not starting_the_cli():
        return
    one_blas_thread_from_the_start()
    for name in _MESSAGES:
        sig = getattr(signal, name, None)
        if sig is None:
            continue
        try:
            if signal.getsignal(sig) in (signal.SIG_IGN,):    # nohup: an ignored SIGHUP stays ignored
                continue
            signal.signal(sig, _stop)
        except (OSError, ValueError):       # not the main thread
            pass
