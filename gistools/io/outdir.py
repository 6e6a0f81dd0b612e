"""The output folder of a run: created and checked before any work, locked, cleared of this program's leftovers.

A run holds ``OUT/.gistools.lock`` (process id, host, start time) while it writes; a
second run into the same folder is refused with one line. A lock whose process is
gone (same host, that pid no longer running the same process) is stale and taken
over. Leftovers of a killed run are removed only when this program made them:
partial files named by :func:`gistools.io.atomic.partial_name`, and scratch folders
``.gistools-scratch-*``, in the output folder and its product folders, nowhere else.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import socket
import sys
import threading
import time
from pathlib import Path

from ..errors import OutputBusyError, OutputError, OutputExistsError
from ..parameters import option
from .atomic import is_partial, raise_output_error

__all__ = ["claim_output", "output_folder", "check_record", "is_our_record", "LOCK_NAME", "remove_leftovers"]

log = logging.getLogger(__name__)

LOCK_NAME = ".gistools.lock"
SCRATCH_PREFIX = ".gistools-scratch-"
# the folders under --out that gistools writes (one per raster product, the tile reports, band points)
OUTPUT_FOLDERS = ("dsm", "dem", "ndsm", "topclass", "bands", "veg", "wetveg", "density", "cover", "classes",
                  "band_points", "tile_reports", "classified")
_HELD: dict[str, int] = {}  # output folders this process holds, with a nesting count (shrub runs rasters inside)
_HELD_LOCK = threading.Lock()


PROC = Path("/proc")  # Linux's process table; absent on Windows and macOS (and in some containers)


def _psutil():
    """psutil where installed (not a dependency: the platform's own calls are used without it), else None."""
    try:
        import psutil
    except ImportError:
        return None
    return psutil


def _process_start(pid: int) -> str | None:
    """Start time of process ``pid``, to tell a reused pid apart: Linux /proc clock ticks since boot, else psutil's
    creation time (``t<seconds>``); None where neither is available (the pid alone then decides)."""
    if (PROC / "self" / "stat").exists():
        try:
            text = (PROC / str(pid) / "stat").read_text(encoding="utf-8")
            return text.rsplit(")", 1)[1].split()[19]
        except (OSError, IndexError):
            return None
    psutil = _psutil()
    if psutil is None:
        return _start_without_proc(pid)
    try:
        return f"t{psutil.Process(pid).create_time():.3f}"
    except (psutil.Error, OSError, ValueError):
        return None


def _start_without_proc(pid: int) -> str | None:
    """A process's start time where there is neither /proc nor psutil: Windows' GetProcessTimes (``w<100 ns ticks>``),
    elsewhere (macOS, the BSDs) what ``ps -o lstart=`` prints (``p<text>``); None where neither answers."""
    if sys.platform == "win32":  # pragma: no cover - Windows
        return _start_windows(pid)
    import subprocess

    try:
        run = subprocess.run(["ps", "-o", "lstart=", "-p", str(int(pid))], capture_output=True, text=True, timeout=10,
                             env={**os.environ, "LC_ALL": "C"})
    except (OSError, subprocess.SubprocessError):
        return None
    text = " ".join(run.stdout.split())
    return f"p{text}" if run.returncode == 0 and text else None


def _start_windows(pid: int) -> str | None:  # pragma: no cover - Windows
    import ctypes
    from ctypes import wintypes

    kernel32 = ctypes.windll.kernel32
    handle = kernel32.OpenProcess(0x1000, False, pid)  # PROCESS_QUERY_LIMITED_INFORMATION
    if not handle:
        return None
    try:
        times = [wintypes.FILETIME() for _ in range(4)]
        if not kernel32.GetProcessTimes(handle, *[ctypes.byref(t) for t in times]):
            return None
        return f"w{(times[0].dwHighDateTime << 32) | times[0].dwLowDateTime}"
    finally:
        kernel32.CloseHandle(handle)


def _alive(pid: int, start: str | None) -> bool:
    """Whether the process ``pid`` that took a lock (started at ``start``, where known) still runs."""
    if pid <= 0:
        return False
    if not _pid_exists(pid):
        return False
    now = _process_start(pid)
    if start is None or now is None or _clock(str(start)) != _clock(now):  # unknown, or another clock
        return True
    return now == str(start)


def _clock(stamp: str) -> str:
    """Which clock a start time was read from: /proc's ticks (digits), psutil's (t), ps's (p), Windows' (w)."""
    return "proc" if stamp[:1].isdigit() else stamp[:1]


def _pid_exists(pid: int) -> bool:
    psutil = _psutil()
    if psutil is not None:
        return psutil.pid_exists(pid)
    if sys.platform == "win32":  # os.kill(pid, 0) would terminate the process there
        return _alive_windows(pid)
    try:
        os.kill(pid, 0)  # POSIX: signal 0 only asks whether the process exists
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OSError:
        return False
    return True


def _alive_windows(pid: int) -> bool:  # pragma: no cover - Windows
    """Windows: the process can be opened and has not exited (STILL_ACTIVE)."""
    import ctypes

    kernel32 = ctypes.windll.kernel32
    handle = kernel32.OpenProcess(0x1000, False, pid)  # PROCESS_QUERY_LIMITED_INFORMATION
    if not handle:
        return ctypes.GetLastError() == 5  # access denied: it exists, another user's
    try:
        code = ctypes.c_ulong()
        return bool(kernel32.GetExitCodeProcess(handle, ctypes.byref(code))) and code.value == 259
    finally:
        kernel32.CloseHandle(handle)


def _make_folder(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise OutputError(f"{option('out')} {out} is a file, not a folder", hint=f"Choose a folder for {option('out')}")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise_output_error(err, out)
        raise OutputError(f"{option('out')} {out} cannot be created ({err.strerror or err})",
                          hint=f"Choose another {option('out')}") from None


def _take_lock(out: Path, command: str) -> Path:
    lock = out / LOCK_NAME
    me = {"pid": os.getpid(), "host": socket.gethostname(), "start": _process_start(os.getpid()),
          "command": command, "since": time.strftime("%Y-%m-%d %H:%M:%S")}
    for _ in range(3):
        if lock.is_dir() and not lock.is_symlink():  # not gistools' lock: someone's folder of that name
            raise OutputError(f"{lock} is a folder, where gistools keeps its lock file",
                              hint=f"Rename or move that folder, or choose another {option('out')}")
        try:
            fd = os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            holder = _read_lock(lock)
            if holder is not None and _holder_alive(holder):
                raise OutputBusyError(
                    f"{out} is in use by another gistools run ({holder.get('command', 'gistools')}, process "
                    f"{holder.get('pid')} on {holder.get('host')} since {holder.get('since')})",
                    hint=f"Wait for it to end or choose another {option('out')}; if that run is gone, delete {lock}")
            log.warning("%s: taking over the lock of a run that is gone (%s)", out, holder)
            with contextlib.suppress(FileNotFoundError):
                lock.unlink()
            continue
        except OSError as err:
            raise_output_error(err, lock)
            raise
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(json.dumps(me))
        except OSError as err:
            with contextlib.suppress(OSError):
                lock.unlink()
            raise_output_error(err, lock)
            raise
        return lock
    raise OutputBusyError(f"{out}: the lock {lock} keeps changing hands", hint=f"Choose another {option('out')}")


def _read_lock(lock: Path) -> dict | None:
    try:
        return json.loads(lock.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return {}
    except (OSError, ValueError, RecursionError):  # empty or half-written: its writer died at once, or is writing it now
        try:
            young = time.time() - lock.stat().st_mtime < 10
        except OSError:
            young = False
        return {"pid": "?", "host": "?", "since": "just now"} if young else None


def _holder_alive(holder: dict) -> bool:
    if not holder:
        return False
    if holder.get("pid") == "?":
        return True
    if holder.get("host") != socket.gethostname():
        return True  # another machine's run (shared storage): cannot be checked from here, so it is respected
    try:
        return _alive(int(holder["pid"]), holder.get("start"))
    except (KeyError, TypeError, ValueError):
        return False


def remove_leftovers(out: Path) -> None:
    """Remove this program's leftovers of a killed run: partial files and scratch folders, in ``out`` and the
    folders of OUTPUT_FOLDERS (where gistools writes); a file a user named, or any file elsewhere, is never touched."""
    if not out.is_dir():
        return
    for entry in list(out.iterdir()):
        if entry.name.startswith(SCRATCH_PREFIX) and entry.is_dir() and not entry.is_symlink():
            if entry.name.startswith(ROLLBACK_PREFIX):  # a step rerun killed midway: the folder as it was
                _restore_left(out, entry)
            log.info("removing %s, left by an interrupted run", entry)
            shutil.rmtree(entry, ignore_errors=True)
    folders = [out] + [out / d for d in OUTPUT_FOLDERS if (out / d).is_dir() and not (out / d).is_symlink()]
    for folder in folders:
        try:
            entries = list(folder.iterdir())
        except OSError:
            continue
        for entry in entries:
            if is_partial(entry) and entry.is_file():
                log.info("removing %s, left by an interrupted run", entry)
                with contextlib.suppress(OSError):
                    entry.unlink()


def abandon() -> None:
    """The run is ending at once (the command line's stop watchdog): every step rerun of this process put back,
    its folders' partial files and scratch removed, their locks released."""
    for rollback in list(_ROLLBACKS):
        with contextlib.suppress(Exception):
            rollback.restore()
    for key in list(_HELD):
        out = Path(key)
        with contextlib.suppress(Exception):
            remove_leftovers(out)
        with contextlib.suppress(Exception):
            if (_read_lock(out / LOCK_NAME) or {}).get("pid") == os.getpid():
                (out / LOCK_NAME).unlink()


def output_folder(out) -> Path:
    """``out`` as a Path; an empty value (an unset variable) is refused, never taken as the current folder."""
    if out is None or not str(out).strip():
        raise OutputError(f"{option('out')} is empty", hint=f"Give the output folder, e.g. {option('out', 'out')}")
    return Path(out)


RECORD_NAME = "report.json"


def is_our_record(path) -> bool:
    """Whether ``path`` is a record gistools wrote: a JSON object whose ``tool`` names a gistools command."""
    try:
        value = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError, RecursionError):
        return False
    return isinstance(value, dict) and str(value.get("tool") or "").startswith("gistools")


# the commands that make and remake one kind of folder: the shrub chain's (its rasters, each step, its map), and
# each other command's own; a command is refused a folder another kind of command made (it would rewrite that
# command's products and record: gistools metrics into a chain's folder rewrote its density/)
FOLDER_KINDS = {
    "shrub chain": ("gistools shrub", "gistools rasters", "gistools bands", "gistools clip", "gistools density",
                    "gistools classes", "gistools classify", "gistools map", "gistools webmap", "gistools scene",
                    "gistools mapbook"),
}


def folder_kind(command: str) -> str:
    """The kind of folder ``command`` makes ("shrub chain" for the chain's commands, else the command itself)."""
    for kind, commands in FOLDER_KINDS.items():
        if command in commands:
            return kind
    return command


def _record_tool(record: Path) -> str | None:
    try:
        value = json.loads(record.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError, RecursionError):
        return None
    return str(value.get("tool") or "") if isinstance(value, dict) else None


def check_record(out, command: str | None = None) -> None:
    """Refuse, before anything is written, a folder whose ``report.json`` gistools did not write (a user's own file
    of that name: the record of the run would replace it), and a folder another kind of command made
    (``command`` would rewrite its products)."""
    record = Path(out) / RECORD_NAME
    if record.is_dir() or (record.exists() and not is_our_record(record)):
        raise OutputExistsError(f"a {RECORD_NAME} gistools did not write is in the way", path=record,
                                hint="Move or rename it, or choose another output folder")
    owner = _record_tool(record) if record.exists() else None
    if command and command.startswith("gistools ") and owner and folder_kind(owner) != folder_kind(command):
        raise OutputExistsError(f"this folder holds the outputs of {owner}; {command} would rewrite them",
                                path=Path(out), hint=f"Give {command} another output folder "
                                                     f"(e.g. {Path(out).name}_{command.split()[1]})")


@contextlib.contextmanager
def claim_output(out, command: str = "gistools"):
    """Create and lock the output folder ``out`` for the block, after removing this program's leftovers.

    Raises OutputError (not writable, a file, read-only), OutputBusyError (another run holds it) or
    OutputExistsError (a report.json gistools did not write is there) before anything is written. Nested claims of one folder in one process (the shrub chain runs the rasters) share
    the lock.
    """
    out = output_folder(out)
    key = os.path.abspath(out)
    with _HELD_LOCK:
        nested = _HELD.get(key, 0) > 0
        if not nested:
            check_record(out, command)
            _make_folder(out)
            _take_lock(out, command)
            remove_leftovers(out)
        _HELD[key] = _HELD.get(key, 0) + 1
    failed = True
    try:
        yield out
        failed = False
    finally:
        with _HELD_LOCK:
            _HELD[key] -= 1
            if _HELD[key] == 0:
                del _HELD[key]
                if failed:  # an error or Ctrl-C: partial files of stopped workers go; the lock is still ours
                    with contextlib.suppress(OSError):
                        remove_leftovers(out)
                with contextlib.suppress(OSError):
                    if (_read_lock(out / LOCK_NAME) or {}).get("pid") == os.getpid():
                        (out / LOCK_NAME).unlink()


ROLLBACK_PREFIX = SCRATCH_PREFIX + "rollback-"
MANIFEST = "manifest.json"
_ROLLBACKS: set = set()  # the rollbacks of this process in progress (abandon() restores them)


def _restore_left(out: Path, saved: Path) -> None:
    """Put back what a rollback folder left by a killed step rerun holds (its manifest says what it kept)."""
    try:
        manifest = json.loads((saved / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return  # killed while it was being made: the folder's files were not touched yet
    rollback = Rollback(out, manifest.get("folders", ()), manifest.get("files", ()))
    rollback.saved, rollback.kept = saved, list(manifest.get("kept", ()))
    with contextlib.suppress(OSError):
        rollback.restore()


class Rollback:
    """Keep the current state of some outputs so that a step rerun that fails can put them back.

    Every file of ``folders`` (sub-folders of ``out``) and every name of ``files`` (in ``out``) is hard-linked
    into a hidden ``.gistools-scratch-rollback-*`` folder: no data is copied, and since every write replaces its
    file by a rename, the links keep the old contents. :meth:`restore` puts them back and removes the files of
    those folders that the rerun added; :meth:`drop` forgets them. Used as a context manager, a block that
    raises (Ctrl-C included) is restored; one that returns is kept only after :meth:`drop`.
    """

    def __init__(self, out, folders, files):
        self.out = Path(out)
        self.folders, self.files = tuple(folders), tuple(files)
        self.saved = None

    def __enter__(self):
        import tempfile

        self.saved = Path(tempfile.mkdtemp(prefix=ROLLBACK_PREFIX, dir=self.out))
        self.kept = []
        for rel in self._present():
            target = self.saved / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            try:
                os.link(self.out / rel, target)
            except OSError:  # a file system without hard links: a copy
                shutil.copy2(self.out / rel, target)
            self.kept.append(rel)
        with open(self.saved / MANIFEST, "w", encoding="utf-8") as fh:  # what a later run puts back if this one is killed
            json.dump({"folders": self.folders, "files": self.files, "kept": self.kept}, fh)
        _ROLLBACKS.add(self)
        return self

    def _present(self) -> list[str]:
        found = [name for name in self.files if (self.out / name).is_file()]
        for folder in self.folders:
            d = self.out / folder
            if d.is_dir():
                found += [f"{folder}/{p.name}" for p in d.iterdir() if p.is_file() and not is_partial(p)]
        return found

    def restore(self) -> None:
        if self.saved is None:
            return
        kept = set(self.kept)
        for rel in self._present():
            if rel not in kept:
                with contextlib.suppress(OSError):
                    (self.out / rel).unlink()
        for rel in self.kept:
            os.replace(self.saved / rel, self.out / rel)
        self.drop()

    def drop(self) -> None:
        _ROLLBACKS.discard(self)
        if self.saved is not None:
            shutil.rmtree(self.saved, ignore_errors=True)
            self.saved = None

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None:
            self.restore()
        return False
