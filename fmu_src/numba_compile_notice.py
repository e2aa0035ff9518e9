"""The notice before a first compile of the kernels: whether numba will load an entry point from its cache."""
from __future__ import annotations

import sys

from . import kernel_driver
from . import numba_cache

__all__ = ["COMPILE_SECONDS", "kernels_cached", "compile_notice", "notice_checked"]

#: Wall time to compile each entry point with an empty cache [s] on a 2-core machine, for the
#: notice: the CLI cold start of ``benchmarks/bench_throughput.py`` (``advance_hammer``); the
#: general driver is a function of the same size.
COMPILE_SECONDS = {"advance_hammer": 12, "advance": 12}
_NOTICE_CHECKED = set()


def kernels_cached(entry: str) -> bool:
    """True if numba will load the kernel entry point ``entry`` from its cache.

    Reads numba's cache index of the entry point (a small pickle; numba itself
    reads it on the first call): an entry for this machine's code generator
    and the current source means no compile.  Unknown (numba internals changed):
    True, so no notice is shown rather than a wrong one.
    """
    disp = getattr(kernel_driver, entry)
    # numba internal (no public "is this cached?"): the dispatcher's cache index.
    # tests/test_numba_internals.py fails on a numba release that changes it.
    try:
        if disp.signatures:
            return True
        cache = disp._cache
        index = cache._cache_file._load_index()
        magic = disp.targetctx.codegen().magic_tuple()
        return any(key[1] == magic for key in index)
    except Exception:  # pragma: no cover - numba internals
        return True


def compile_notice(entry: str, stream=None) -> bool:
    """Say once per process on stderr that ``entry`` is about to compile (a cache miss).

    Returns True if the notice was printed.
    """
    if entry in _NOTICE_CHECKED:
        return False
    _NOTICE_CHECKED.add(entry)
    if kernels_cached(entry):
        return False
    stream = sys.stderr if stream is None else stream
    print(f"hammerbit: compiling the solver kernels for this machine (about "
          f"{COMPILE_SECONDS.get(entry, 60)} s, once; cached in {numba_cache.cache_root()})",
          file=stream, flush=True)
    return True


def notice_checked(entry: str) -> bool:
    """True once :func:`compile_notice` has looked at ``entry`` in this process."""
    return entry in _NOTICE_CHECKED
