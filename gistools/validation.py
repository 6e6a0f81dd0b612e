"""One validation layer for the options of every command and Processing algorithm.

Pure checks (no I/O), run before any input is read or any output touched. Each raises
:class:`~gistools.errors.InputError` with one line naming the option, the value and the fix.
The settings dataclasses (RasterSettings, ShrubSettings, ...) call these in ``validate()``; the
CLI and the QGIS algorithms build those settings, so both get the same checks.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError
from .parameters.core import PARAMETERS, option
from .units import parse_length

__all__ = ["check_scheduler", "check_length", "check_number", "check_breaks", "check_count", "grid_shape", "check_grid_size",
           "MAX_GRID_CELLS", "check_geometry_types"]

# A tile's grids (DSM, counts, classes: about 40 bytes a cell in pass 1) must fit in memory: 400 M cells is
# 16 GB. A grid beyond this comes from a cell size far too small for the tile or from a header's bogus bounds.
MAX_GRID_CELLS = 400_000_000


def named(name: str, value=None) -> str:
    """A parameter as a message names it (:func:`gistools.parameters.option`): ``name`` is its Python name (or,
    still taken, its flag); other text (a value that is not a parameter) is used as it is."""
    key = name[2:].replace("-", "_") if name.startswith("--") else name
    if key in PARAMETERS:
        return option(key, value)
    return name if value is None else f"{name} {value}"


def check_length(value, name: str, *, minimum: float = 0.0, allow_equal: bool = False, example: str = "5ft"):
    """A length option ("25ft", "1.5m", 5): finite and > ``minimum`` (>= with ``allow_equal``); returns it unchanged."""
    number, _ = parse_length(value, name=named(name))
    ok = math.isfinite(number) and (number >= minimum if allow_equal else number > minimum)
    if not ok:
        bound = f"at least {minimum:g}" if allow_equal else ("positive" if minimum == 0 else f"more than {minimum:g}")
        raise InputError(f"{named(name)} {value!r} must be a finite length, {bound}", hint=f"Give e.g. {named(name, example)}")
    return value


def check_number(value, name: str, *, low=None, high=None, low_open: bool = False, example: str = "1"):
    """A plain number option within [low, high] (``low_open``: > low); returns it as float."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{named(name)} {value!r} is not a number", hint=f"Give e.g. {named(name, example)}") from None
    bad = not math.isfinite(v) or (low is not None and (v <= low if low_open else v < low)) or (high is not None and v > high)
    if bad:
        span = f"{'>' if low_open else '>='} {low:g}" if low is not None else ""
        span += (" and " if span and high is not None else "") + (f"<= {high:g}" if high is not None else "")
        raise InputError(f"{named(name)} {value!r} must be a finite number {span}".rstrip(), hint=f"Give e.g. {named(name, example)}")
    return v


def check_count(value, name: str, *, minimum: int = 1, example: str = "1") -> int:
    """An integer option of at least ``minimum``."""
    if isinstance(value, bool) or not float(value).is_integer() or int(value) < minimum:
        raise InputError(f"{named(name)} {value!r} must be an integer of at least {minimum}", hint=f"Give e.g. {named(name, example)}")
    return int(value)


def check_jobs(value) -> int | str:
    """``jobs``: "auto" (gistools chooses, see gistools.engine.batch.auto_workers) or a whole number of at least 1."""
    if isinstance(value, str) and value.strip().lower() == "auto":
        return "auto"
    try:
        float(value)
    except (TypeError, ValueError):
        raise InputError(f"{named('jobs')} {value!r} is neither auto nor a whole number",
                         hint=f"Give e.g. {named('jobs', 'auto')} or {named('jobs', 2)}") from None
    return check_count(value, "jobs", example="2")


def check_breaks(values, name: str, *, count: int, low: float, high: float, low_open: bool = False,
                 example: str = "0.3,0.7") -> tuple[float, ...]:
    """``count`` strictly increasing finite numbers within [low, high] (``low_open``: above low)."""
    try:
        v = tuple(float(x) for x in values)
    except (TypeError, ValueError):
        raise InputError(f"{named(name)} {values!r} is not a list of numbers", hint=f"Give e.g. {named(name, example)}") from None
    shown = ",".join(f"{x:g}" for x in v)
    if len(v) != count:
        raise InputError(f"{named(name)} {shown}: needs {count} values, got {len(v)}", hint=f"Give e.g. {named(name, example)}")
    if not all(math.isfinite(x) for x in v) or any(b <= a for a, b in zip(v, v[1:])):
        raise InputError(f"{named(name)} {shown}: the values must be finite and increasing", hint=f"Give e.g. {named(name, example)}")
    if (v[0] <= low if low_open else v[0] < low) or v[-1] > high:
        raise InputError(f"{named(name)} {shown}: the values must lie {'above' if low_open else 'within'} "
                         f"{low:g}{' and up to' if low_open else ' -'} {high:g}", hint=f"Give e.g. {named(name, example)}")
    return v


def grid_shape(bounds, cell_size: float) -> tuple[int, int]:
    """(columns, rows) of the snapped grid covering ``bounds`` at ``cell_size`` (no allocation; may be huge)."""
    w, s, e, n = bounds
    cols = math.floor(e / cell_size) - math.floor(w / cell_size) + 1
    rows = math.floor(n / cell_size) - math.floor(s / cell_size) + 1
    return int(cols), int(rows)


def _cells_held(max_cells: int | None, bytes_per_cell: int) -> tuple[int, float | None]:
    """(the cells a tile's grid may have, the process's available memory in bytes where that sets the limit)."""
    from .machine import available_memory

    if max_cells is not None:
        return max_cells, None
    memory = available_memory()
    if memory is not None and int(0.8 * memory // bytes_per_cell) < MAX_GRID_CELLS:
        return int(0.8 * memory // bytes_per_cell), memory
    return MAX_GRID_CELLS, None


def check_grid_size(bounds, cell_size: float, what: str, *, unit: str = "", max_cells: int | None = None,
                    bytes_per_cell: int = 40, cell_option: str = "cell_size") -> tuple[int, int]:
    """Refuse a grid of more than ``max_cells`` cells (default: :data:`MAX_GRID_CELLS`, or fewer where this
    process's memory holds fewer at ``bytes_per_cell``) before anything is allocated, with the numbers
    (``cell_option``: the option that sets the cell size, named in the message)."""
    if not all(math.isfinite(b) for b in bounds) or not math.isfinite(cell_size) or cell_size <= 0:
        raise InputError(f"{what}: bounds {bounds} at cell size {cell_size!r} give no grid",
                         hint=f"Check the header's bounds and {option(cell_option)}")
    cols, rows = grid_shape(bounds, cell_size)
    held, memory = _cells_held(max_cells, bytes_per_cell)
    if cols * rows > held:
        w, s, e, n = bounds
        limit = (f"more than this process's {memory / 1e9:.1f} GB of available memory holds ({held:,} cells)"
                 if memory else f"more than the {held:,} cells a tile may have")
        raise InputError(
            f"{what}: {e - w:.6g} x {n - s:.6g} {unit} at cell size {cell_size:g} {unit} is a grid of "
            f"{cols:,} x {rows:,} cells (about {cols * rows * bytes_per_cell / 1e9:,.1f} GB), {limit}",
            hint=f"Give a larger {option(cell_option)}" + (", run on a machine with more memory" if memory else "")
            + ", or check the tile's header bounds (lasinfo)")
    return cols, rows


_GEOMETRY_FAMILY = {"Point": "point", "MultiPoint": "point", "LineString": "line", "MultiLineString": "line",
                    "LinearRing": "line", "Polygon": "polygon", "MultiPolygon": "polygon"}


def check_geometry_types(types, allowed: tuple[str, ...], what: str, path: str) -> None:
    """Refuse a layer whose geometries are not of the ``allowed`` families (point, line, polygon)."""
    names = [t for t in np.unique(np.asarray(list(types), dtype=object).astype(str)) if t not in ("None", "nan")]
    bad = sorted({t for t in names if _GEOMETRY_FAMILY.get(t) not in allowed})
    if bad:
        hint = f"Give the {what} layer (e.g. file.gpkg:LAYER) of {' or '.join(allowed)} features"
        if allowed == ("line",) and any(_GEOMETRY_FAMILY.get(t) == "polygon" for t in bad):
            hint += (" (outlines as polygons: convert them with QGIS's Polygons to Lines; water polygons go to "
                     f"{option('waterbodies')})")
        raise InputError(
            f"{what} must hold {' or '.join(a + 's' for a in allowed)}, but the layer holds {', '.join(bad)}",
            path=path, hint=hint)


def check_scheduler(address) -> None:
    """A Dask scheduler address: "local", host:port, or scheme://host:port (tcp, tls, ucx, ws, wss)."""
    if address is None or address == "local":
        return
    text = str(address)
    scheme, sep, rest = text.partition("://")
    if not sep:  # host:port, which Dask reads as tcp://host:port
        scheme, rest = "tcp", text
    host, _, port = rest.rpartition(":")
    if scheme in ("inproc",):  # a scheduler inside this process cannot run tiles in other processes
        raise InputError(f"{option('scheduler')} {text!r}: an in-process address cannot reach workers",
                         hint=f"Give e.g. {option('scheduler', 'tcp://127.0.0.1:8786')}, or {option('scheduler', 'local')}")
    if scheme not in ("tcp", "tls", "ucx", "ws", "wss") or not rest or not (host and port.isdigit()):
        raise InputError(f"{option('scheduler')} {text!r} is not a Dask scheduler address",
                         hint=f"Give e.g. {option('scheduler', 'tcp://127.0.0.1:8786')}, or {option('scheduler', 'local')}")
