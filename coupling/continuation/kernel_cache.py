"""The numba cache of the continuation's kernels: keyed on their own sources and on the model's kernels they call.

numba's own cache entry of a kernel holds the compiled code of its callees
but is invalidated only by a change of the kernel's own file.  The
variational equations call the model's vector field (``kernel_forces``), so
their entries are keyed on the content of this package's kernel modules
(:data:`KERNEL_MODULES`) and on the model's kernel digest
(:func:`hammerbit.model.numba_cache.kernels_digest`): a change to either
misses the cache, and the first ``hammerbit continue`` of a process loads the
compiled code instead of compiling it.
"""
from __future__ import annotations

import functools
import hashlib
import os

from hammerbit.model import numba_cache

__all__ = ["KERNEL_MODULES", "continuation_digest", "ContinuationCacheLocator"]

_HERE = os.path.dirname(os.path.abspath(__file__))

#: the modules of this package that hold cached numba kernels
KERNEL_MODULES = ("monodromy.py", "variational.py")


@functools.lru_cache(maxsize=1)
def continuation_digest() -> str:
    """SHA-256 (shortened) of the continuation's kernel modules and of the model's kernels."""
    h = hashlib.sha256(numba_cache.kernels_digest().encode())
    for name in KERNEL_MODULES:
        h.update(name.encode() + b"\0")
        with open(os.path.join(_HERE, name), "rb") as fh:
            h.update(fh.read())
    return h.hexdigest()[:20]


class ContinuationCacheLocator(numba_cache.ContentHashCacheLocator):
    """The cache locator of this package's kernels: the model's cache directory, keyed on
    :func:`continuation_digest`."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        module = getattr(py_func, "__module__", None) or os.path.splitext(os.path.basename(py_file))[0]
        self._cache_path = os.path.join(numba_cache.cache_root(), f"{module}-{continuation_digest()}")

    @classmethod
    def from_function(cls, py_func, py_file):
        if not py_file or os.path.dirname(os.path.abspath(py_file)) != _HERE or not os.path.exists(py_file):
            return None
        return cls(py_func, py_file)


numba_cache.register_locator(ContinuationCacheLocator)
