"""Build of the optional compiled TIN kernel (everything else is in pyproject.toml).

The kernel needs a C compiler with 128-bit integers (GCC or Clang). Where it cannot be built the
install still succeeds and gistools uses Triangle for TINs (``gistools.lidar.tin.tin_engine()``).
"""

import sys

from setuptools import Extension, setup

# -fno-wrapv: Python builds extensions with -fwrapv (signed overflow defined), which holds back the grid loops;
# the kernel never relies on signed overflow; -ffp-contract=off: no fused multiply-adds (aarch64 would contract
# a * b + c), so the kernel's float64 arithmetic is numpy's (cell indices, scaled z)
flags = [] if sys.platform == "win32" else ["-O3", "-std=c99", "-fno-wrapv", "-ffp-contract=off"]
setup(ext_modules=[Extension("gistools.lidar._tinkernel", ["gistools/lidar/_tinkernel.c"],
                             extra_compile_args=flags, optional=True)])
