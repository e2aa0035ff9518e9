"""The numba internals the kernels rely on: each test fails on a numba release that removes or changes one.

numba has no public interface for these (docs/architecture.md lists them);
the modules that use them fall back quietly, so only these tests say when a
numba upgrade broke one.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

from hammerbit.model import kernel_forces, numba_cache, numba_dispatch


def test_the_content_cache_locator_is_registered_and_used():
    from numba.core import caching
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl")
    # first in numba's list (an FMU runtime loaded in this process puts its own copy before it)
    ours = [c for c in impl._locator_classes if c.__name__ == "ContentHashCacheLocator"]
    assert numba_cache.ContentHashCacheLocator in ours
    assert impl._locator_classes[:len(ours)] == ours
    locator = kernel_forces.kinetic_friction._cache._impl.locator
    assert isinstance(locator, numba_cache.ContentHashCacheLocator)
    assert locator.get_cache_path().startswith(numba_cache.cache_root())
    assert numba_cache.kernels_digest() in locator.get_cache_path()


_FRESH = r"""
import json
from hammerbit.model.numba_compile_notice import kernels_cached
from hammerbit.model import kernel_driver
index = kernel_driver.advance._cache._cache_file._load_index()
print(json.dumps({"cached": kernels_cached("advance"), "index": len(index)}))
"""


def test_the_cache_index_says_cached_or_not(tmp_path):
    """With an empty cache the index is read (empty) and says 'not cached'; the notice's fallback
    on an unknown numba would say 'cached' instead."""
    env = dict(os.environ, HAMMERBIT_CACHE_DIR=str(tmp_path))
    r = subprocess.run([sys.executable, "-c", _FRESH], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout.strip().splitlines()[-1]) == {"cached": False, "index": 0}


def test_an_entry_point_is_found_for_compiled_arguments():
    y = np.zeros(4)
    p = np.zeros(14)
    kernel_forces.overlap(y, p)                        # compiled (or loaded) for these types
    ep = numba_dispatch.entry_point(kernel_forces.overlap, (y, p))
    assert ep is not kernel_forces.overlap             # the dispatcher would be the fallback
    y[0] = 0.7
    assert ep(y, p) == kernel_forces.overlap(y, p) == 0.7
