"""Linear units of a CRS and lengths given with their unit ("5ft", "1.5m").

Factors are metres per unit. "ft" means the CRS's own foot when the CRS is in
feet (international or US survey), so "5ft" is exactly 5 map units on a ftUS
CRS; on a metre CRS "ft" is the international foot (0.3048 m). "ftUS"/"usft"
is always the US survey foot (1200/3937 m).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the CRS is read by the caller: the command line starts without PROJ
    import pyproj

from .errors import InputError
from .parameters.core import option

__all__ = [
    "METRE",
    "FOOT",
    "US_SURVEY_FOOT",
    "LinearUnit",
    "horizontal_unit",
    "vertical_unit",
    "parse_length",
    "length_to_crs_units",
    "unit_from_word",
]

METRE = 1.0
FOOT = 0.3048
US_SURVEY_FOOT = 1200.0 / 3937.0


@dataclass(frozen=True)
class LinearUnit:
    """A linear unit: its name (as PROJ spells it) and metres per unit."""

    name: str
    metres: float

    @property
    def is_foot(self) -> bool:
        return abs(self.metres - FOOT) < 1e-6 or abs(self.metres - US_SURVEY_FOOT) < 1e-6

    @property
    def short(self) -> str:
        if abs(self.metres - US_SURVEY_FOOT) < 1e-9:
            return "ftUS"
        if abs(self.metres - FOOT) < 1e-9:
            return "ft"
        if abs(self.metres - 1.0) < 1e-12:
            return "m"
        return self.name


def _axis_unit(axes) -> LinearUnit | None:
    for axis in axes:
        if axis.unit_conversion_factor and axis.unit_name not in ("degree", "radian", "grad"):
            return LinearUnit(axis.unit_name, float(axis.unit_conversion_factor))
    return None


def horizontal_unit(crs: pyproj.CRS) -> LinearUnit:
    """Linear unit of a projected CRS's x and y axes.

    Raises InputError for a geographic CRS (degrees cannot be gridded).
    """
    horizontal = crs.sub_crs_list[0] if crs.is_compound else crs
    if horizontal.is_geographic:
        raise InputError(
            f"CRS {horizontal.name!r} is geographic (degrees)",
            hint="Reproject the tiles to a projected CRS (e.g. with PDAL or las2las) first",
        )
    unit = _axis_unit(horizontal.axis_info)
    if unit is None:
        raise InputError(f"CRS {horizontal.name!r} has no linear unit", hint=f"Give a projected CRS with {option('crs')}")
    return unit


def vertical_unit(crs: pyproj.CRS) -> LinearUnit:
    """Linear unit of z: the vertical CRS's unit for a compound CRS, else the horizontal unit.

    LAS files without a vertical CRS store z in the horizontal unit by convention
    (ASPRS LAS spec); that is the reading taken here.
    """
    if crs.is_compound and len(crs.sub_crs_list) > 1:
        unit = _axis_unit(crs.sub_crs_list[1].axis_info)
        if unit is not None:
            return unit
    return horizontal_unit(crs)


_LENGTH = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z_ ]*)\s*$")
_UNIT_WORDS = {
    "": None,
    "m": METRE,
    "metre": METRE,
    "metres": METRE,
    "meter": METRE,
    "meters": METRE,
    "ft": "foot",
    "foot": "foot",
    "feet": "foot",
    "ftus": US_SURVEY_FOOT,
    "usft": US_SURVEY_FOOT,
    "us_ft": US_SURVEY_FOOT,
    "us-ft": US_SURVEY_FOOT,
    "survey_ft": US_SURVEY_FOOT,
    "ftintl": FOOT,
    "intl_ft": FOOT,
}


def parse_length(text: str | float, *, name: str = "length") -> tuple[float, str | float | None]:
    """Split "5ft" into (5.0, unit) where unit is metres-per-unit, "foot", or None (map units)."""
    if isinstance(text, (int, float)):
        if not math.isfinite(text):
            raise InputError(f"{name} {text!r} must be a finite length", hint="Give a number, e.g. 5")
        return float(text), None
    match = _LENGTH.match(str(text))
    if not match:
        raise InputError(f"{name} {text!r} is not a length", hint="Write a number with an optional unit, e.g. 5ft, 1.5m or 5")
    value, word = float(match.group(1)), match.group(2).strip().lower().replace(" ", "")
    if not math.isfinite(value):  # nan, inf, or a number past a double's range (1e400)
        raise InputError(f"{name} {text!r} must be a finite length", hint="Write a number with an optional unit, e.g. 5ft, 1.5m or 5")
    if word not in _UNIT_WORDS:
        raise InputError(
            f"{name} {text!r}: unknown unit {match.group(2)!r}", hint="Use m, ft (the CRS's foot), ftUS or a bare number in map units"
        )
    return value, _UNIT_WORDS[word]


def length_to_crs_units(text: str | float, unit: LinearUnit, *, name: str = "length") -> float:
    """A length given with its unit ("5ft", "1.5m", 5) in the units of ``unit``.

    >>> from gistools.units import LinearUnit, US_SURVEY_FOOT
    >>> length_to_crs_units("5ft", LinearUnit("US survey foot", US_SURVEY_FOOT))
    5.0
    >>> round(length_to_crs_units("1m", LinearUnit("foot", 0.3048)), 6)
    3.28084
    """
    value, word = parse_length(text, name=name)
    if word is None:
        return value
    if word == "foot":
        metres = unit.metres if unit.is_foot else FOOT
    else:
        metres = float(word)
    if abs(metres - unit.metres) < 1e-12:
        return value
    return value * metres / unit.metres


def unit_from_word(word: str, *, name: str = "unit") -> LinearUnit:
    """The LinearUnit of a unit word as rasters and users write it ("m", "ft", "ftUS", "US survey foot").

    "ft" alone is the international foot here (a raster's unit string has no CRS to lean on).

    >>> unit_from_word("ftUS").short
    'ftUS'
    """
    text = str(word).strip()
    if text in ("US survey foot", "US survey feet"):
        return LinearUnit("US survey foot", US_SURVEY_FOOT)
    key = text.lower().replace(" ", "")
    metres = _UNIT_WORDS.get(key, False)
    if metres is False or metres is None:
        raise InputError(f"{name} {word!r} is not a known linear unit", hint="Use m, ft or ftUS")
    if metres == "foot" or abs(float(metres) - FOOT) < 1e-12:
        return LinearUnit("foot", FOOT)
    if abs(float(metres) - US_SURVEY_FOOT) < 1e-12:
        return LinearUnit("US survey foot", US_SURVEY_FOOT)
    return LinearUnit("metre", METRE)


_SIZE = {"": 1, "b": 1, "kb": 1e3, "mb": 1e6, "gb": 1e9, "tb": 1e12, "kib": 2**10, "mib": 2**20, "gib": 2**30,
         "tib": 2**40}


def parse_size(text: str | float, *, name: str = "size") -> float:
    """A number of bytes from "500MB", "2GB", "1.5GiB" or a bare number of bytes.

    >>> parse_size("2GB")
    2000000000.0
    >>> parse_size("1KiB")
    1024.0
    """
    if isinstance(text, (int, float)):
        value, word = float(text), ""
    else:
        match = re.fullmatch(r"\s*([0-9.eE+-]+)\s*([A-Za-z]*)\s*", str(text))
        try:
            value, word = float(match.group(1)), match.group(2).lower()
        except (AttributeError, ValueError):
            value, word = math.nan, ""
    if word not in _SIZE or not math.isfinite(value) or value <= 0:
        raise InputError(f"{name} {text!r} is not a size", hint="Write a positive number with a unit, e.g. 500MB or 2GB")
    return value * _SIZE[word]
