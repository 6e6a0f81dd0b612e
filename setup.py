"""Build of the optional compiled kernel, ``gistools._kernel`` (everything else is in pyproject.toml).

The kernel (csrc/) is C99, bound with cffi in API mode (csrc/kernel_build.py). Where it cannot be built the
install still succeeds and gistools runs its numpy forms, with the same results, more slowly; ``gistools
--version`` says which engine runs, and the test suite fails in CI when the kernel was not built.
"""

import os
import runpy

from setuptools import setup

if os.environ.get("GISTOOLS_PURE") == "1":  # the QGIS plugin's fallback wheel (py3-none-any): the numpy engine
    setup()
    raise SystemExit(0)
ffibuilder = runpy.run_path("csrc/kernel_build.py")["ffibuilder"]
kernel = ffibuilder.distutils_extension("build/cffi")
kernel.optional = True  # a machine without a C compiler still installs gistools
# the kernel uses only Python's stable ABI (py_limited_api in csrc/kernel_build.py): one abi3 wheel per platform
# serves Python 3.11 and every later one
setup(ext_modules=[kernel], options={"bdist_wheel": {"py_limited_api": "cp311"}})
