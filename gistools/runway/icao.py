"""ICAO Annex 14 aerodrome reference codes and the runway cross-section template (design spec section 2).

A template is a list of zones from the centre line outwards: (name, outer offset from the centre
line in m, cross slope falling away from the centre line as a fraction). Offsets are half-widths.

``icao`` (default): runway edge at half the runway width, shoulders to half the overall
runway + shoulders width, graded strip, strip half-width, with Annex 14's transverse slopes.
``dissertation``: the chapter's reading of the widths as offsets (runway 45, shoulders 52.5,
graded 75, strip 150 m) with the same slopes; it reproduces the dissertation's tables.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..errors import InputError

__all__ = ["Zone", "Template", "parse_code", "template", "VALID_CODES", "RUNWAY_TYPES", "TEMPLATES"]

RUNWAY_TYPES = ("precision", "non_precision", "non_instrument")
TEMPLATES = ("icao", "dissertation")
# runway width (m) by code number and letter, Annex 14 up to the 7th edition (None: no such runway)
_WIDTH = {
    1: {"A": 18, "B": 18, "C": 23},
    2: {"A": 23, "B": 23, "C": 30},
    3: {"A": 30, "B": 30, "C": 30, "D": 45},
    4: {"C": 45, "D": 45, "E": 45, "F": 60},
}
VALID_CODES = tuple(f"{n}{letter}" for n, row in _WIDTH.items() for letter in row)


@dataclass(frozen=True)
class Zone:
    name: str
    outer: float  # m from the centre line
    slope: float  # fraction, falling away from the centre line


@dataclass(frozen=True)
class Template:
    code: str
    runway_type: str
    kind: str
    zones: tuple[Zone, ...]

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return tuple(z.outer for z in self.zones)

    @property
    def half_width(self) -> float:
        return self.zones[-1].outer

    def drop(self, offset):
        """Height below the centre line at |offset| (m): the sum of slope x width over the zones crossed."""
        import numpy as np

        a = np.abs(np.asarray(offset, np.float64))
        out = np.zeros_like(a)
        inner = 0.0
        for z in self.zones:
            out += z.slope * np.clip(a - inner, 0.0, z.outer - inner)
            inner = z.outer
        # beyond the strip the last slope goes on
        out += self.zones[-1].slope * np.clip(a - inner, 0.0, None)
        return out


def parse_code(code: str) -> tuple[int, str]:
    """(code number, code letter) of an aerodrome reference code such as "4E"; InputError listing the valid ones."""
    m = re.fullmatch(r"\s*([1-4])\s*([A-Fa-f])\s*", str(code))
    if not m or f"{m.group(1)}{m.group(2).upper()}" not in VALID_CODES:
        raise InputError(f"aerodrome reference code {code!r} is not valid",
                         hint=f"Use one of {', '.join(VALID_CODES)} (code number 1-4 by field length, letter A-F by wingspan)")
    return int(m.group(1)), m.group(2).upper()


def template(code: str = "4E", runway_type: str = "precision", kind: str = "icao") -> Template:
    """The cross-section template of a reference code and runway type (see the module text)."""
    number, letter = parse_code(code)
    if runway_type not in RUNWAY_TYPES:
        raise InputError(f"runway type {runway_type!r} is not one of {', '.join(RUNWAY_TYPES)}")
    if kind not in TEMPLATES:
        raise InputError(f"template {kind!r} is not one of {', '.join(TEMPLATES)}")
    width = _WIDTH[number][letter]
    runway_slope = 0.015 if letter in "CDEF" else 0.02
    # strip half-width: instrument runways 150 m (code 3, 4) / 75 m (1, 2); non-instrument 75 / 40 / 30 m
    if runway_type == "non_instrument":
        strip = {1: 30.0, 2: 40.0, 3: 75.0, 4: 75.0}[number]
    else:
        strip = 150.0 if number >= 3 else 75.0
    graded = 75.0 if number >= 3 else 40.0
    graded_slope = 0.025 if number >= 3 else 0.03
    if kind == "dissertation":
        zones = (Zone("runway", 45.0, runway_slope), Zone("shoulder", 52.5, 0.025), Zone("graded", 75.0, graded_slope),
                 Zone("strip", 150.0, graded_slope))
        return Template(f"{number}{letter}", runway_type, kind, zones)
    zones = [Zone("runway", width / 2, runway_slope)]
    if letter in "DEF":  # shoulders: runway + shoulders >= 60 m (D, E), 75 m (F)
        overall = 75.0 if letter == "F" else 60.0
        if overall / 2 > width / 2:
            zones.append(Zone("shoulder", overall / 2, 0.025))
    inner = zones[-1].outer
    if graded > inner and graded < strip:
        zones.append(Zone("graded", graded, graded_slope))
    zones.append(Zone("strip", max(strip, zones[-1].outer), graded_slope))
    return Template(f"{number}{letter}", runway_type, kind, tuple(zones))
