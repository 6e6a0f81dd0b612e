"""The docstring sections that many library functions share, written once.

A docstring names a section by a line holding only ``{name}``; ``shared_sections`` puts the section there, indented
as that line. ``help()`` and the reference pages (mkdocstrings inspects the imported functions) show the whole text.
"""

from __future__ import annotations

import textwrap

_TILES_RAISE_REST = """\
CRSMismatchError
    The tiles are not all in one CRS.
TilesFailed
    Every tile failed.
Cancelled
    ``progress`` returned False."""

SECTIONS = {
    # the tiles a command reads and the folder it writes (Parameters)
    "tiles_in": """\
inputs : str, path or list
    LAS / LAZ files, folders (their tiles), glob patterns or a ``.vpc``.
out : str or path
    Output folder, made when missing.""",
    # how a command of tiles runs (Parameters)
    "tiles_run": """\
jobs : int or "auto"
    Tiles processed at once, each in a local process; "auto" (the default): in this process until the tiles'
    points repay starting workers (``gistools.engine.batch.auto_workers``).
scheduler : str, optional
    A dask.distributed scheduler address (``"tcp://host:8786"``), or ``"local"`` for a local cluster of ``jobs``
    workers, to run the tiles on instead; the workers must see the tiles and ``out`` at the same paths.
overwrite : bool
    Remake tiles whose outputs exist (without it a rerun keeps them: it resumes).
progress : callable, optional
    ``progress(fraction, message)``; returning False cancels the run.""",
    # how a command of tiles fails (the Raises section)
    "tiles_raise": "Raises\n------\nInputError\n    An option is not valid, or ``inputs`` holds no tile.\n" + _TILES_RAISE_REST,
    # the same after the command's own InputError
    "tiles_raise_rest": _TILES_RAISE_REST,
    # the breaklines of the shrub chain (Parameters)
    "breaklines_in": """\
roads : str, optional
    Edge-of-pavement lines, a path or ``file.gpkg:LAYER``.
hydro : str, optional
    Water lines (streams, canals), likewise.
waterbodies : str, optional
    Water polygons, likewise.""",
    # how a deliverable of a chain's folder fails (the Raises section)
    "deliverable_raise": """\
Raises
------
InputError
    An option is not valid, or ``out`` is not a folder.
OutputExistsError
    A file gistools did not write is in the way.""",
    # how a step of a raster runs (Parameters)
    "raster_run": """\
overwrite : bool
    Replace outputs that exist.
block : int
    Rows and columns computed at a time (bounds memory).
progress : callable, optional
    ``progress(fraction, message)``; returning False cancels.""",
    # how a product of a raster fails, after its own InputError and DataFileError (Raises)
    "raster_raise_rest": """\
OutputExistsError
    An output is there from a run with other settings, and ``overwrite`` is False; or ``out`` holds another
    command's outputs.
OutputError
    ``out`` cannot be made, or another run is writing in it.
Cancelled
    ``progress`` returned False.""",
    # a product of a DEM read window by window (Parameters)
    "dem_run": """\
overwrite : bool
    Replace existing outputs. Without it, the outputs of an earlier run with the same settings on the same DEM
    are kept (listed in ``kept``), and an output of other settings is refused.
block : int
    Cells a side of the windows read at once (0: the whole raster).
progress : callable, optional
    ``progress(fraction, message)``, told after each window; returning False cancels the run.""",
}


def shared_sections(function):
    """Decorator: ``function``'s docstring with each ``{name}`` line of ``SECTIONS`` replaced by the section."""
    lines = []
    for line in (function.__doc__ or "").split("\n"):
        name = line.strip()
        if name.startswith("{") and name.endswith("}") and name[1:-1] in SECTIONS:
            indent = line[: len(line) - len(line.lstrip())]
            lines.extend(textwrap.indent(SECTIONS[name[1:-1]], indent).split("\n"))
        else:
            lines.append(line)
    function.__doc__ = "\n".join(lines)
    return function
