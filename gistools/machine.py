"""What this machine gives a run: the CPUs it may use and the memory still available (portable: Linux, macOS,
Windows, and a process limit such as ``ulimit -v`` where one is set)."""

from __future__ import annotations

import ctypes
import os
import sys

__all__ = ["usable_cpus", "available_memory", "free_memory", "address_space_left", "address_space_limit"]


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity where the platform has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # macOS, Windows
        return max(1, os.cpu_count() or 1)


def available_memory() -> int | None:
    """Bytes of memory the machine can still give without swapping, or the process's address-space limit
    (``ulimit -v``) less what it uses, whichever is smaller (None where neither can be told)."""
    free = free_memory()
    limit = address_space_left()
    if free is None or (limit is not None and limit < free):
        return limit
    return free


def address_space_limit() -> int | None:
    """This process's address-space limit in bytes (``ulimit -v``); None without one (or on Windows)."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, AttributeError, ValueError, OSError):
        return None
    return None if soft in (resource.RLIM_INFINITY, -1) or soft <= 0 else int(soft)


def address_space_left() -> int | None:
    """Bytes this process may still map under its address-space limit (``ulimit -v``); None without a limit."""
    soft = address_space_limit()
    if soft is None:
        return None
    used = None
    try:
        with open("/proc/self/statm", encoding="utf-8") as f:
            used = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):
        pass
    return max(0, soft - (used or 0))


def free_memory() -> int | None:
    """Bytes of memory the machine can still give without swapping (None where it cannot be told)."""
    try:
        with open("/proc/meminfo", encoding="utf-8") as f:  # Linux: MemAvailable counts the reclaimable page cache
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")  # other POSIX
    except (AttributeError, ValueError, OSError):
        pass
    if sys.platform == "win32":  # pragma: no cover - Windows
        class _Status(ctypes.Structure):
            _fields_ = [("length", ctypes.c_ulong), ("load", ctypes.c_ulong), ("total", ctypes.c_ulonglong),
                        ("avail", ctypes.c_ulonglong), ("page_total", ctypes.c_ulonglong),
                        ("page_avail", ctypes.c_ulonglong), ("virtual_total", ctypes.c_ulonglong),
                        ("virtual_avail", ctypes.c_ulonglong), ("extended", ctypes.c_ulonglong)]

        status = _Status(length=ctypes.sizeof(_Status))
        if ctypes.windll.kernel32.GlobalMemoryStatusEx(ctypes.byref(status)):
            return int(status.avail)
    return None
