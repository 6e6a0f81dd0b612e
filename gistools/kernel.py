"""gistools' compiled kernel (``csrc/``, the module ``gistools._kernel``), and which engine runs.

The kernel's entry points are declared once, in ``csrc/gistools_kernel.h``: cffi (API mode, ``csrc/kernel_build.py``)
compiles wrappers from that header, so the C compiler checks each definition against it and each call from Python
is checked against it (a wrong number of arguments or a number where an array belongs is a TypeError). The
functions given here also check each array's dtype and layout against the C type before the call.

The kernel is optional at install (a machine without a C compiler still installs gistools): every caller has a
numpy form giving the same values. :func:`engine` says which one runs (``gistools --version`` prints it), and the
test suite fails in CI when the kernel was not built.
"""

from __future__ import annotations

import functools

import numpy as np

from .progress import check_stop

__all__ = ["function", "engine", "loaded", "names"]

try:
    from ._kernel import ffi as _ffi, lib as _lib
    _WHY = None
except ImportError as _err:  # not built (no C compiler at install), or built for another Python
    _ffi = _lib = None
    _WHY = f"not built ({_err}); reinstall gistools with a C compiler"

# the numpy dtype of each C element type an array argument may have
_DTYPES = {"double": np.float64, "float": np.float32, "int64_t": np.int64, "int32_t": np.int32, "uint8_t": np.uint8}


def loaded() -> bool:
    """True where the compiled kernel runs."""
    return _lib is not None


def engine() -> str:
    """Which engine runs, in words: the compiled kernel and its file, or the numpy forms and why."""
    if _lib is None:
        return f"numpy (the C kernel is {_WHY})"
    from . import _kernel

    return f"compiled C kernel ({_kernel.__file__})"


def names() -> list[str]:
    """The kernel's entry points (those of csrc/gistools_kernel.h), where it is built."""
    return sorted(n for n in dir(_lib) if n.startswith("gt_")) if _lib is not None else []


def _argument(ctype, name: str, k: int):
    """A converter of one argument to what cffi passes for ``ctype``: numbers as they are (cffi checks them),
    arrays checked against the C element type and C-contiguous, None as NULL, an int as an address (strided
    views of LAS point records)."""
    if ctype.kind != "pointer":
        return None
    dtype = _DTYPES.get(ctype.item.cname)

    def convert(value):
        if value is None:
            return _ffi.NULL
        if isinstance(value, (int, np.integer)):
            return _ffi.cast(ctype, int(value))
        if not isinstance(value, np.ndarray):
            raise TypeError(f"{name} argument {k + 1}: a numpy array is needed, not {type(value).__name__}")
        if dtype is not None and value.dtype != dtype:
            raise TypeError(f"{name} argument {k + 1}: {ctype.item.cname} array needed, got {value.dtype}")
        if not value.flags.c_contiguous:
            raise TypeError(f"{name} argument {k + 1}: the array must be C-contiguous")
        return _ffi.cast(ctype, value.ctypes.data)  # the array itself is held by the caller through the call

    return convert


@functools.cache
def function(name: str):
    """The kernel's entry point ``name`` (a function of csrc/gistools_kernel.h), taking numpy arrays where the C
    takes pointers; None where the kernel is not built (the caller's numpy form then runs, with the same values)."""
    if _lib is None:
        return None
    fn = getattr(_lib, name)
    converters = [_argument(t, name, k) for k, t in enumerate(_ffi.typeof(fn).args)]

    def call(*args):
        if len(args) != len(converters):
            raise TypeError(f"{name} takes {len(converters)} arguments ({len(args)} given)")
        check_stop()  # a tile on a pool's thread stops at its next kernel call once the run has stopped
        keep = [c(a) if c is not None else a for c, a in zip(converters, args)]  # kept alive through the call
        return fn(*keep)

    call.__name__ = name
    return call
