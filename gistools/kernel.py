"""gistools' compiled kernel (``gistools/lidar/_tinkernel.c``): loaded once, every entry point's types declared
here once.

The kernel is optional at install (a machine without a C compiler still installs gistools) and every caller has
a numpy form giving the same values; :func:`engine` says which one runs (``gistools --version`` prints it), and
the test suite fails in CI when the kernel was not built. ``tests/test_tin_kernel.py`` checks :data:`SIGNATURES`
against the C prototypes, so a changed C argument list fails a test instead of corrupting memory.

Argument codes: ``l`` int64, ``i`` int32, ``d`` double; ``*d`` ``*l`` ``*i`` ``*b`` ``*f`` a C-contiguous numpy
array of float64, int64, int32, uint8 or float32 (its dtype is checked at each call); ``&l`` a ``ctypes.c_int64``
passed by reference; ``p`` an address or None (strided views, optional arrays).
"""

from __future__ import annotations

import ctypes
import functools
import importlib.machinery
from pathlib import Path

import numpy as np

__all__ = ["SIGNATURES", "function", "engine", "loaded"]

# name: (result, arguments); the order and types of gistools/lidar/_tinkernel.c's prototypes
SIGNATURES: dict[str, tuple[str, tuple[str, ...]]] = {
    # TIN
    "gt_quantise": ("d", ("l", "*d", "d", "d", "*l")),
    "gt_delaunay": ("l", ("l", "*l", "*l", "*i", "&l")),
    "gt_rasterize": ("l", ("l", "*i", "*d", "*d", "*d", "i", "i", "d", "*d", "p", "p")),
    "gt_tin_grid": ("l", ("l", "*l", "*l", "*d", "*d", "*d", "i", "i", "d", "*d", "&l", "p", "p")),
    "gt_tin_at": ("l", ("l", "*i", "*d", "*d", "*d", "l", "l", "*d", "*d", "*d")),
    # morphology (ground filters)
    "gt_cross_filter": ("v", ("*d", "*d", "*d", "l", "l", "i", "i")),
    "gt_fill_rings": ("l", ("*d", "*d", "l", "l", "i")),
    "gt_progressive": ("v", ("*d", "*b", "*d", "l", "l", "d", "d", "i")),
    "gt_fill_front": ("l", ("*d", "l", "l", "i", "l", "*l", "*b", "*d")),
    "gt_bilinear": ("v", ("*d", "l", "l", "l", "*d", "*d", "d", "l", "l", "*d")),
    "gt_slope_threshold": ("v", ("*d", "l", "l", "d", "d", "d", "d", "*d")),
    # grid
    "gt_cell_index": ("v", ("l", "*d", "*d", "d", "l", "l", "l", "l", "*l")),
    "gt_cell_min": ("v", ("l", "*l", "*d", "*d")),
    "gt_cell_mean": ("v", ("l", "*l", "*d", "*b", "l", "*d", "*l", "*d")),
    "gt_max_with_class": ("v", ("l", "*l", "*d", "*b", "*b", "l", "*d", "*b", "*d", "*b")),
    # scan (pass 1 of the rasters)
    "gt_scan_chunk": ("v", ("l", "p", "l", "p", "l", "p", "l", "*d", "*d", "*l", "*b", "*b", "*b", "*b", "*b", "l",
                            "*d", "p", "*d", "*b", "*l", "*l", "p", "*i", "*f", "l", "l", "p", "p", "*d", "*i", "p",
                            "*i", "*b", "*d", "*l")),
}

_SCALARS = {"l": ctypes.c_int64, "i": ctypes.c_int32, "d": ctypes.c_double, "v": None, "p": ctypes.c_void_p,
            "&l": ctypes.POINTER(ctypes.c_int64)}
_ARRAYS = {"*d": np.float64, "*l": np.int64, "*i": np.int32, "*b": np.uint8, "*f": np.float32}


def ctype(code: str):
    """The ctypes type of an argument code (a numpy ndpointer for the array codes)."""
    if code in _ARRAYS:
        return np.ctypeslib.ndpointer(_ARRAYS[code], flags="C_CONTIGUOUS")
    return _SCALARS[code]


def _library_file() -> Path | None:
    """The built kernel's file beside its source (found by the interpreter's extension suffixes, without importing
    gistools.lidar, which imports the modules that use the kernel)."""
    folder = Path(__file__).resolve().parent / "lidar"
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        if (folder / f"_tinkernel{suffix}").is_file():
            return folder / f"_tinkernel{suffix}"
    return None


def _load():
    """(the kernel library or None, where it is or why not)."""
    path = _library_file()
    if path is None:
        return None, "not built (no C compiler when gistools was installed?)"
    try:
        lib = ctypes.CDLL(str(path))
    except OSError as err:
        return None, f"not loadable ({err})"
    missing = [name for name in SIGNATURES if not hasattr(lib, name)]
    if missing:
        return None, f"older than this gistools (no {', '.join(missing)}): reinstall gistools"
    return lib, str(path)


_LIB, _WHERE = _load()


def loaded() -> bool:
    """True where the compiled kernel runs."""
    return _LIB is not None


def engine() -> str:
    """Which engine runs, in words: the compiled kernel and its file, or the numpy forms and why."""
    return f"compiled C kernel ({_WHERE})" if _LIB is not None else f"numpy (the C kernel is {_WHERE})"


@functools.cache
def function(name: str):
    """The kernel's entry point ``name`` with its declared argument and result types, or None where the kernel is
    not built: the caller's numpy form then runs, with the same values. Looked up once per name."""
    result, args = SIGNATURES[name]
    if _LIB is None:
        return None
    fn = getattr(_LIB, name)
    fn.argtypes = [ctype(code) for code in args]
    fn.restype = ctype(result)
    return fn
