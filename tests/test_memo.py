"""hammerbit.memo: a remembered result is that of its own arrays, shared read-only, and bounded.

Oracles: the computations themselves, done again without the memo (``np.linalg.eigvals``, the
modal form rebuilt as ``T lam T^-1``)."""
from __future__ import annotations

import numpy as np
import pytest

from hammerbit.memo import MEMO_SIZE, digest, memo


def test_the_key_tells_shapes_types_values_and_extras_apart():
    a = np.arange(6.0)
    b = a.copy()
    b[5] = np.nextafter(b[5], 6.0)              # one ulp in the last entry
    keys = {digest("t", a), digest("t", a.reshape(2, 3)), digest("t", a.astype(np.float32)),
            digest("t", b), digest("t", a, extra=1e-3),
            digest("u", a)}
    assert len(keys) == 6
    assert digest("t", a) == digest("t", a.copy()) == digest("t", np.asfortranarray(a))


def test_a_result_is_computed_once_shared_read_only_and_the_oldest_dropped_first():
    calls = []

    def compute(x):
        calls.append(x)
        return np.full(3, float(x))

    key = digest("memo test", np.array([0.5]))
    first = memo(key, lambda: compute(0.5))
    assert memo(key, lambda: compute(-1.0)) is first and calls == [0.5]
    with pytest.raises(ValueError):
        first[0] = 2.0                          # shared: read-only
    for i in range(MEMO_SIZE):                  # as many newer results as the memo keeps
        memo(digest("memo test", np.array([float(i)])), lambda i=i: compute(i))
    assert memo(key, lambda: compute(0.5)) is not first and calls.count(0.5) == 2


def test_the_auto_drillers_loop_eigenvalues_are_those_of_each_matrix():
    from hammerbit.drillstring.top_stability import loop_eigenvalues
    rng = np.random.default_rng(3)
    A = rng.normal(size=(30, 30))
    B = A.copy()
    B[17, 23] += 1.0                            # the same corner, shape and type
    for M in (A, B, A):
        assert np.array_equal(np.sort_complex(loop_eigenvalues(M)), np.sort_complex(np.linalg.eigvals(M)))


def test_the_modal_form_is_that_of_each_matrix():
    from hammerbit.cosim.modal_form import modal_transform
    rng = np.random.default_rng(4)
    A = rng.normal(size=(12, 12)) - 4.0 * np.eye(12)
    B = A.copy()
    B[7, 5] += 0.5
    for M in (A, B):
        T, lam = modal_transform(M, 12, 1e-4)
        assert np.abs(T @ lam @ np.linalg.inv(T) - M).max() <= 1e-10 * np.abs(M).max()
