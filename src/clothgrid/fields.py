"""Two-dimensional fields given as a number, an array, a ``.npy`` file or a grayscale image.

The heat solver's conductivity, source and capacity (one value a cell) and ``generate``'s weight
field (:class:`clothgrid.weights.WeightField`) are read here. Arrays are indexed ``[i, j]``,
``i`` along x or u (left to right) and ``j`` along y or v (bottom to top); an image's top row is
the top (``j`` last).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError

__all__ = ["load_field", "checked_field", "finite_number"]


def finite_number(x: Any, what: str) -> float:
    """``x`` as a finite float, else InputError naming ``what``."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a number, not {x!r}") from None
    if not math.isfinite(v):
        raise InputError(f"{what} must be finite, not {x!r}")
    return v


def load_field(value: Any, *, name: str, shape: tuple[int, int] | None = None,
               value_range: tuple[float, float] | None = None, positive: bool = True,
               range_option: str | None = None) -> np.ndarray | float:
    """A field of one value a cell: a number, an array, a ``.npy`` file or a grayscale image.

    Arrays are indexed ``[i, j]``, ``i`` along x (left to right) and ``j``
    along y (bottom to top), shape ``(nx, ny)``. An image (``.png``, ``.jpg``,
    ...) is read as gray levels in ``[0, 1]`` (the mean of its colour
    channels), black mapped to ``value_range[0]`` and white to
    ``value_range[1]``; its top row is the top of the rectangle (``j = ny-1``)
    and each pixel is a cell.

    Parameters
    ----------
    value : float, array_like, str or Path
    name : str
        What the field is, for messages.
    shape : (int, int), optional
        The cells' shape the field must have.
    value_range : (float, float), optional
        For images: the values of black and white.
    positive : bool
        Values must be > 0 (else >= 0 is not checked: any finite value).
    range_option : str, optional
        The command-line option that gives ``value_range``, for the message
        when an image comes without one (default ``--NAME-range``).

    Returns
    -------
    float or numpy.ndarray
        A number stays a number; anything else is a float64 ``(nx, ny)`` array.
    """
    if isinstance(value, (int, float, np.number)) and not isinstance(value, bool):
        v = finite_number(value, name)
        if positive and v <= 0:
            raise InputError(f"{name} must be positive, not {value!r}")
        return v
    if isinstance(value, (str, Path)):
        path = Path(value)
        try:
            v = float(str(value))
        except ValueError:
            pass
        else:
            return load_field(v, name=name, shape=shape, value_range=value_range, positive=positive,
                              range_option=range_option)
        if not path.is_file():
            raise InputError(f"{name}: no such file {str(path)!r}")
        if path.suffix.lower() == ".npy":
            try:      # the header first (a memory map reads no data): a size that cannot fit is refused
                mapped = np.load(path, mmap_mode="r", allow_pickle=False)
                _check_count(int(np.prod(mapped.shape, dtype=np.int64)), name, path)
                arr = np.array(mapped)
                del mapped
            except InputError:
                raise
            except OSError as exc:
                raise InputError(f"{name}: cannot read {str(path)!r}: {exc}") from None
            except ValueError:
                raise InputError(f"{name}: {str(path)!r} is not a complete NumPy .npy array of numbers") from None
        else:
            arr = _read_image(path, name, value_range, range_option or f"--{name.replace(' ', '-')}-range")
    else:
        arr = value
    return checked_field(arr, name=name, shape=shape, positive=positive)


def checked_field(value: Any, *, name: str, shape: tuple[int, int] | None = None,
                  positive: bool = True) -> np.ndarray:
    """``value`` as a C-contiguous float64 2D array of finite numbers (positive ones where
    ``positive``; of ``shape`` where given), else InputError naming ``name``."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "fiu":
        raise InputError(f"{name} must hold numbers, not {arr.dtype}")
    arr = np.ascontiguousarray(arr, dtype=np.float64)
    if arr.ndim != 2 or min(arr.shape) < 1:
        raise InputError(f"{name} must be a 2D array (nx, ny), not of shape {arr.shape}")
    if shape is not None and arr.shape != tuple(shape):
        raise InputError(f"{name} has shape {arr.shape}, the cells are {tuple(shape)}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} holds NaN or infinite values")
    if positive and not np.all(arr > 0):
        bad = np.argwhere(~(arr > 0))[0]
        raise InputError(f"{name} must be positive everywhere; cell ({bad[0]}, {bad[1]}) holds {arr[tuple(bad)]!r}")
    return arr


def _check_count(count: int, name: str, path: Path) -> None:
    from .limits import MAX_FIELD_VALUES

    if count > MAX_FIELD_VALUES:
        raise InputError(f"{name}: {str(path)!r} holds {count:,} values, more than the limit of "
                         f"{MAX_FIELD_VALUES:,} for a field")


def _read_image(path: Path, name: str, value_range: tuple[float, float] | None, option: str) -> np.ndarray:
    if value_range is None:
        raise InputError(f"{name}: an image needs the values of black and white: give {option} LO,HI")
    lo, hi = (finite_number(v, f"{name}'s range") for v in value_range)
    import matplotlib.image as mpimg
    from PIL import Image

    try:
        with Image.open(path) as probe:          # the header only: its size before any pixel is decoded
            w, h = probe.size
        _check_count(w * h, name, path)
        img = np.asarray(mpimg.imread(path), dtype=np.float64)
    except InputError:
        raise
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as exc:
        raise InputError(f"{name}: cannot read the image {str(path)!r}: {exc}") from None
    if path.suffix.lower() not in (".png",) and img.max(initial=0) > 1:
        img = img / 255.0
    if img.ndim == 3:
        img = img[..., :3].mean(axis=-1) if img.shape[-1] >= 3 else img[..., 0]
    if img.ndim != 2:
        raise InputError(f"{name}: {str(path)!r} is not a 2D image")
    gray = np.clip(img, 0.0, 1.0)[::-1].T        # rows top-down -> [i, j] with j upward
    return lo + (hi - lo) * gray
