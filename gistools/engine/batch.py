"""Running one function per tile: inline, on local processes, or on a dask.distributed cluster.

One bad tile never stops the batch: its result is marked failed with the error's
one-line message, and the other tiles go on.
"""

from __future__ import annotations

import contextvars
import ctypes
import logging
import multiprocessing
import os
import shutil
import signal
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, ThreadPoolExecutor, wait
from pathlib import Path

from ..errors import Cancelled, ClusterLostError, GistoolsError, InputError, OutOfMemoryError
from ..io.atomic import raise_output_error
from ..machine import address_space_limit, free_memory, usable_cpus
from ..parameters import option
from ..progress import check_interrupt, run_stoppable

log = logging.getLogger(__name__)

__all__ = ["ProcessPool", "ThreadPool", "DaskPool", "make_pool", "auto_workers", "run_each", "drive", "fail", "worker_count", "machine_error"]


def fail(result, err: BaseException, out=None) -> None:
    """Mark a tile's result failed with a one-line message; a write failure of the disk or folder ``out``
    (full, read-only) is raised instead as an OutputError: it stops the run, it is no tile's fault."""
    check_interrupt()  # a Ctrl-C that a C extension turned into another error: the run stops
    if out is not None:
        raise_output_error(err, out)
    machine_error(err, getattr(result, "name", None) or getattr(result, "path", ""))
    result.status = "failed"
    result.error = str(err) if isinstance(err, GistoolsError) else f"{result.path}: {type(err).__name__}: {err}"



def machine_error(err: BaseException, tile) -> None:
    """Raise the run's error for a tile that met the machine's limits (out of memory, a worker killed by the
    system): no tile's fault, so the run stops with the numbers and the fix instead of blaming the tile."""
    from concurrent.futures.process import BrokenProcessPool

    if isinstance(err, GistoolsError):
        return
    if isinstance(err, MemoryError):
        raise out_of_memory(f"while making tile {tile}") from None
    if isinstance(err, BrokenProcessPool):
        raise out_of_memory(f"while making tile {tile}", killed=True) from None


def out_of_memory(where: str, killed: bool = False, fix: str | None = None) -> OutOfMemoryError:
    """The run's error when the machine's memory (or the process's ``ulimit -v``) ran out ``where``, with the
    numbers and the fix."""
    limit, memory = address_space_limit(), free_memory()
    if limit is not None:
        have = f" (this process may map {limit / 1e9:.1f} GB: ulimit -v)"
    else:
        have = f" ({memory / 1e9:.1f} GB available now)" if memory is not None else ""
    fix = fix or (f"Run with fewer {option('jobs')}, a smaller {option('chunk_size')} or a larger "
                  f"{option('cell_size')}, or on a machine with more memory")
    if killed:
        return OutOfMemoryError(f"a worker process was killed by the system {where} (most often: out of memory{have})",
                                hint=fix)
    return OutOfMemoryError(f"the machine ran out of memory {where}{have}", hint=fix)


def python_executable() -> str:
    """The Python interpreter for worker processes.

    Inside QGIS (desktop or qgis_process) ``sys.executable`` is the QGIS program itself, and
    spawning it would start QGIS; the interpreter beside the running Python library is used then.
    """
    exe = sys.executable or ""
    if os.path.basename(exe).lower().startswith("python"):
        return exe
    # Windows: pythonw.exe first, so that workers started from QGIS open no console window each
    names = ("pythonw.exe", "python.exe", "python3.exe") if os.name == "nt" else (
        f"python{sys.version_info[0]}.{sys.version_info[1]}", "python3")
    for folder in (os.path.join(sys.exec_prefix, "bin"), sys.exec_prefix, os.path.join(sys.base_exec_prefix, "bin")):
        for name in names:
            candidate = os.path.join(folder, name)
            if os.path.isfile(candidate):
                return candidate
    return shutil.which("python3") or exe


def timed(fn, args):
    """(fn(*args), seconds it took)."""
    t = time.perf_counter()
    value = fn(*args)
    return value, time.perf_counter() - t


def worker_timed(fn, args):
    """timed() in a worker process (local pool or Dask worker), with keep_freed_memory() and one LAZ decoder thread."""
    keep_freed_memory()
    one_decoder_thread()
    return timed(fn, args)


# Thread pools of numeric libraries in worker processes: one thread each, as Dask's nanny sets them. The
# processes are the parallelism; OpenBLAS's idle threads otherwise spin on the cores the other workers need.
# A variable among these that the user set is respected (the limit is then theirs).
WORKER_THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
                     "NUMEXPR_NUM_THREADS")


def one_thread_per_worker() -> None:
    """In a worker process: its BLAS and OpenMP pools limited to one thread, those loaded later by
    WORKER_THREAD_ENV in the worker's own environment, those loaded already by threadpoolctl, unless the user set
    one of WORKER_THREAD_ENV. Changes nothing in the parent (its environment included)."""
    if any(k in os.environ for k in WORKER_THREAD_ENV):
        return
    for k in WORKER_THREAD_ENV:  # the pools loaded later (numpy, scipy: imported when a task needs them) start at 1
        os.environ[k] = "1"
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # an install without it: the pools loaded already keep their size
        return
    threadpool_limits(limits=1)  # the pools loaded already (by the worker's start)


def worker_thread_environment() -> None:
    """For the command line, a process gistools owns: WORKER_THREAD_ENV set to 1 where the user set none, so that
    the workers it spawns load numpy's and scipy's OpenBLAS with no thread pool (threadpoolctl, in each worker's
    initializer, can only shrink a pool that exists: its threads spin about 0.1 s of CPU a worker after the import,
    while the other workers start). The library never calls it: in QGIS other threads read the environment while
    a plugin runs, and setenv is not safe beside them."""
    if any(k in os.environ for k in WORKER_THREAD_ENV):
        return
    for k in WORKER_THREAD_ENV:
        os.environ[k] = "1"


def parent_gone(parent: int) -> bool:
    """Whether this worker's parent process has ended: multiprocessing's handle on it where this process was started
    by multiprocessing (every system: on Windows ``os.getppid()`` keeps a dead parent's id), else the parent's id."""
    import multiprocessing

    proc = multiprocessing.parent_process()
    if proc is not None:
        try:
            return not proc.is_alive()
        except (OSError, ValueError):
            pass
    return os.getppid() != parent


def _watch_parent(parent: int) -> None:
    while True:
        time.sleep(0.5)
        if parent_gone(parent):  # the parent died (kill -9, a crash): this worker is an orphan
            os._exit(1)


def one_decoder_thread() -> None:
    """In a worker process: LAZ decoded on one thread (lazrs decodes a file's chunks on a rayon pool of one thread a
    core, whose idle threads spin on the cores the other workers need: on the dense benchmark block, two workers
    read LAZ 12 % faster this way, and their TINs ran faster beside them), unless the user set RAYON_NUM_THREADS.
    Takes effect where the pool is not started yet (before the worker's first LAZ file). GeoTIFFs are compressed
    on one thread there too (GDAL_NUM_THREADS, read by gistools.io.raster.compression_threads), unless set."""
    os.environ.setdefault("RAYON_NUM_THREADS", "1")
    os.environ.setdefault("GDAL_NUM_THREADS", "1")


_MEMORY_KEPT = False


def keep_freed_memory() -> bool:
    """Where the C library is glibc: large arrays a tile frees stay in the process's heap for the next tile, instead
    of going back to the system and being faulted in (and zeroed) again page by page: a third of the time of
    ``gistools ground`` on the benchmark block was that system time (and about 12 % of a TIN's). For processes that
    do tile after tile (the command line, the pool's and Dask's workers); the memory high-water mark then stays
    with the process until it ends. No large block is mmap'ed (M_MMAP_MAX 0: glibc refuses an M_MMAP_THRESHOLD
    above 32 MiB, smaller than a county tile's grids) and the heap is not trimmed. Once per process."""
    global _MEMORY_KEPT
    if _MEMORY_KEPT or not sys.platform.startswith("linux"):
        return _MEMORY_KEPT
    if address_space_limit() is not None:
        return _lean_address_space()
    _MEMORY_KEPT = True
    try:
        libc = ctypes.CDLL("libc.so.6")
        m_trim_threshold, m_mmap_max = -1, -4  # malloc.h
        return bool(libc.mallopt(m_mmap_max, 0)) and bool(libc.mallopt(m_trim_threshold, 2**31 - 1))
    except (OSError, AttributeError):  # not glibc
        return False


def _lean_address_space() -> bool:
    """Under an address-space limit (``ulimit -v``) memory is mapped sparingly instead: the freed heap goes back to
    the system, glibc keeps one heap arena (each thread's arena reserves 64 MiB of address space) and LAZ decodes on
    one thread (no pool of thread stacks), so the limit holds the run's arrays, not reservations."""
    os.environ.setdefault("RAYON_NUM_THREADS", "1")
    try:
        ctypes.CDLL("libc.so.6").mallopt(-8, 1)  # M_ARENA_MAX
    except (OSError, AttributeError):
        pass
    return False


def _worker_start(parent: int, main_thread: bool) -> None:
    """In each worker process: leave Ctrl-C (and SIGTERM, SIGHUP) to the parent (which stops the workers and cleans up, so a
    Ctrl-C prints one line, not a traceback per worker), and die with the parent: Linux's
    PR_SET_PDEATHSIG when the parent's main thread started the pool (the signal follows the thread), and
    everywhere a watchdog thread that exits once the parent is gone."""
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):  # sent to the whole process group: the parent handles them
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)
    one_thread_per_worker()
    one_decoder_thread()
    keep_freed_memory()
    if main_thread and sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if parent_gone(parent):
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True, name="gistools-parent-watch").start()


def has_main_guard(path: Path) -> bool:
    """Whether the script ``path`` runs its work under ``if __name__ == "__main__":`` at its top level (parsed,
    not matched as text: a guard in a comment or a string does not count)."""
    import ast

    try:
        tree = ast.parse(Path(path).read_bytes())
    except (OSError, SyntaxError, ValueError):
        return False

    def is_guard(test) -> bool:
        if not (isinstance(test, ast.Compare) and len(test.ops) == 1 and isinstance(test.ops[0], ast.Eq)):
            return False
        sides = [test.left, test.comparators[0]]
        names = [s for s in sides if isinstance(s, ast.Name) and s.id == "__name__"]
        values = [s for s in sides if isinstance(s, ast.Constant) and s.value == "__main__"]
        return len(names) == 1 and len(values) == 1

    return any(isinstance(node, ast.If) and is_guard(node.test) for node in tree.body)


def start_method() -> tuple[str | None, str | None]:
    """How local workers start here: ("spawn" | "fork" | None for no workers, a warning or None).

    spawn (the safe default) re-imports the main script in every worker: that is harmless under an
    ``if __name__ == "__main__":`` guard, in a notebook or an interactive session, but a script without the
    guard would run again in each worker, and a script read from standard input cannot be re-read. Then
    the workers are forked (Linux), or the tiles run one at a time elsewhere; either way with a warning.
    """
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    spec = getattr(main, "__spec__", None)
    if spec is not None and getattr(spec, "origin", None):
        path = spec.origin  # python -m module: the module is re-imported by name
    if path is None:
        return "spawn", None  # interactive, a notebook: nothing of __main__ is re-run
    p = Path(path)
    if not p.is_file() and any(parent.is_file() for parent in p.parents):
        return "spawn", None  # a zip application: pip's gistools.exe launcher, re-imported by name, never re-run
    if p.is_file():
        if has_main_guard(p):
            return "spawn", None
        reason = f"{p.name} has no 'if __name__ == \"__main__\":' guard"
    else:
        reason = "the script comes from standard input"
    if sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods():
        return "fork", f"{reason}: the worker processes are forked (put the call under the guard to spawn them)"
    return None, f"{reason}: the tiles run one at a time (put the call under the guard to use several processes)"


_STARTED: list = []  # the executors this process started, joined by join_workers


def join_workers() -> None:
    """Wait until every worker process this process started has exited: the command line calls it before it
    returns, so no worker outlives the command. (A pool closed after its last task lets its workers end on their
    own, overlapping what the run does next; this waits for the last of them.) multiprocessing's resource tracker,
    which the pools started, is stopped and reaped too (else it would end a moment after the command)."""
    import gc
    from multiprocessing import resource_tracker

    while _STARTED:
        _STARTED.pop().join()
    tracker = getattr(resource_tracker, "_resource_tracker", None)
    if getattr(tracker, "_pid", 0) is None:  # no tracker runs (no pool started one): nothing to collect or stop
        return
    gc.collect()  # the pools' queues and their semaphores, unregistered from the tracker as they go
    from multiprocessing.synchronize import SemLock

    if any(isinstance(o, SemLock) for o in gc.get_objects()):  # still held (an interrupted run's traceback): the
        return  # tracker must outlive them, or their clean-up at exit would find them gone; it ends with us
    stop = getattr(getattr(resource_tracker, "_resource_tracker", None), "_stop", None)
    if stop is not None:  # CPython's own teardown does the same at exit; here it happens before we return
        try:
            stop()
        except Exception:  # noqa: BLE001 - a tracker already gone, or one that is not ours
            pass


class ProcessPool:
    """Local worker processes (spawn, not fork: forking a process that holds GDAL / BLAS threads can deadlock;
    fork only where spawn cannot work: see start_method).

    Workers die with the parent (kill -9 included) and ignore Ctrl-C; closing the pool after an error or an
    interrupt stops them at once instead of waiting for their tiles."""

    def __init__(self, jobs: int, method: str = "spawn", warm: bool = True, tie_to_thread: bool = True):
        ctx = multiprocessing.get_context(method)
        python = python_executable()
        if python != sys.executable and method == "spawn":
            ctx.set_executable(python)
        self.workers = jobs
        self.pool = ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=_worker_start,
                                        initargs=(os.getpid(), tie_to_thread and
                                                  threading.current_thread() is threading.main_thread()))
        self._manager, self._processes, self.closed = None, [], False
        _STARTED.append(self)
        for _ in range(jobs if warm else 0):  # every worker starts now (a task each), importing while the parent plans
            self.pool.submit(os.getpid)

    def submit(self, fn, *args):
        return self.pool.submit(fn, *args)

    def wait_first(self, futures):
        return wait(futures, return_when=FIRST_COMPLETED)[0]

    def close(self, futures=()):
        """Shut the workers down; ``futures`` still pending (an error or Ctrl-C): stop the workers now, and wait
        for them. With every task done, the workers exit on their own while the caller goes on (their
        interpreters' teardown, about 0.1 s, overlaps the mosaics, the reports or the map); Python joins them
        at its exit at the latest."""
        self.closed = True
        # what join() waits for: shutdown(wait=False) lets go of the executor's thread and processes
        self._manager = getattr(self.pool, "_executor_manager_thread", None) or self._manager
        self._processes = list((getattr(self.pool, "_processes", None) or {}).values()) or self._processes
        if futures:  # not cancelled here: the pool's own thread, finding its workers killed, marks every pending
            # future failed, and one cancelled from this thread meanwhile stops it with a traceback on Python 3.11
            # (InvalidStateError); shutdown(cancel_futures=True) cancels the rest from that thread
            for proc in self._processes:
                if proc.is_alive():
                    proc.kill()
        if futures or self.lost_worker():  # a worker dead, whoever waits: its pipe may hold a blocked writer
            _unblock_feeder(self.pool)
        self.pool.shutdown(wait=bool(futures), cancel_futures=True)

    def lost_worker(self) -> bool:
        """True when one of the pool's processes has ended (the system killed it between two calls)."""
        return any(proc.exitcode is not None for proc in (getattr(self.pool, "_processes", None) or {}).values())

    def join(self):
        """Close the pool if it is open, and wait until its workers and its manager thread have ended."""
        self.close()
        for proc in self._processes:
            proc.join()
        if self._manager is not None:
            self._manager.join()


def _stdlib_unblocks() -> bool:
    """True where Python's process pool closes the dead workers' pipe itself (cpython issue 94777 fixed)."""
    import inspect
    from concurrent.futures import process

    try:
        return "_reader.close" in inspect.getsource(process._ExecutorManagerThread.terminate_broken)
    except (OSError, TypeError, AttributeError):  # no source at hand (a frozen build)
        return sys.version_info >= (3, 12)


def _unblock_feeder(executor) -> None:
    """Let the executor's queue feeder go when its readers are dead: a worker killed while a task's arguments were
    being written to it leaves the feeder thread blocked on a full pipe, and Python before 3.11.5 then waits for it
    for ever when the pool is shut down (cpython issue 94777). Closing this process's copy of the pipe's reading end
    (and on Windows its writing end, cpython issue 107219) is what later Pythons do."""
    if _stdlib_unblocks():
        return  # the pool closes it itself, once its futures have failed: closing it here too would race with it
    queue = getattr(executor, "_call_queue", None)
    ends = [getattr(queue, "_reader", None)] + ([getattr(queue, "_writer", None)] if sys.platform == "win32" else [])
    for end in ends:
        try:
            end.close()
        except (AttributeError, OSError):  # gone already, or a Python that keeps its queues otherwise
            pass


class ThreadPool:
    """Tiles on threads of this process: what ``jobs="auto"`` runs below a worker process's worth of work. No
    interpreter to start, nothing to import again, no points copied between processes: the compiled kernel, numpy,
    GDAL, the LAZ decoder and shapely release the GIL in their loops, so the tiles share the cores. A thread runs
    ``timed``: the process's own LAZ decoding and GeoTIFF compression threads stay as they are.

    Closing the pool after an error or an interrupt stops the running tiles at their next compiled-kernel call or
    chunk read (progress.check_stop) and waits for them: no thread outlives the run. A tile's own progress (a
    tile's read in ``rasters``) reaches the caller's callback from its thread, so a Cancel there stops the run."""

    queued = 1  # tasks in flight a thread (engine.passes): it takes the next one at once
    shares_process = True  # the tiles see the caller's progress callback (engine.passes)

    def __init__(self, jobs: int):
        self.workers = jobs
        self.stop = threading.Event()
        self.pool = ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="gistools-tile")

    def submit(self, fn, *args):  # in the caller's context: messages name options as the caller speaks
        return self.pool.submit(contextvars.copy_context().run, run_stoppable, self.stop,
                                timed if fn is worker_timed else fn, *args)

    def wait_first(self, futures):
        while True:  # in short waits: a Ctrl-C reaches the waiting thread on every platform
            done = wait(futures, timeout=0.25, return_when=FIRST_COMPLETED)[0]
            if done:
                return done

    def close(self, futures=()):
        if futures:
            self.stop.set()
        self.pool.shutdown(wait=True, cancel_futures=True)


class DaskPool:
    """Tiles as tasks on a dask.distributed cluster: a scheduler address, or "local" for a LocalCluster."""

    def __init__(self, address: str, jobs: int | None):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise InputError(
                f"{option('scheduler')} needs dask.distributed, which is not installed", hint="pip install 'gistools[dask]'"
            ) from None
        self.cluster = None
        self.workers = jobs
        if address == "local":
            self.cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None)
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(address, timeout=10)
            except Exception as err:  # no answer, a protocol this install lacks (ucx), TLS without certificates
                why = str(err).splitlines()[0][:200] if str(err) else type(err).__name__
                raise InputError(f"{option('scheduler', address)}: cannot connect to a Dask scheduler there ({why})",
                                 hint="Start one (dask scheduler), check the address, or give tls:// its "
                                      "certificates in Dask's configuration") from None
            if self.workers is None:  # jobs auto: the cluster's threads
                self.workers = max(1, sum(self.client.nthreads().values()))

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False)

    def wait_first(self, futures):
        """The futures done first; a scheduler lost on the way is the run's error, in one line (ClusterLostError),
        rather than each of its tiles' (dask cancels every future it held)."""
        from dask.distributed import wait as dask_wait

        try:
            done = dask_wait(list(futures), return_when="FIRST_COMPLETED").done
        except Exception as err:  # FuturesCancelledError: "scheduler-connection-lost"
            if self._lost(err):
                raise self._lost_error() from None
            raise
        if any(fut.status == "cancelled" for fut in done) and self._lost():
            raise self._lost_error()
        return done

    def _lost(self, err: Exception | None = None) -> bool:
        return "scheduler-connection-lost" in str(err or "") or getattr(self.client, "status", "") != "running"

    def _lost_error(self) -> ClusterLostError:
        address = getattr(self.client.scheduler, "address", None) or "the cluster"
        return ClusterLostError(f"{option('scheduler', address)}: the Dask scheduler was lost in the middle of the run; "
                                "the tiles finished are kept",
                                hint=f"Start the scheduler and its workers again (or run on this machine with "
                                     f"{option('jobs')}) and rerun the same command: it resumes with the tiles not "
                                     "finished")

    def close(self, futures=()):
        import logging

        if self.client is None:
            return
        lost = self._lost()
        names = [n for n in list(logging.root.manager.loggerDict) if n.split(".")[0] == "distributed"] if lost else []
        quiet = {name: logging.getLogger(name).disabled for name in names}
        for name in names:  # the client's attempts to reconnect end in tracebacks it logs: the run's line says it
            logging.getLogger(name).disabled = True
        try:
            if futures and not lost:
                self.client.cancel(list(futures))
            self.client.close()
        except Exception:  # noqa: BLE001 - a scheduler already gone: nothing is left to cancel there
            pass
        finally:
            for name, disabled in quiet.items():
                logging.getLogger(name).disabled = disabled
        if self.cluster is not None:
            try:
                self.cluster.close()
            except Exception:  # noqa: BLE001 - a local cluster whose scheduler died: its processes end with ours
                pass
        self.client = self.cluster = None


def run_each(fn, arglist, pool, results, names, on_done, tick, verb, out=None) -> None:
    """Run fn over arglist (inline when ``pool`` is None, else on the pool); a failure marks its tile
    failed and the rest go on, but a failed write to the folder ``out`` (disk full) stops the run."""
    if not arglist:
        return
    if pool is None:
        for name, args in zip(names, arglist):
            if results[name].status == "failed":
                continue
            try:
                value, seconds = timed(fn, args)
                on_done(args[0], value, seconds)
            except Cancelled:
                raise
            except Exception as err:  # one bad tile never stops the batch; it is reported
                fail(results[name], err, out)
            tick(f"{name} {verb}")
        return
    pending = {pool.submit(worker_timed, fn, args): (name, args) for name, args in zip(names, arglist)
               if results[name].status != "failed"}
    try:
        while pending:
            for fut in pool.wait_first(pending):
                name, args = pending.pop(fut)
                try:
                    value, seconds = fut.result()
                    on_done(args[0], value, seconds)
                except Cancelled:  # the user's Cancel, from a tile's progress on a thread of this process
                    raise
                except Exception as err:  # incl. a worker crash: reported per tile
                    fail(results[name], err, out)
                tick(f"{name} {verb}")
    except BaseException:
        pool.close(list(pending))
        raise


WORKER_BASE_BYTES = 250_000_000  # a worker with numpy, scipy, rasterio, pyproj and laspy imported


def worker_count(jobs: int, n_tasks: int, task_bytes: int | None = None, *, warn=None,
                 base: int = WORKER_BASE_BYTES, noun: str = "workers") -> int:
    """The workers a run starts: ``jobs``, but never more than its tasks, the usable CPUs (with a warning) or what
    the available memory holds at ``base`` plus ``task_bytes`` a worker (with a warning; threads share the process:
    ``base`` 0)."""
    warn = warn or (lambda text: log.warning("gistools: %s", text))
    count = max(1, min(int(jobs), max(int(n_tasks), 1)))
    cpus = usable_cpus()
    if count > cpus:
        warn(f"{jobs} jobs asked for, {cpus} CPUs here: running {cpus} at a time")
        count = cpus
    memory = free_memory()  # each worker has its own address space: the machine's memory is what they share
    if memory is not None and count > 1:
        each = max(int(base) + int(task_bytes or 0), 1)
        fits = max(1, int(0.8 * memory // each))
        if fits < count:
            warn(f"{count} {noun} of about {each / 1e9:.1f} GB each do not fit in the {memory / 1e9:.1f} GB of memory "
                 f"available: running {fits} at a time")
            count = fits
    return count


# The points of work that repay starting one more worker process. A worker imports numpy, scipy, rasterio, pyproj
# and laspy (about 1.2 s of CPU) and decodes LAZ on one thread; below this the tiles run on threads of the command's
# own process (ThreadPool), which start at once and decode a file on every core: on 2 cores the threads are as fast
# as 2 workers up to the 16-tile Levy block (26 M points), 2 workers a little faster there (benchmarks/bench_jobs.py).
POINTS_PER_WORKER = 5_000_000
TASKS_PER_WORKER = 8  # where the work is not known in points (a step rerun over raster tiles): tiles a worker repays


def auto_workers(n_tasks: int, points: int | None = None) -> int:
    """The workers ``jobs="auto"`` starts: one per :data:`POINTS_PER_WORKER` points of the tasks (``points``; where
    unknown, one per :data:`TASKS_PER_WORKER` tasks), never more than the tasks or the usable CPUs; 1 (this process,
    no worker: its threads, see make_pool) below that."""
    by_work = int(points) // POINTS_PER_WORKER if points is not None else int(n_tasks) // TASKS_PER_WORKER
    return max(1, min(by_work, max(int(n_tasks), 1), usable_cpus()))


def make_pool(jobs, scheduler: str | None, n_tasks: int, task_bytes: int | None = None, points: int | None = None):
    """A DaskPool for a scheduler address, a ProcessPool for more than one worker (``jobs`` capped by
    :func:`worker_count`: never more workers than tasks, CPUs or the memory holds), else None (inline). ``jobs``
    "auto": :func:`auto_workers` from the tasks' ``points``; below one worker's worth, a ThreadPool of one thread a
    usable CPU (capped by the tasks and the memory) when there are several tasks."""
    if scheduler:
        if jobs == "auto":  # a cluster: as many tasks in flight as its workers have threads; local: the CPUs
            jobs = usable_cpus() if scheduler == "local" else None
        return DaskPool(scheduler, jobs if scheduler != "local" else worker_count(jobs, n_tasks, task_bytes))
    if jobs == "auto":
        jobs = auto_workers(n_tasks, points)
        # threads share the process's address space: under a ``ulimit -v`` each tile's read checks what is left
        # (io.points.room_to_decode), which another thread's read could take between the check and the decode
        threads = (worker_count(usable_cpus(), n_tasks, task_bytes, base=0, noun="tiles")
                   if jobs == 1 and n_tasks > 1 and address_space_limit() is None else 1)
        where = (f"{jobs} worker processes" if jobs > 1 else f"{threads} threads in this process" if threads > 1
                 else "in this process")
        log.info("gistools: jobs auto: %s (%d tasks%s)", where, n_tasks,
                 "" if points is None else f", {points / 1e6:.1f} M points")
        if jobs == 1:
            return ThreadPool(threads) if threads > 1 else None
    jobs = worker_count(jobs, n_tasks, task_bytes) if jobs > 1 else 1
    if jobs > 1 and n_tasks > 1:
        method, warning = start_method()
        if warning:
            log.warning("gistools: %s", warning)
        return ProcessPool(jobs, method) if method else None
    return None


def drive(pool, owned: bool, in_flight: int, next_task, start, pending: dict, finish) -> None:
    """Keep up to ``in_flight`` tasks going: ``next_task()`` gives (kind, name) or None, ``start(kind, name)`` runs it
    inline (``pool`` None) or puts its future in ``pending``; ``finish(kind, name, value, seconds, err)`` takes each
    result (a worker's error, a crash included, as ``err``). On any error or Ctrl-C the pending tasks are cancelled
    and the pool is stopped at once (a caller's shared pool too: the run is over); an ``owned`` pool is closed at
    the end."""
    try:
        while True:
            while len(pending) < in_flight and (task := next_task()) is not None:
                start(*task)
            if not pending:  # everything started has finished and nothing more can start
                break
            for fut in pool.wait_first(pending):
                kind, name = pending.pop(fut)
                try:
                    value, seconds = fut.result()
                except Cancelled:  # the user's Cancel, from a tile's progress on a thread of this process
                    raise
                except Exception as err:  # incl. a worker crash: reported per tile
                    finish(kind, name, None, 0.0, err)
                    continue
                finish(kind, name, value, seconds, None)
    except BaseException:
        if pool is not None:  # the run stops: its workers too, the caller's pool included, before the caller's
            pool.close(list(pending))  # clean-up removes the scratch they might still be writing into
        raise
    finally:
        if pool is not None and owned:
            pool.close()

