"""The cffi build of gistools' C kernel (API mode): the module ``gistools._kernel`` (``ffi``, ``lib``).

cffi reads the entry points from ``gistools_kernel.h`` (the one declaration) and compiles wrappers that include
that header and the kernel's sources: the C compiler checks each definition against the header, and each call
from Python is checked against it by the wrappers. setup.py builds it (optional: without a C compiler gistools
installs and runs its numpy forms; ``gistools --version`` says which engine runs).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
SOURCES = ["tin.c", "morphology.c", "grid.c", "scan.c"]

# -fno-wrapv: Python builds extensions with -fwrapv (signed overflow defined), which holds back the grid loops;
# the kernel never relies on signed overflow; -ffp-contract=off: no fused multiply-adds (aarch64 would contract
# a * b + c), so the kernel's float64 arithmetic is numpy's (cell indices, scaled z). MSVC: /fp:precise (its
# default) contracts nothing.
FLAGS = [] if sys.platform == "win32" else ["-O3", "-std=c99", "-fno-wrapv", "-ffp-contract=off"]


def declarations() -> str:
    """The header's prototypes, its comments left out (what cffi's cdef reads)."""
    text = (HERE / "gistools_kernel.h").read_text()
    return re.sub(r"/\*.*?\*/", "", text, flags=re.S)


ffibuilder = FFI()
ffibuilder.cdef(declarations())
# py_limited_api: the wrappers use only Python's stable ABI, so one build (an abi3 wheel) serves every Python from
# 3.11 on (setup.py tags the wheel)
ffibuilder.set_source("gistools._kernel", '#include "gistools_kernel.h"',
                      sources=[str(Path("csrc") / s) for s in SOURCES], include_dirs=["csrc"],
                      extra_compile_args=FLAGS, py_limited_api=True)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
