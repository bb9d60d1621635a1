"""Length units: of pattern files, of ``--edge-length`` and ``--units``, of the outputs.

Pattern pieces are always returned in millimetres; :data:`UNITS` gives the
size of every known unit in millimetres and :func:`parse_length` reads a
length such as ``"5mm"``, ``"0.25 in"`` or ``"1.5cm"``.
"""

from __future__ import annotations

import math
import re

from .errors import InputError

__all__ = ["UNITS", "LENGTH_UNITS", "unit_to_mm", "length_scale", "parse_length", "format_length",
           "PLAUSIBLE_PIECE_MM", "size_warning"]

#: unit name -> millimetres (CSS: 96 px and 72 pt per inch)
UNITS: dict[str, float] = {
    "um": 1e-3,
    "mm": 1.0,
    "q": 0.25,          # CSS quarter-millimetre
    "cm": 10.0,
    "dm": 100.0,
    "m": 1000.0,
    "in": 25.4,
    "ft": 304.8,
    "yd": 914.4,
    "pt": 25.4 / 72.0,
    "pc": 25.4 / 6.0,
    "px": 25.4 / 96.0,
    "mil": 25.4e-3,
}

_ALIASES = {
    "µm": "um", "μm": "um", "micron": "um", "microns": "um",
    "millimeter": "mm", "millimeters": "mm", "millimetre": "mm", "millimetres": "mm",
    "centimeter": "cm", "centimeters": "cm", "centimetre": "cm", "centimetres": "cm",
    "meter": "m", "meters": "m", "metre": "m", "metres": "m",
    "inch": "in", "inches": "in", '"': "in",
    "foot": "ft", "feet": "ft", "yard": "yd", "yards": "yd",
    "point": "pt", "points": "pt", "pica": "pc", "picas": "pc",
    "pixel": "px", "pixels": "px", "mils": "mil", "thou": "mil",
}

_LENGTH = re.compile(r"\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*([^\d\s.+-][^\s]*)?\s*")


def _unit_name(unit: str) -> str | None:
    u = unit.strip()
    key = u.lower()
    if key in UNITS:
        return key
    return _ALIASES.get(key)


def unit_to_mm(unit: str, what: str = "unit") -> float:
    """Millimetres per ``unit`` (``"mm"``, ``"cm"``, ``"in"``, ``"px"``, ...).

    Raises
    ------
    InputError
        If the unit is not known; the message lists the known ones.
    """
    name = _unit_name(unit) if isinstance(unit, str) else None
    if name is None:
        raise InputError(f"unknown {what} {unit!r}: use one of {', '.join(UNITS)}")
    return UNITS[name]


def parse_length(text: str | float, default_unit: str | None = "mm", *,
                 what: str = "length") -> float:
    """A length in millimetres from text such as ``"5mm"``, ``"0.5 in"`` or ``"12"``.

    Parameters
    ----------
    text : str or float
        A number with an optional unit (see :data:`UNITS`); a plain number is
        in ``default_unit``.
    default_unit : str or None
        Unit of a plain number; None makes a unit mandatory.
    what : str
        What the length is, for error messages.

    Returns
    -------
    float
        The length in millimetres, finite and positive.

    Raises
    ------
    InputError
        Text that is not a number with a known unit, a missing unit when
        ``default_unit`` is None, or a length that is not positive and finite.
    """
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value, unit = float(text), None
    elif isinstance(text, str):
        m = _LENGTH.fullmatch(text)
        if m is None:
            raise InputError(f"invalid {what} {text!r}: expected a number with an optional unit, "
                             f"e.g. 5mm, 0.5cm or 0.25in")
        value, unit = float(m.group(1)), m.group(2)
    else:
        raise InputError(f"invalid {what} {text!r}: expected a number or text such as 5mm")
    if unit is None:
        if default_unit is None:
            raise InputError(f"{what} {text!r} needs a unit, e.g. {text}mm "
                             f"(known: {', '.join(UNITS)})")
        unit = default_unit
    mm = value * unit_to_mm(unit, what=f"unit in {what} {text!r}")
    if not math.isfinite(mm) or mm <= 0:
        raise InputError(f"invalid {what} {text!r}: it must be positive and finite")
    return mm


def format_length(mm: float) -> str:
    """``"12.5 mm"``: a length in millimetres for messages."""
    return f"{mm:.6g} mm"


#: Metres per length unit of the outputs and ``--units``, by name (any of :data:`UNITS` is accepted too).
LENGTH_UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048,
                                  "yd": 0.9144}


def length_scale(unit: str) -> float:
    """Metres per ``unit``: one of :data:`LENGTH_UNITS` (case-insensitive), or another unit
    of :data:`UNITS` (``px``, ``pt``, ``inch``, ``metres``, ...), so that ``--units`` means the
    same for boundary files and pattern files.

    Raises
    ------
    InputError
        For an unknown unit.
    """
    key = unit.strip().lower() if isinstance(unit, str) else None
    if key in LENGTH_UNITS:
        return LENGTH_UNITS[key]
    if key and _unit_name(key) is not None:
        return unit_to_mm(key) / 1000.0
    raise InputError(f"unknown length unit {unit!r}: use one of {', '.join(LENGTH_UNITS)}")


#: A pattern file whose largest piece is smaller or larger than this (mm, in the units the file
#: states) is most likely read in the wrong units: a CLO export that says "UNITS: METRIC" with
#: coordinates in centimetres reads as pieces of 15-73 mm; millimetres read as inches make a
#: 600 mm piece 15 m.
PLAUSIBLE_PIECE_MM = (100.0, 10_000.0)
#: ... and the size the warning's suggested unit brings it nearest to (mm)
TYPICAL_PIECE_MM = 600.0


def size_warning(size: float, read_in: str, what: str = "piece") -> str | None:
    """A line for the user where the largest ``what`` of a file, ``size`` mm across when read in the
    file's own units ``read_in``, is outside :data:`PLAUSIBLE_PIECE_MM`; None where it is plausible."""
    lo, hi = PLAUSIBLE_PIECE_MM
    if lo <= size <= hi:
        return None
    why = f"a garment {what} is rarely under {lo:g} mm" if size < lo else f"that is large for a garment {what}"
    hint = ""
    try:
        own = unit_to_mm(read_in)
    except Exception:                  # a unit the file names that we do not know: no suggestion
        own = None
    if own and size > 0:               # the unit that makes it the most typical size (TYPICAL_PIECE_MM)
        fits = [(abs(math.log(size * unit_to_mm(u) / own / TYPICAL_PIECE_MM)), u) for u in ("mm", "cm", "in", "m")
                if unit_to_mm(u) != own and lo <= size * unit_to_mm(u) / own <= hi]
        if fits:
            unit = min(fits)[1]
            hint = f" (--units {unit} would make it {size * unit_to_mm(unit) / own:.4g} mm)"
    return (f"the largest {what} is {size:.3g} mm across, read in the file's units ({read_in}): "
            f"{why}; if the file is in other units, give them with --units (mm, cm, in, ...){hint}")
