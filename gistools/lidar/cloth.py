"""The Cloth Simulation Filter's one call, in a process of its own where the caller must stay stoppable.

``cloth-simulation-filter`` (the ``CSF`` module, SWIG-wrapped C++) holds Python's interpreter lock for the whole
simulation, seconds a tile: in the process that runs the command, neither Ctrl-C, SIGTERM, QGIS's Cancel nor the
command line's stop watchdog could act until it returns, and the tiles a thread pool runs beside it would wait
too. So the main process hands the call to a helper process (started once, kept for the run, stopped with the
command's other workers) and waits in short steps; a stop kills the helper at once. Worker processes, which their
parent stops, call the library directly.
"""

from __future__ import annotations

import threading
from concurrent.futures import FIRST_COMPLETED, wait

import numpy as np

_HELPER: dict = {}
_LOCK = threading.Lock()


def cloth_ground_indices(points: np.ndarray, settings: dict) -> np.ndarray:
    """Indices (int64) of the rows of ``points`` (n x 3, CRS units, shifted near 0) that the cloth calls ground.
    ``settings``: the CSF module's ``params`` fields (cloth_resolution, class_threshold, rigidness, time_step,
    interations, bSloopSmooth), in its spelling. Runs the simulation in this process."""
    import CSF

    csf = CSF.CSF()
    for name, value in settings.items():
        setattr(csf.params, name, value)
    csf.setPointCloud(np.ascontiguousarray(points, np.float64))
    ground, other = CSF.VecInt(), CSF.VecInt()
    csf.do_filtering(ground, other, exportCloth=False)
    return np.asarray(ground, np.int64)


def stoppable_cloth_ground_indices(points: np.ndarray, settings: dict) -> np.ndarray:
    """cloth_ground_indices, from the main process in the helper process (waited for in steps of 0.25 s, so that a
    signal, a Cancel or a run's stop reaches this thread); in a worker process, or where a helper could only be
    forked (a script without a ``__main__`` guard) or not started at all, in this process."""
    import multiprocessing
    from concurrent.futures.process import BrokenProcessPool

    from ..engine.batch import start_method
    from ..errors import Cancelled
    from ..progress import check_stop

    method, _warning = start_method()
    if multiprocessing.parent_process() is not None or method != "spawn":
        return cloth_ground_indices(points, settings)
    for attempt in (1, 2):  # a helper that died between calls (the system ended it): a new one, once
        pool = _helper(method)
        try:
            future = pool.submit(cloth_ground_indices, points, settings)
            while not wait([future], timeout=0.25, return_when=FIRST_COMPLETED)[0]:
                check_stop()
            return future.result()
        except BrokenProcessPool:
            _discard(pool)
            if attempt == 2:
                raise
        except (Cancelled, KeyboardInterrupt):
            _discard(pool)  # stopped: the simulation in the helper ends now, not when it is done
            raise
    raise AssertionError("unreachable")


def _helper(method: str):
    from ..engine.batch import ProcessPool
    from ..machine import usable_cpus

    with _LOCK:
        pool = _HELPER.get("pool")
        if pool is not None and not pool.closed and pool.lost_worker():  # ended by the system since the last call
            pool.close(futures=[None])
        if pool is None or pool.closed:
            # a process a core at most (61: Windows' limit), started as calls come (a ThreadPool's threads may call
            # at once); not tied to the thread that starts it (PDEATHSIG follows a thread): the helper's watchdog
            # ends it with this process
            workers = max(1, min(usable_cpus(), 61))
            pool = _HELPER["pool"] = ProcessPool(workers, method, warm=False, tie_to_thread=False)
        return pool


def _discard(pool) -> None:
    """Stop ``pool``'s processes now, and forget it if it is still the helper."""
    with _LOCK:
        if _HELPER.get("pool") is pool:
            del _HELPER["pool"]
    pool.close(futures=[None])


def close_helper() -> None:
    """End the helper processes (at the end of a run: a library or QGIS session does not keep them)."""
    with _LOCK:
        pool = _HELPER.pop("pool", None)
    if pool is not None:
        pool.join()
