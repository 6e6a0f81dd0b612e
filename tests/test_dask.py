"""Tiles on a real dask.distributed cluster give the same rasters as a local run."""

from __future__ import annotations

import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from gistools import rasters_from_tiles
from gistools.errors import InputError
from gistools.io.raster import read_raster

distributed = pytest.importorskip("distributed", reason="dask.distributed is an optional extra (gistools[dask])")


def _same(a_out, b_out):
    for product in ("dsm", "dem", "ndsm"):
        a, _, _ = read_raster(a_out / f"{product}.vrt")
        b, _, _ = read_raster(b_out / f"{product}.vrt")
        assert np.array_equal(a, b, equal_nan=True), product


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def dask_cluster():
    """A scheduler and two workers as separate processes on loopback, as on a real cluster."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    bin_dir = __import__("pathlib").Path(sys.executable).parent
    procs = [subprocess.Popen([str(bin_dir / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    time.sleep(1.5)
    for _ in range(2):
        procs.append(subprocess.Popen([str(bin_dir / "dask"), "worker", address, "--nthreads", "1", "--no-dashboard"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    from dask.distributed import Client

    with Client(address, timeout=30) as client:
        client.wait_for_workers(2, timeout=60)
    yield address
    for p in procs[::-1]:
        p.terminate()
    _ended(procs)


def _ended(procs) -> None:
    """Wait for each process; one whose graceful close hangs (a worker without its nanny) is killed."""
    for p in procs:
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(timeout=30)


def test_dask_scheduler_gives_the_same_rasters(sample_tiles, sample_run, tmp_path, dask_cluster):
    summary = rasters_from_tiles(sample_tiles, tmp_path, scheduler=dask_cluster)
    assert summary["counts"] == {"ok": 4, "failed": 0, "skipped": 0}
    assert all(t["points"] > 60000 for t in summary["tiles"])
    _same(tmp_path, sample_run[0])


def test_dask_local_cluster(sample_tiles, sample_run, tmp_path):
    summary = rasters_from_tiles(sample_tiles, tmp_path, jobs=2, scheduler="local")
    assert summary["counts"]["ok"] == 4
    _same(tmp_path, sample_run[0])


def test_unreachable_scheduler_is_a_clear_error(sample_tiles, tmp_path):
    with pytest.raises(InputError, match="cannot connect to a Dask scheduler there"):
        rasters_from_tiles(sample_tiles[:1], tmp_path, scheduler=f"tcp://127.0.0.1:{_free_port()}")


def test_shrub_chain_on_dask_equals_local(sample_tiles, tmp_path, dask_cluster):
    from conftest import SAMPLE
    from gistools.products.shrub import shrub_from_tiles

    b = SAMPLE / "breaklines.gpkg"
    vectors = dict(roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE", waterbodies=f"{b}:WATERBODY",
                   wetlands=f"{b}:WETLAND", tile_index=f"{b}:FOOTPRINT")
    local = shrub_from_tiles(sample_tiles, tmp_path / "local", make_map=False, **vectors)
    remote = shrub_from_tiles(sample_tiles, tmp_path / "dask", make_map=False, scheduler=dask_cluster, **vectors)
    assert remote["counts"] == {"ok": 4, "skipped": 0, "failed": 0}
    assert remote["class_area"] == local["class_area"] and remote["band_area"] == local["band_area"]
    for product in ("bands", "veg", "classes", "cover"):
        a, _, _ = read_raster(tmp_path / "local" / f"{product}.vrt")
        c, _, _ = read_raster(tmp_path / "dask" / f"{product}.vrt")
        assert np.array_equal(a, c, equal_nan=True), product


def test_a_worker_lost_in_the_middle_of_a_run_the_run_completes_with_the_same_rasters(tmp_path):
    """A cluster of a scheduler and two workers (separate processes, no nanny to restart them); one worker is
    killed (SIGKILL) once the run has written a few tiles: the scheduler gives its tiles to the other, the command
    exits 0 with every tile, and the rasters equal a run on this machine's processes."""
    import signal

    from conftest import repeated_block

    tiles = repeated_block(tmp_path / "tiles")
    reference = rasters_from_tiles(tiles, tmp_path / "local", jobs=1)
    assert reference["counts"]["ok"] == 64
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    bin_dir = __import__("pathlib").Path(sys.executable).parent
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    procs = [subprocess.Popen([str(bin_dir / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], **quiet)]
    try:
        time.sleep(1.5)
        workers = [subprocess.Popen([str(bin_dir / "dask"), "worker", address, "--nthreads", "1", "--no-nanny",
                                     "--no-dashboard"], **quiet) for _ in range(2)]
        procs += workers
        from dask.distributed import Client

        with Client(address, timeout=30) as client:
            client.wait_for_workers(2, timeout=60)
        out = tmp_path / "dask"
        run = subprocess.Popen([sys.executable, "-m", "gistools.cli.main", "rasters", str(tiles), "--out", str(out),
                                "--scheduler", address, "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
        deadline = time.monotonic() + 300
        while len(list((out / "dsm").glob("*.tif"))) < 6 and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert run.poll() is None, "the run ended before a worker could be lost: " + run.communicate()[1]
        workers[0].send_signal(signal.SIGKILL)
        workers[0].wait(timeout=30)
        _, stderr = run.communicate(timeout=600)
        assert run.returncode == 0, stderr
        written = len(list((out / "dsm").glob("*.tif")))
        assert written == 64
        _same(out, tmp_path / "local")
    finally:
        for p in procs[::-1]:
            if p.poll() is None:
                p.terminate()
        _ended(procs)


def test_a_scheduler_lost_in_the_middle_of_a_run_is_one_line_and_the_rerun_resumes(tmp_path):
    """The scheduler of a run is killed (SIGKILL) once a few tiles are written: the command exits 1 with one line
    that names --scheduler and says to rerun, no traceback; the same command rerun on a new cluster keeps the tiles
    finished (their files untouched) and completes, equal to a run on this machine's processes."""
    import signal

    from conftest import repeated_block

    tiles = repeated_block(tmp_path / "tiles")
    rasters_from_tiles(tiles, tmp_path / "local", jobs=1)
    out = tmp_path / "dask"
    first = _cluster(tmp_path)
    try:
        run = subprocess.Popen([sys.executable, "-m", "gistools.cli.main", "rasters", str(tiles), "--out", str(out),
                                "--scheduler", first.address, "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
        deadline = time.monotonic() + 300
        while len(list((out / "dsm").glob("*.tif"))) < 6 and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert run.poll() is None, "the run ended before its scheduler could be lost: " + run.communicate()[1]
        first.procs[0].send_signal(signal.SIGKILL)
        _, stderr = run.communicate(timeout=300)
    finally:
        first.end()
    lines = stderr.strip().splitlines()
    assert run.returncode == 1 and len(lines) == 1, stderr
    assert lines[0].startswith(f"gistools: error: --scheduler {first.address}: the Dask scheduler was lost") and \
        "rerun the same command" in lines[0], stderr
    finished = [p.stem for p in (out / "tile_reports").glob("*.json")]  # a tile's report: all its rasters written
    kept = {f"{name}.tif": (out / "dsm" / f"{name}.tif").stat().st_mtime_ns for name in finished}
    assert 0 < len(kept) < 64
    second = _cluster(tmp_path)
    try:
        rerun = subprocess.run([sys.executable, "-m", "gistools.cli.main", "rasters", str(tiles), "--out", str(out),
                                "--scheduler", second.address, "-q"], capture_output=True, text=True, timeout=600)
    finally:
        second.end()
    assert rerun.returncode == 0, rerun.stderr
    assert len(list((out / "dsm").glob("*.tif"))) == 64
    assert {name: (out / "dsm" / name).stat().st_mtime_ns for name in kept} == kept  # resumed, not remade
    _same(out, tmp_path / "local")


class _cluster:
    """A scheduler and two single-thread workers as processes on loopback (workers without a nanny)."""

    def __init__(self, tmp_path):
        port = _free_port()
        self.address = f"tcp://127.0.0.1:{port}"
        bin_dir = __import__("pathlib").Path(sys.executable).parent
        quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.procs = [subprocess.Popen([str(bin_dir / "dask"), "scheduler", "--host", "127.0.0.1", "--port",
                                        str(port), "--no-dashboard"], **quiet)]
        try:
            time.sleep(1.5)
            self.procs += [subprocess.Popen([str(bin_dir / "dask"), "worker", self.address, "--nthreads", "1",
                                             "--no-nanny", "--no-dashboard"], **quiet) for _ in range(2)]
            from dask.distributed import Client

            with Client(self.address, timeout=30) as client:
                client.wait_for_workers(2, timeout=60)
        except BaseException:
            self.end()
            raise

    def end(self):
        for p in self.procs[::-1]:
            if p.poll() is None:
                p.terminate()
        _ended(self.procs)


@pytest.mark.parametrize("verbose", [0, 1])
def test_the_command_line_prints_dask_messages_at_its_own_level(verbose):
    """distributed sets its loggers to INFO when imported: the command line prints their information only with -v,
    as it does its own, and their warnings always (a record logged directly, not a race of a lost scheduler)."""
    code = ("import logging\n"
            "from gistools.cli.main import cli\n"
            f"cli.callback(verbose={verbose})\n"
            "log = logging.getLogger('distributed.batched')\n"
            "log.setLevel(logging.INFO)\n"
            "log.info('Batched Comm Closed')\n"
            "log.warning('a worker is slow')\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    lines = run.stderr.strip().splitlines()
    expected = ["INFO distributed.batched: Batched Comm Closed"] if verbose else []
    assert lines == expected + ["WARNING distributed.batched: a worker is slow"], run.stderr
