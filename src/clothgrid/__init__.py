"""clothgrid: structured quad grids inside four boundary curves, for cloth simulation.

The public API::

    import clothgrid
    b = clothgrid.load_boundary("piece.json")          # or Boundary.from_sides / from_outline
    grid = clothgrid.generate(b, (256, 256))           # exact to tol=2**-12 of the piece's size
    print(clothgrid.quality(grid).table())
    grid.save("piece.obj")
    clothgrid.batch(["patterns/"], "meshes", workers=4)   # many files on Dask (clothgrid[batch])
"""

from __future__ import annotations

from ._startup import guard_cli_start, short_openmp_spin, threads_for_cpu_quota

guard_cli_start()          # python -m clothgrid / the clothgrid script: a signal while importing ends it cleanly
short_openmp_spin()        # Numba's threads sleep soon when they wait: no 25x slowdown on a busy machine
threads_for_cpu_quota()    # a container's CPU limit: no more Numba threads than it allows

from .boundary import Boundary
from .errors import (BackendUnavailableError, BoundaryError, ClothgridError, InputError, NotConvergedError,
                     PiecesError, SizeError)
from .generate import generate
from .grid import Grid
from .quality import Quality, quality
from .readers import load_boundary
from .weights import WeightField, Weights, make_weights

__version__ = "0.1.0"

__all__ = [
    "Boundary", "Grid", "Quality", "WeightField", "Weights", "generate", "load_boundary", "make_weights", "quality",
    "ClothgridError", "InputError", "BoundaryError", "SizeError", "PiecesError", "BackendUnavailableError", "NotConvergedError",
    "__version__", "batch",
]


def __getattr__(name: str) -> object:
    """``clothgrid.batch``: imported on first use (it needs Dask only when it runs)."""
    if name == "batch":
        import importlib

        return importlib.import_module(".batch", __name__)   # a callable module: clothgrid.batch(...)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
