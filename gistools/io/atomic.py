"""Atomic, checked writes, and the names of the partial files gistools owns.

Every output is written to a hidden partial file beside its final name,
``.<name>.gistools-<pid>-<token>.partial`` (a name no user chooses), checked, and
renamed onto the final name only once the write and the close succeeded and the
check passed. A failed write (disk full, read-only file system, a GDAL write
error that GDAL only logged) raises :class:`~gistools.errors.OutputError`, which
names the folder's disk and the fix, and the partial file is removed.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import re
import secrets
import shutil
from pathlib import Path

from ..errors import GistoolsError, OutputError, OutputExistsError
from ..parameters import option

__all__ = ["atomic_path", "partial_name", "is_partial", "output_error", "raise_output_error", "check_nonempty",
           "disk_is_full", "no_space_error"]

_PARTIAL = re.compile(r"^\..+\.gistools-\d+-[0-9a-f]{8}\.partial(\.[A-Za-z0-9]+)?$")
_TOKEN = secrets.token_hex(4)  # per process; the pid tells processes apart

# errors that say the output side failed, not the input: the run stops with one line about the disk
_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}
_DISK_TEXT = re.compile(r"No space left|requested and \d+ written|Disk quota|File too large|database or disk is full",
                        re.IGNORECASE)
_FOLDER_ERRNOS = {errno.EROFS: "is on a read-only file system", errno.EACCES: "is not writable (permission denied)",
                  errno.EPERM: "is not writable (permission denied)", errno.ENOTDIR: "is under a file, not a folder"}


NAME_MAX = 255  # bytes of a file name on the file systems of Linux, macOS and Windows


def partial_name(path, keep_suffix: bool = False) -> Path:
    """The partial file for ``path``: hidden, in the same folder, owned by this process.
    ``keep_suffix``: end in the final suffix too (laspy picks LAZ, GDAL the GeoPackage driver, by it)."""
    path = Path(path)
    tail = f".gistools-{os.getpid()}-{_TOKEN}.partial" + (path.suffix if keep_suffix else "")
    stem = path.name
    room = NAME_MAX - 1 - len(tail.encode())  # a legal 240-character tile name still gets a legal partial name
    if len(stem.encode()) > room:
        digest = hashlib.sha1(stem.encode()).hexdigest()[:10]
        stem = stem.encode()[:max(room - 11, 1)].decode("utf-8", "ignore") + "~" + digest
    return path.with_name(f".{stem}{tail}")


def is_partial(path) -> bool:
    """True for a partial file named by :func:`partial_name` (of any gistools process)."""
    return bool(_PARTIAL.match(Path(path).name))


def _existing_parent(path: Path) -> Path:
    p = Path(os.path.abspath(path))
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _mount_point(path: Path) -> Path:
    p = _existing_parent(path)
    while not os.path.ismount(p) and p != p.parent:
        p = p.parent
    return p


def output_error(err: BaseException, path) -> OutputError | None:
    """The one-line OutputError for a write failure of ``path`` caused by the disk or the folder, else None."""
    if isinstance(err, OutputError):
        return err
    if isinstance(err, GistoolsError):
        return None
    code = getattr(err, "errno", None)
    text = str(err)
    named = getattr(err, "filename", None)
    path = final_name(named) if named else path
    if code in _DISK_ERRNOS or _DISK_TEXT.search(text):
        return no_space_error(path)
    if code in _FOLDER_ERRNOS:
        return OutputError(f"{path} cannot be written: {_existing_parent(Path(path).parent)} {_FOLDER_ERRNOS[code]}",
                           hint=f"Choose another {option('out')} (a writable folder)")
    return None


def disk_is_full(path, margin: float = 1e6) -> bool:
    """True when the disk of ``path`` has less than ``margin`` bytes free (why a write just failed)."""
    try:
        return shutil.disk_usage(_existing_parent(Path(path))).free < margin
    except OSError:
        return False


def no_space_error(path) -> OutputError:
    """The one line for a full disk under ``path``."""
    where = _existing_parent(Path(path))
    try:
        free = shutil.disk_usage(where).free / 1e6
    except OSError:
        free = 0.0
    return OutputError(f"no space left on {_mount_point(where)} (writing {path}; {free:.1f} MB free)",
                       hint=f"Free some space or choose another {option('out')}; complete outputs are kept and a rerun resumes")


def raise_output_error(err: BaseException, path) -> None:
    """Raise output_error(err, path) from None when there is one (else return: the caller re-raises ``err``)."""
    out = output_error(err, path)
    if out is not None:
        raise out from None


def final_name(tmp) -> Path:
    """The final path of a partial file (itself for any other path)."""
    tmp = Path(tmp)
    if not is_partial(tmp):
        return tmp
    return tmp.with_name(tmp.name[1:].split(".gistools-")[0])


def unreadable_output(tmp, what: str, err=None) -> OutputError:
    """The error for a file that was written without an error but does not read back: a full disk when it is."""
    if disk_is_full(tmp):
        return no_space_error(final_name(tmp))
    reason = f" ({err})" if err else ""
    return OutputError(f"{final_name(tmp)}: the {what} just written does not read back{reason}",
                       hint=f"Check the disk of {option('out')} (full, failing?) and run again")


def check_nonempty(tmp: Path) -> None:
    """The minimal check of any written file: it exists and is not empty."""
    if not tmp.is_file() or tmp.stat().st_size == 0:
        raise unreadable_output(tmp, "file", "it is empty")


# Windows refuses to replace a file another program holds open (QGIS holds every raster of its project open):
# the rename is tried again for a while, then refused naming the file and the program that may hold it
REPLACE_TRIES = (0.05, 0.1, 0.2, 0.4, 0.8, 1.6)


class HeldOpenError(OutputError):
    """An output cannot be replaced because another program holds it open (Windows)."""


def replace(tmp, path, *, tries=REPLACE_TRIES, windows: bool | None = None) -> None:
    """``os.replace(tmp, path)``; where the system refuses because ``path`` is open elsewhere (Windows:
    PermissionError), tried again after each pause of ``tries`` (seconds), then a HeldOpenError naming the file."""
    import time

    windows = os.name == "nt" if windows is None else windows
    for pause in (*tries, None):
        try:
            os.replace(tmp, path)
            return
        except PermissionError as err:
            if not windows or not Path(path).exists():
                raise
            if pause is None:
                raise HeldOpenError(f"{path} cannot be replaced: another program holds it open ({err.strerror or err})",
                                    hint="Close it there (in QGIS: remove the layer from the project), then run "
                                         "again; complete outputs are kept and a rerun resumes") from None
            time.sleep(pause)


@contextlib.contextmanager
def atomic_path(path, *, overwrite: bool = False, keep_suffix: bool = False, verify=check_nonempty):
    """Yield a partial path beside ``path``; after the block, ``verify(partial)`` and rename it onto ``path``.

    On any error (in the block or in ``verify``) the partial file is removed and nothing is renamed; a write
    failure of the disk or the folder becomes an OutputError naming the disk and the fix.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise OutputExistsError("output exists", path=path,
                                hint=f"Pass {option('overwrite')} to replace it, or choose another {option('out')}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise_output_error(err, path)
        raise
    tmp = partial_name(path, keep_suffix)
    try:
        yield tmp
        if verify is not None:
            verify(tmp)
        replace(tmp, path)
    except Exception as err:
        raise_output_error(err, path)
        if not isinstance(err, GistoolsError) and disk_is_full(path):  # a writer's own words for a full disk
            raise no_space_error(path) from None
        raise
    finally:
        with contextlib.suppress(OSError):
            if tmp.exists():
                tmp.unlink()
