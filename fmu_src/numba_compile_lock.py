"""One first compile of a kernel entry point per cache at a time: other processes wait, then load it.

Processes that start together on an empty cache (a study's Dask workers,
pytest-xdist's workers) would each compile the same entry point, since numba's
cache has no lock: minutes of CPU each on two cores.  The first process to miss
the cache takes a file lock named for the entry point in the cache directory
and compiles it; the others block on that lock and, once it is released, find
the entry point cached and load it.  Only the compile is held under the lock,
never an integration.  The lock is an ``flock`` on an open file, so the system
releases it when its holder exits, killed or not.  Without ``fcntl`` (Windows)
or a writable cache directory (an FMU in a read-only place), nothing is locked
and each process compiles on its own, as numba would.
"""
from __future__ import annotations

import contextlib
import os

from . import numba_cache

try:
    import fcntl
except ImportError:  # pragma: no cover -- Windows: no flock, no lock
    fcntl = None

__all__ = ["compiling", "lock_path", "file_lock"]

#: the lock file of an entry point: ``<cache root>/<entry><LOCK_SUFFIX>``
LOCK_SUFFIX = ".compile-lock"


def lock_path(entry: str) -> str:
    """The lock file of ``entry`` in this process's cache directory."""
    return os.path.join(numba_cache.cache_root(), entry + LOCK_SUFFIX)


def compiling(entry: str):
    """Hold the compile lock of ``entry`` (after any other process holding it has let go)."""
    return file_lock(lock_path(entry))


@contextlib.contextmanager
def file_lock(path: str):
    """Hold an exclusive lock on the file ``path`` (created, with its directory, if missing); where
    it cannot be created, or without ``fcntl``, go on unlocked."""
    fd = _open(path)
    try:
        if fd is not None:
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        if fd is not None:
            os.close(fd)            # releases the lock


def _open(path: str):
    if fcntl is None:
        return None
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        return os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError:                 # a read-only cache: compile unlocked
        return None
