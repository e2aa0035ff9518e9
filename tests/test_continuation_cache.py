"""The continuation's kernels cached on disk (hammerbit.continuation.kernel_cache): keyed on their sources and
the model's kernels they call, and loaded, not compiled, by a later process."""
import json
import subprocess
import sys

from hammerbit.continuation import correct_orbit, kernel_cache, monodromy, orbit_from_simulation
from hammerbit.model import numba_cache
from hammerbit.model.presets import preset

_LATER = r"""
import json
from hammerbit.continuation import correct_orbit, monodromy, orbit_from_simulation
from hammerbit.model.presets import preset
g = preset("paper-fig9").replace(a=0.2)
n, s = orbit_from_simulation(g)
correct_orbit(g, s, n)
st = monodromy.sensitivity_along.stats
print(json.dumps({"hits": sum(st.cache_hits.values()), "misses": sum(st.cache_misses.values())}))
"""


def test_the_kernels_are_keyed_on_the_models_kernels_they_call(monkeypatch):
    locator = monodromy.sensitivity_along._cache._impl.locator
    assert isinstance(locator, kernel_cache.ContinuationCacheLocator)
    assert locator.get_cache_path().startswith(numba_cache.cache_root())
    assert kernel_cache.continuation_digest() in locator.get_cache_path()
    # another model kernel digest (a change to the vector field they call) is another key
    now = kernel_cache.continuation_digest.__wrapped__()
    monkeypatch.setattr(numba_cache, "kernels_digest", lambda: "another model")
    assert kernel_cache.continuation_digest.__wrapped__() != now


def test_a_later_process_loads_the_compiled_kernels():
    g = preset("paper-fig9").replace(a=0.2)
    n, s = orbit_from_simulation(g)
    correct_orbit(g, s, n)  # compiled (and saved) or loaded here
    out = subprocess.run([sys.executable, "-c", _LATER], capture_output=True, text=True, timeout=600, check=True)
    stats = json.loads(out.stdout.strip().splitlines()[-1])
    assert stats == {"hits": 1, "misses": 0}, out.stderr
