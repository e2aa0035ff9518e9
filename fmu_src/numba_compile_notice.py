"""The notice before a first compile of the kernels: whether numba will load an entry point from its cache."""
from __future__ import annotations

import sys

from . import kernel_driver
from . import numba_cache

__all__ = ["kernels_cached", "compile_notice", "compile_done", "notice_checked"]

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
    # no duration is promised: it ranges from seconds to minutes with the machine and its load;
    # compile_done says how long it took
    print(f"hammerbit: compiling the solver kernels for this machine (once; cached in "
          f"{numba_cache.cache_root()})", file=stream, flush=True)
    return True


def compile_done(seconds: float, stream=None) -> None:
    """Say on stderr how long the compile that :func:`compile_notice` announced took."""
    stream = sys.stderr if stream is None else stream
    print(f"hammerbit: compiled the solver kernels in {seconds:.1f} s", file=stream, flush=True)


def notice_checked(entry: str) -> bool:
    """True once :func:`compile_notice` has looked at ``entry`` in this process."""
    return entry in _NOTICE_CHECKED
