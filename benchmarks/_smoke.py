"""The benchmarks' smoke scale: with ``GISTOOLS_BENCH_SMOKE=1`` in the environment every script in benchmarks/ runs
its same code path end to end on a tiny problem (a few thousand points or cells, one repeat, peers skipped), in a
few seconds, and says first that it is a smoke run. The test suite runs the commands of docs/performance.md so;
their figures are meaningless."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

ENV = "GISTOOLS_BENCH_SMOKE"


def smoke() -> bool:
    """True when the environment asks for a smoke run."""
    return os.environ.get(ENV, "").strip() not in ("", "0")


def scaled(n, small):
    """``small`` in a smoke run, ``n`` otherwise."""
    return small if smoke() else n


def announce(name: str) -> None:
    """In a smoke run, print the line that says so (the first line of the script's output); otherwise make sure
    gistools' modules are byte-compiled (:func:`compiled`)."""
    if smoke():
        print(f"{name}: smoke run ({ENV}=1): a tiny problem, the figures are meaningless",
              flush=True)
    else:
        compiled()


def compiled() -> None:
    """Byte-compile gistools' modules beside their sources, as ``pip install`` leaves an installed package: a
    checkout installed in editable mode compiles them on the first import, but where PYTHONDONTWRITEBYTECODE is
    set (some sandboxes and CI images) every timed run would compile them again (about 0.1 s of each start here)."""
    import compileall
    from pathlib import Path

    package = Path(__file__).resolve().parents[1] / "gistools"
    compileall.compile_dir(str(package), quiet=1, workers=1)


def workdir(default: str) -> str:
    """``default`` or, in a smoke run, a fresh temporary folder removed at exit (a smoke run never reuses nor leaves
    behind the full-size data cached in ``default``)."""
    if not smoke():
        return default
    path = tempfile.mkdtemp(prefix=os.path.basename(default.rstrip("/")) + "-smoke-")
    atexit.register(shutil.rmtree, path, ignore_errors=True)
    return path
