"""Runs bounded by the machine: never more workers than tiles or CPUs, none past what the memory holds, and a run
that meets the machine's limits says so in one line with the fix instead of blaming a tile."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import SAMPLE, need_kernel
from gistools.machine import available_memory, free_memory, usable_cpus
from gistools.engine.batch import worker_count

GISTOOLS = [sys.executable, "-m", "gistools.cli.main"]


def test_workers_are_capped_by_the_tasks_the_cpus_and_the_memory():
    said = []
    assert worker_count(1000, 4, warn=said.append) == min(4, usable_cpus())
    assert worker_count(3, 1, warn=said.append) == 1  # one task, one worker, without a word
    if usable_cpus() < 4:
        assert f"1000 jobs asked for, {usable_cpus()} CPUs here" in said[0]
    said.clear()
    memory = free_memory()
    assert memory is not None and memory > 0
    # tasks of half the free memory each: at most one at a time fits, said with the numbers
    assert worker_count(2, 8, task_bytes=memory // 2, warn=said.append) == 1
    if usable_cpus() >= 2:
        assert "do not fit in the" in said[-1] and "GB of memory available" in said[-1]


def _run(args, limit_bytes=None, timeout=600):
    def limit():
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))

    return subprocess.run(GISTOOLS + [str(a) for a in args], capture_output=True, text=True, timeout=timeout,
                          preexec_fn=limit if limit_bytes else None)


def test_jobs_1000_runs_as_many_workers_as_tiles_and_cpus_allow(tmp_path):
    start = time.perf_counter()
    run = _run(["rasters", SAMPLE, "--out", tmp_path / "a", "-q", "--jobs", 1000])
    seconds = time.perf_counter() - start
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr
    workers = min(4, usable_cpus())
    if usable_cpus() < 4:
        assert f"1000 jobs asked for, {usable_cpus()} CPUs here: running {workers} at a time" in run.stderr
    assert seconds < 120, seconds  # not 1000 interpreters starting (which took minutes and the machine's memory)


@pytest.mark.skipif(sys.platform != "linux", reason="ulimit -v")
def test_a_grid_past_the_memory_is_refused_with_the_numbers_before_any_allocation(tmp_path):
    """Under ``ulimit -v 3G`` a 0.06 ft grid of a sample tile (about 2.6 billion cells) is refused by the memory it
    would need, naming the memory and the fix, not a MemoryError blamed on the tile."""
    run = _run(["rasters", SAMPLE / "35712.las", "--out", tmp_path / "b", "-q", "--cell-size", "0.06ft"], 3 * 2**30)
    assert run.returncode == 1, run.stderr
    assert "Traceback" not in run.stderr and "MemoryError" not in run.stderr
    assert "cell size 0.06" in run.stderr and "--cell-size" in run.stderr


@pytest.mark.skipif(sys.platform != "linux", reason="ulimit -v")
def test_the_import_under_a_tight_memory_limit_is_one_line_or_works(tmp_path):
    run = _run(["info", SAMPLE / "35712.las"], 600 * 2**20)
    assert "Traceback" not in run.stderr, run.stderr[-2000:]
    assert run.returncode in (0, 1)
    if run.returncode:
        assert run.stderr.strip().count("\n") == 0 and run.stderr.startswith("gistools:")


def test_available_memory_reads_the_process_limit(tmp_path):
    code = ("import resource; resource.setrlimit(resource.RLIMIT_AS, (2**31, 2**31)); "
            "from gistools.machine import available_memory; print(available_memory())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert 0 < int(out.stdout) < 2**31
    assert available_memory() is not None


@pytest.mark.skipif(sys.platform != "linux", reason="ulimit -v")
@pytest.mark.parametrize("mib", [560, 600, 640, 680, 720, 760])
def test_a_run_under_a_tight_memory_limit_completes_or_says_so_in_one_line(tmp_path, mib):
    """Under ``ulimit -v`` limits around what the run needs, it either completes or stops with one line saying the
    machine ran out of memory under that limit, with the fix: no traceback, no tile blamed ("FAILED"), and no abort
    of the LAZ decoder (Rust's "memory allocation of N bytes failed", which kills the process with SIGABRT)."""
    run = _run(["rasters", SAMPLE, "--out", tmp_path / "c", "-q"], mib * 2**20)
    assert "Traceback" not in run.stderr and "FAILED" not in run.stderr, run.stderr[-2000:]
    if run.returncode:
        line = run.stderr.strip()
        assert run.returncode == 1 and line.count("\n") == 0, line
        assert line.startswith("gistools: error: the machine ran out of memory") and "ulimit -v" in line, line


def test_memory_errors_are_the_runs_not_a_tiles():
    """A tile's MemoryError, or a worker the system killed (BrokenProcessPool), stops the run with the machine's
    error and the fix, instead of marking the tile failed while the others go on."""
    from concurrent.futures.process import BrokenProcessPool

    from gistools.errors import OutOfMemoryError
    from gistools.parameters import speaks
    from gistools.engine.batch import fail
    from gistools.products.rasters import TileResult

    for err in (MemoryError(), BrokenProcessPool("A process in the process pool was terminated abruptly")):
        result = TileResult(name="35712", path="35712.las")
        with pytest.raises(OutOfMemoryError) as raised, speaks("cli"):
            fail(result, err)
        with speaks("cli"):
            text = str(raised.value)
        assert "35712" in text and "--jobs" in text and "--cell-size" in text
        assert result.status == "ok"  # the tile is not blamed


_KILLED_WHILE_FED = """
import os, signal, threading
from gistools.engine.batch import ProcessPool

if __name__ == "__main__":
    pool = ProcessPool(1, "spawn", warm=True)
    pid = pool.submit(os.getpid).result(timeout=120)
    os.kill(pid, signal.SIGSTOP)  # the worker stops reading: the task's 8 MB fill the pipe and the feeder waits
    fut = pool.submit(len, bytes(8_000_000))
    threading.Event().wait(0.5)
    os.kill(pid, signal.SIGKILL)
    try:
        fut.result(timeout=60)
    except Exception as err:
        print(type(err).__name__)
    closing = threading.Thread(target=pool.close, args=([fut],), daemon=True)
    closing.start()
    closing.join(60)
    print("hung" if closing.is_alive() else "closed", flush=True)
    os._exit(0)
"""


@pytest.mark.skipif(sys.platform == "win32", reason="stops a process with SIGSTOP (POSIX)")
def test_a_worker_killed_while_its_task_is_written_to_it_does_not_hang_the_pool(tmp_path):
    """A worker the system kills while a large task is still being written to it (a cloth helper given a tile's
    points): the task fails with BrokenProcessPool and closing the pool returns. Python 3.11.2 (Debian 12) waits for
    the blocked writer for ever unless the pool lets it go."""
    script = tmp_path / "killed_while_fed.py"
    script.write_text(_KILLED_WHILE_FED, encoding="utf-8")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300,
                          cwd=Path(__file__).resolve().parents[1])
    assert done.stdout.split() == ["BrokenProcessPool", "closed"], done.stdout + done.stderr[-2000:]


@pytest.mark.skipif(sys.platform != "linux", reason="reads the process group with ps (Linux)")
def test_no_process_of_the_group_is_left_when_the_command_returns(tmp_path):
    """`gistools rasters --jobs 2` in its own process group (as a scheduler or a script starts it): when it has
    returned, no process of the group is left: no worker, no resource tracker, no zombie."""
    for run in range(3):
        proc = subprocess.Popen([sys.executable, "-m", "gistools.cli.main", "rasters", str(SAMPLE), "--out",
                                 str(tmp_path / f"out{run}"), "--jobs", "2"], start_new_session=True,
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        _, err = proc.communicate(timeout=600)
        left = subprocess.run(["ps", "-o", "pid=,stat=,args=", "-g", str(proc.pid)], capture_output=True,
                              text=True).stdout.strip()
        assert proc.returncode == 0, err[-2000:]
        assert not left, f"run {run}: left in the group after the command returned:\n{left}"


def test_jobs_auto_runs_small_work_in_the_process_and_repays_each_worker_with_points(monkeypatch):
    """The rule of jobs="auto": no worker below 5 M points, then one per 5 M points, capped by the tasks and the
    CPUs; unknown work (a step rerun) counts 8 tiles a worker."""
    from gistools.engine import batch

    monkeypatch.setattr(batch, "usable_cpus", lambda: 8)
    assert batch.auto_workers(4, 2_830_000) == 1  # a few real tiles: the one process decodes on every core
    assert batch.auto_workers(4, 9_999_999) == 1
    assert batch.auto_workers(16, 43_000_000) == 8  # the 16-tile block: all the CPUs
    assert batch.auto_workers(3, 43_000_000) == 3  # never more workers than tiles
    assert batch.auto_workers(40, None) == 5 and batch.auto_workers(4, None) == 1
    monkeypatch.setattr(batch, "usable_cpus", lambda: 2)
    assert batch.auto_workers(16, 43_000_000) == 2


def test_jobs_takes_auto_or_a_whole_number_and_says_so_in_one_line(tmp_path):
    from gistools.errors import InputError
    from gistools import rasters_from_tiles

    for bad in ("0", "abc", "-1"):
        proc = subprocess.run([sys.executable, "-m", "gistools.cli.main", "rasters", str(SAMPLE), "--out",
                               str(tmp_path / "o"), "--jobs", bad], capture_output=True, text=True, timeout=300)
        assert proc.returncode == 2 and "Traceback" not in proc.stderr and "--jobs" in proc.stderr, proc.stderr
        assert not (tmp_path / "o").exists()
    with pytest.raises(InputError, match="jobs 'many' is neither auto nor a whole number"):
        rasters_from_tiles([str(SAMPLE)], tmp_path / "p", jobs="many")
    assert not (tmp_path / "p").exists()
    proc = subprocess.run([sys.executable, "-m", "gistools.cli.main", "-v", "rasters", str(SAMPLE), "--out",
                           str(tmp_path / "a"), "--jobs", "auto"], capture_output=True, text=True, timeout=300)
    threads = min(usable_cpus(), 4)
    said = f"{threads} threads in this process" if threads > 1 else "in this process"
    assert proc.returncode == 0 and f"jobs auto: {said} (4 tasks, 0.3 M points)" in proc.stderr, proc.stderr[-2000:]


def test_jobs_auto_runs_small_work_on_threads_of_the_process_with_the_outputs_of_one_at_a_time(tmp_path, monkeypatch,
                                                                                               caplog):
    """Below a worker's worth of points, "auto" runs the tiles on threads of the caller's process (one a CPU, capped
    by the tiles): the rasters are those of a run one tile at a time, value for value."""
    import logging

    import numpy as np

    from gistools import rasters_from_tiles
    from gistools.engine import batch
    from gistools.io.raster import read_raster

    monkeypatch.setattr(batch, "usable_cpus", lambda: 3)
    with caplog.at_level(logging.INFO, logger="gistools.engine.batch"):
        rasters_from_tiles([str(SAMPLE)], tmp_path / "auto", jobs="auto")
    assert "jobs auto: 3 threads in this process (4 tasks, 0.3 M points)" in caplog.text
    rasters_from_tiles([str(SAMPLE)], tmp_path / "one", jobs=1)
    for product in ("dsm", "dem", "ndsm"):
        a, _, _ = read_raster(tmp_path / "one" / f"{product}.vrt")
        b, _, _ = read_raster(tmp_path / "auto" / f"{product}.vrt")
        assert np.array_equal(a, b, equal_nan=True), product


def test_a_thread_pool_closed_early_stops_its_tiles_at_their_next_kernel_call_and_leaves_no_thread():
    """An error or an interrupt closes the pool with tiles still running: each stops at its next call of the
    compiled kernel (Cancelled), the queued ones never start, and close returns only when no tile thread is left."""
    import threading

    import numpy as np

    from gistools.engine.batch import ThreadPool
    from gistools.errors import Cancelled
    from gistools.lidar.tin import delaunay_triangles

    need_kernel()
    running = threading.Event()
    x, y = np.random.default_rng(1).uniform(0, 10, (2, 50))

    def tile():  # a long tile: kernel calls until the run stops
        while True:
            delaunay_triangles(x, y)
            running.set()

    pool = ThreadPool(2)
    futures = [pool.submit(tile) for _ in range(3)]
    assert running.wait(30)  # a tile has made kernel calls
    pool.close(futures)
    assert not any(t.name.startswith("gistools-tile") and t.is_alive() for t in threading.enumerate())
    assert isinstance(futures[0].exception(), Cancelled) and futures[2].cancelled()
    assert futures[1].cancelled() or isinstance(futures[1].exception(), Cancelled)  # started, or not yet


def test_tiles_on_threads_silence_a_c_library_together_and_give_the_terminal_back():
    """CSF prints from C: the tiles on threads send file descriptor 1 to /dev/null from the first one in to the last
    one out, and then it is the terminal (or file) it was."""
    import os
    import threading

    from gistools.products.ground import _quiet_stdout

    before = os.fstat(1)
    inside, leave = threading.Barrier(3), threading.Event()

    def tile():
        with _quiet_stdout(True):
            inside.wait(30)
            leave.wait(30)

    threads = [threading.Thread(target=tile) for _ in range(2)]
    for t in threads:
        t.start()
    inside.wait(30)
    assert os.path.samestat(os.fstat(1), os.stat(os.devnull))
    leave.set()
    for t in threads:
        t.join(30)
    after = os.fstat(1)
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)


def test_a_cancel_from_within_a_tile_on_a_thread_stops_the_run_and_leaves_no_output(tmp_path, monkeypatch):
    """On threads, a tile's read reports its chunks to the caller's callback (as one tile at a time does): answering
    False there (QGIS's Cancel) stops the whole run at once, with no raster, scratch or partial file left."""
    from gistools import RasterSettings, rasters_from_tiles
    from gistools.engine import batch
    from gistools.errors import Cancelled

    monkeypatch.setattr(batch, "usable_cpus", lambda: 2)
    said = []

    def progress(fraction, message):
        said.append(message)
        return "points read" not in message  # the first report from inside a tile's read asks to stop

    out = tmp_path / "out"
    with pytest.raises(Cancelled):
        rasters_from_tiles([str(SAMPLE)], out, RasterSettings(chunk_size=5000), jobs="auto", progress=progress)
    assert any("points read" in m for m in said)
    assert not list(out.rglob("*.tif")) and not list(out.rglob("*.partial*")) and not list(out.glob(".gistools-scratch-*"))
