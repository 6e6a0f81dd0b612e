"""The single exception tree of gistools.

Messages read "<file or parameter>: <problem>. <fix>." The path and the hint are
also kept as attributes so adapters (CLI, QGIS) never parse message text.
"""

__all__ = [
    "GistoolsError",
    "InputError",
    "CRSMismatchError",
    "EmptyTileError",
    "DataFileError",
    "MissingCRSError",
    "OutputExistsError",
    "OutputError",
    "OutputBusyError",
    "Cancelled",
]


class GistoolsError(Exception):
    """Root of every error gistools raises on purpose."""

    def __init__(self, message: str, *, path=None, hint: str | None = None):
        self.path = None if path is None else str(path)
        self.hint = hint
        text = message
        if self.path and not message.startswith(self.path):
            text = f"{self.path}: {message}"
        if hint:
            text = f"{text.rstrip('.')}. {hint}"
        super().__init__(text)


class InputError(GistoolsError, ValueError):
    """A parameter or an input's content is not acceptable."""


class CRSMismatchError(InputError):
    """Two inputs of one run are in different coordinate reference systems."""


class EmptyTileError(InputError):
    """A tile holds no usable points."""


class DataFileError(GistoolsError, OSError):
    """A file cannot be read: missing, truncated, not the expected format."""


class MissingCRSError(DataFileError):
    """A file carries no coordinate reference system."""


class OutputExistsError(GistoolsError, FileExistsError):
    """An output exists and overwriting was not asked for."""


class OutputError(GistoolsError, OSError):
    """An output cannot be written (disk full, read-only, not a folder): the run stops, it is not a tile's fault."""


class OutputBusyError(OutputError):
    """Another gistools run holds the output folder's lock."""


class Cancelled(GistoolsError):
    """The user asked the work to stop (progress callback returned False)."""
