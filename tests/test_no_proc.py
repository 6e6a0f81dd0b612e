"""Without /proc (Windows, macOS, some containers): the run lock still tells a live holder from a dead one, and the
plugin still sees a binary wheel's own GDAL / PROJ / GEOS. Real processes, /proc made unavailable to the code."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
import types
from pathlib import Path

import pytest

from gistools.errors import OutputBusyError
from gistools.io import outdir


@pytest.fixture
def processes():
    """A live process and the id of one that has exited (and been reaped)."""
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    yield live, dead.pid
    live.kill()
    live.wait()


@pytest.fixture
def no_proc(monkeypatch, tmp_path):
    monkeypatch.setattr(outdir, "PROC", tmp_path / "no-proc")


@pytest.fixture
def no_psutil(monkeypatch):
    monkeypatch.setitem(sys.modules, "psutil", None)  # import psutil raises ImportError
    assert outdir._psutil() is None


def _lock(out: Path, pid: int, start):
    out.mkdir(exist_ok=True)
    (out / outdir.LOCK_NAME).write_text(json.dumps({"pid": pid, "host": socket.gethostname(), "start": start,
                                                    "command": "rasters", "since": "earlier"}))


@pytest.mark.skipif(sys.platform == "win32" or shutil.which("ps") is None, reason="the ps command (macOS, the BSDs)")
def test_without_proc_and_without_psutil_ps_tells_a_reused_pid_apart(no_proc, no_psutil, processes, tmp_path):
    live, dead = processes
    start = outdir._process_start(live.pid)
    reference = subprocess.run(["ps", "-o", "lstart=", "-p", str(live.pid)], capture_output=True, text=True,
                               env={"LC_ALL": "C", "PATH": "/usr/bin:/bin"}).stdout
    assert start == "p" + " ".join(reference.split())
    assert outdir._alive(live.pid, start) and not outdir._alive(dead, start)
    assert not outdir._alive(live.pid, "pMon Jan  1 00:00:00 2001")  # that pid now runs another process
    assert live.poll() is None  # asked, not signalled
    _lock(tmp_path / "busy", live.pid, start)
    with pytest.raises(OutputBusyError):
        outdir._take_lock(tmp_path / "busy", "rasters")
    _lock(tmp_path / "reused", live.pid, "pMon Jan  1 00:00:00 2001")
    lock = outdir._take_lock(tmp_path / "reused", "rasters")
    assert json.loads(lock.read_text())["pid"] == outdir.os.getpid()


def test_without_proc_psutil_or_ps_the_pid_decides(no_proc, no_psutil, processes, tmp_path, monkeypatch):
    live, dead = processes
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))  # no ps on the path
    assert outdir._process_start(live.pid) is None
    assert outdir._alive(live.pid, None) and not outdir._alive(dead, None)
    assert outdir._alive(live.pid, "4711")  # a /proc start from elsewhere cannot be checked: the pid decides
    assert live.poll() is None  # asked, not signalled
    _lock(tmp_path / "busy", live.pid, None)
    with pytest.raises(OutputBusyError):
        outdir._take_lock(tmp_path / "busy", "rasters")
    _lock(tmp_path / "stale", dead, None)
    lock = outdir._take_lock(tmp_path / "stale", "rasters")
    assert json.loads(lock.read_text())["pid"] == outdir.os.getpid()


def test_without_proc_psutil_tells_a_reused_pid_apart(no_proc, processes, tmp_path):
    psutil = pytest.importorskip("psutil")
    live, dead = processes
    start = outdir._process_start(live.pid)
    assert start == f"t{psutil.Process(live.pid).create_time():.3f}"
    assert outdir._alive(live.pid, start) and not outdir._alive(dead, start)
    assert not outdir._alive(live.pid, "t1.000")  # that pid now runs another process: the lock is stale
    _lock(tmp_path / "busy", live.pid, start)
    with pytest.raises(OutputBusyError):
        outdir._take_lock(tmp_path / "busy", "rasters")
    _lock(tmp_path / "reused", live.pid, "t1.000")
    lock = outdir._take_lock(tmp_path / "reused", "rasters")
    assert json.loads(lock.read_text())["start"] == outdir._process_start(outdir.os.getpid())
    assert live.poll() is None


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="Linux /proc")
def test_with_proc_the_start_is_procs_and_psutil_alone_agrees(processes):
    live, dead = processes
    start = outdir._process_start(live.pid)
    assert start.isdigit() and outdir._alive(live.pid, start) and not outdir._alive(live.pid, str(int(start) + 1))
    assert not outdir._alive(dead, start)


def _plugin():
    pytest.importorskip("qgis.core")
    from qgis_plugin import plugin

    return plugin


@pytest.mark.parametrize("layout", ["manylinux / windows", "macos", "none"])
def test_plugin_finds_a_wheels_own_libraries_from_its_files(tmp_path, layout):
    plugin = _plugin()
    package = tmp_path / "site" / "shapely"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    folder = {"manylinux / windows": tmp_path / "site" / "shapely.libs", "macos": package / ".dylibs"}.get(layout)
    if folder is not None:
        folder.mkdir()
        (folder / "libgeos-c.so.1").write_bytes(b"")
    module = types.SimpleNamespace(__file__=str(package / "__init__.py"))
    assert plugin.bundled_libraries(module) == folder


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="Linux /proc as the reference")
def test_plugin_check_agrees_with_the_libraries_linux_has_mapped():
    import numpy
    import pyproj
    import rasterio
    import scipy.linalg  # noqa: F401  (loads scipy.libs where the wheel has it)
    import shapely

    plugin = _plugin()
    maps = Path("/proc/self/maps").read_text()
    for module in (numpy, scipy, shapely, pyproj, rasterio):
        name = module.__name__.split(".")[0]
        folder = plugin.bundled_libraries(sys.modules[name])
        assert (folder is not None) == (f"/{name}.libs/" in maps), name
