"""Compressed tiles decoded in pass 1, kept for pass 2 in the same process.

A command that sees its neighbours' points (normalize, metrics with heights, chm) reads each tile twice: pass 1
cuts the edge strips its neighbours need, pass 2 makes the tile's product. A LAZ tile costs its decoding each time
(lazrs: about 2 M points a second on one core, 0.3 s for a tile of 600,000 points), so where both passes run in
this process (inline, or on its threads) pass 1 keeps the decoded tile and pass 2 takes it instead of decoding it
again. Kept tiles are bounded: tiles of one chunk of points (2 million), at most a quarter of the free memory (and
of the address space left under a ``ulimit -v``) and 2 GiB in all; another tile is decoded again, as without this.
Each kept tile is taken once, and only while its file's size and modification time are those it was read with.
"""

from __future__ import annotations

import os
import threading

from ..machine import address_space_left, free_memory

MOST_BYTES = 2 * 2**30

_lock = threading.Lock()
_kept: dict = {}  # path -> (stamp, LasData, bytes)


def _key(path) -> str:
    """The absolute path: a relative one names another file once the working folder changes (a notebook, QGIS)."""
    return os.path.abspath(path)


def _stamp(path) -> tuple[int, int]:
    st = os.stat(path)
    return int(st.st_size), int(st.st_mtime_ns)


def _budget() -> int:
    """Bytes the kept tiles may hold together."""
    room = [MOST_BYTES]
    for left in (free_memory(), address_space_left()):
        if left is not None:
            room.append(left // 4)
    return int(min(room))


def worth_keeping(info) -> bool:
    """True for a compressed tile (not COPC: its reader queries nodes) of at most one chunk of points (decoded in
    one call, as the chunked reading does: a stop waits no longer) whose decoded points fit beside the tiles kept
    now."""
    from .points import DEFAULT_CHUNK_SIZE

    if not info.compressed or int(info.point_count) > DEFAULT_CHUNK_SIZE or info.copc:
        return False
    need = int(info.point_count) * _record_bytes(info)
    with _lock:
        used = sum(b for _s, _l, b in _kept.values())
    return used + need <= _budget()


def _record_bytes(info) -> int:
    import laspy

    return laspy.PointFormat(int(info.point_format)).size


def keep(path, las) -> None:
    """Keep a tile decoded (a laspy LasData) for the pass that reads it next."""
    key = _key(path)
    with _lock:
        _kept[key] = (_stamp(path), las, int(las.points.array.nbytes))


def take(path):
    """The tile's decoded LasData kept by :func:`keep`, removed from the kept ones; None when it was not kept or
    its file changed since."""
    key = _key(path)
    with _lock:
        entry = _kept.pop(key, None)
    if entry is None:
        return None
    stamp, las, _bytes = entry
    try:
        return las if _stamp(path) == stamp else None
    except OSError:
        return None


def discard(paths) -> None:
    """Forget the tiles of ``paths`` (what a run kept and did not take: a tile that failed or was not made)."""
    with _lock:
        for p in paths:
            _kept.pop(_key(p), None)
