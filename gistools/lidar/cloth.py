"""The Cloth Simulation Filter's one call, in a process of its own where the caller must stay stoppable.

``cloth-simulation-filter`` (the ``CSF`` module, SWIG-wrapped C++) holds Python's interpreter lock for the whole
simulation, seconds a tile: in the process that runs the command, neither Ctrl-C, SIGTERM, QGIS's Cancel nor the
command line's stop watchdog could act until it returns, and the tiles a thread pool runs beside it would wait
too. So the main process hands the call to a helper process (started once, kept for the run, stopped with the
command's other workers) and waits in short steps; a stop kills the helper at once. Worker processes, which their
parent stops, call the library directly.
"""

from __future__ import annotations

import os
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
    signal, a Cancel or a run's stop reaches this thread); in a worker process (or where no process can be
    started) in this process."""
    import multiprocessing

    from ..engine.batch import start_method

    method, _warning = start_method()
    if multiprocessing.parent_process() is not None or method is None:
        return cloth_ground_indices(points, settings)
    from ..progress import check_stop

    future = _helper(method).submit(cloth_ground_indices, points, settings)
    try:
        while not wait([future], timeout=0.25, return_when=FIRST_COMPLETED)[0]:
            check_stop()
        return future.result()
    except BaseException:
        _discard()  # a stop, or a helper that died: the next call starts a new one
        raise


def _helper(method: str):
    from ..engine.batch import ProcessPool

    with _LOCK:
        pool = _HELPER.get("pool")
        if pool is None or pool.closed:
            # a process a core at most, started as calls come (the threads of a ThreadPool may call at once)
            pool = _HELPER["pool"] = ProcessPool(os.cpu_count() or 1, method, warm=False)
        return pool


def _discard() -> None:
    with _LOCK:
        pool = _HELPER.pop("pool", None)
    if pool is not None:
        pool.close(futures=[None])  # stops its processes now, whatever they are running
