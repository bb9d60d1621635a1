"""Exceptions raised by clothgrid.

Every error a user can cause derives from :class:`ClothgridError`; the CLI maps
:class:`InputError` (and its subclasses) to exit code 2 and
:class:`NotConvergedError` to exit code 3. A pattern file some of whose pieces
fail while others are written is no exception: ``clothgrid generate`` and
``clothgrid pieces`` then exit with code 4 (``clothgrid.cli.EXIT_PARTIAL``).
"""

from __future__ import annotations

__all__ = [
    "ClothgridError",
    "InputError",
    "BoundaryError",
    "SizeError",
    "PiecesError",
    "NotConvergedError",
    "BackendUnavailableError",
    "MissingDependencyError",
]


class ClothgridError(Exception):
    """Base class of every clothgrid error."""


class InputError(ClothgridError, ValueError):
    """Bad input or bad options: the user must change what they asked for."""


class BoundaryError(InputError):
    """The four boundary curves are not a valid piece (open corners, NaN, ...)."""


class SizeError(InputError):
    """The requested grid does not fit (memory, texture size, ...)."""


class PiecesError(InputError):
    """No piece of a pattern file could be read or gridded.

    ``failed`` lists each piece and why
    (:class:`clothgrid.patterns.piece.PieceFailure`); ``source`` is the file.
    """

    def __init__(self, message: str, failed=(), source=None):
        super().__init__(message)
        self.failed = list(failed)
        self.source = source


class BackendUnavailableError(InputError):
    """The requested backend cannot run on this machine."""


class MissingDependencyError(InputError, ImportError):
    """An optional package a feature needs (trimesh, pyvista, ...) is not installed."""


class NotConvergedError(ClothgridError):
    """An iterative solve reached ``max_iter`` before meeting the tolerance.

    The unconverged grid is attached as ``grid`` so callers may still use it.
    """

    def __init__(self, message: str, grid=None):
        super().__init__(message)
        self.grid = grid
