"""The single exception tree of gistools.

Messages read "<file or parameter>: <problem>. <fix>." The path and the hint are
also kept as attributes so adapters (CLI, QGIS) never parse message text.
"""

__all__ = [
    "GistoolsError",
    "InputError",
    "ArgumentError",
    "CRSMismatchError",
    "EmptyTileError",
    "DataFileError",
    "MissingCRSError",
    "OutputExistsError",
    "OutOfMemoryError",
    "OutputError",
    "OutputBusyError",
    "Cancelled",
    "TilesFailed",
    "ClusterLostError",
    "raise_if_every_tile_failed",
]


class GistoolsError(Exception):
    """Root of every error gistools raises on purpose."""

    def __init__(self, message: str, *, path=None, hint: str | None = None):
        self.path = None if path is None else str(path)
        self._hint = hint
        text = message
        if self.path and not message.startswith(self.path):
            text = f"{self.path}: {message}"
        if hint:
            text = f"{text.rstrip('.')}. {hint}"
        super().__init__(text)

    @property
    def hint(self) -> str | None:
        from .parameters.core import render

        return None if self._hint is None else render(self._hint)

    def __str__(self) -> str:
        """The message with its parameters named as the reader speaks: ``overwrite=True`` to a Python caller,
        ``--overwrite`` on the command line, the dialog's label in QGIS (gistools.parameters.render)."""
        from .parameters.core import render

        return render(super().__str__())


class InputError(GistoolsError, ValueError):
    """A parameter or an input's content is not acceptable."""


class ArgumentError(InputError, TypeError):
    """A library call names an argument the function (or settings class) does not take; the message names the
    ones it takes."""


class CRSMismatchError(InputError):
    """Two inputs of one run are in different coordinate reference systems."""


class EmptyTileError(InputError):
    """A tile holds no usable points."""


class DataFileError(GistoolsError, OSError):
    """A file cannot be read: missing, truncated, not the expected format."""


class MissingCRSError(DataFileError):
    """A file carries no coordinate reference system."""


class OutOfMemoryError(GistoolsError, MemoryError):
    """The machine ran out of memory (or the system killed a worker): the run's problem, not a tile's."""


class OutputExistsError(GistoolsError, FileExistsError):
    """An output exists and overwriting was not asked for."""


class OutputError(GistoolsError, OSError):
    """An output cannot be written (disk full, read-only, not a folder): the run stops, it is not a tile's fault."""


class OutputBusyError(OutputError):
    """Another gistools run holds the output folder's lock."""


class ClusterLostError(GistoolsError, ConnectionError):
    """The Dask scheduler of a run went away in the middle of it: the run's problem, not a tile's; the tiles
    finished are kept and a rerun resumes."""


class Cancelled(GistoolsError):
    """The user asked the work to stop (progress callback returned False)."""


class TilesFailed(GistoolsError):
    """Every tile of a batch failed: the library call raises this rather than return a report of nothing made.

    ``report`` holds the run's report (also in the output folder's report.json), each tile with its error."""

    def __init__(self, report: dict, what: str = "tile"):
        self.report = report
        tiles = report.get("tiles", [])
        first = next((t.get("error") for t in tiles if t.get("status") == "failed"), None)
        super().__init__(f"every {what} failed ({len(tiles)}); the first: {first}",
                         hint="Each tile's error is in report.json")


def raise_if_every_tile_failed(report: dict) -> dict:
    """``report`` unchanged, unless it lists tiles and every one of them failed.

    Parameters
    ----------
    report : dict
        A run's report (as in its ``report.json``), with its ``"tiles"`` list.

    Returns
    -------
    dict
        ``report`` itself.

    Raises
    ------
    TilesFailed
        Every tile listed failed; its ``report`` attribute holds the report.

    Examples
    --------
    >>> raise_if_every_tile_failed({"tiles": [{"name": "a", "status": "ok"}, {"name": "b", "status": "failed"}]})["tiles"][0]
    {'name': 'a', 'status': 'ok'}
    """
    tiles = report.get("tiles", [])
    if tiles and all(t.get("status") == "failed" for t in tiles):
        raise TilesFailed(report)
    return report
