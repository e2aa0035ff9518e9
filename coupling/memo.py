"""Results of array computations remembered across the library's objects.

Eigendecompositions and matrix exponentials of a string's model cost far more
than looking them up: a sweep, a run and its reference, a study's repeated runs,
the monolithic reference and the auto-driller's stability check all build them
from the same matrices.  They are
kept under a digest of those matrices (:func:`digest`), the most recent
:data:`MEMO_SIZE` of them, with their arrays read-only (they are shared).
"""
from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np

__all__ = ["MEMO_SIZE", "memo", "digest"]

#: results kept (the oldest is dropped first)
MEMO_SIZE = 32
_MEMO: "OrderedDict[bytes, object]" = OrderedDict()


def memo(key: bytes, compute):
    """``compute()``, remembered under ``key`` (its arrays made read-only: they are shared)."""
    hit = _MEMO.get(key)
    if hit is not None:
        _MEMO.move_to_end(key)
        return hit
    value = compute()
    for a in (value if isinstance(value, tuple) else (value,)):
        if isinstance(a, np.ndarray):
            a.setflags(write=False)
    _MEMO[key] = value
    while len(_MEMO) > MEMO_SIZE:
        _MEMO.popitem(last=False)
    return value


def digest(tag: str, *arrays, extra=()) -> bytes:
    """The key of a computation ``tag`` on ``arrays`` (their shapes, types and bytes) and ``extra``."""
    h = hashlib.sha1(tag.encode())
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(repr((a.shape, a.dtype.str)).encode())
        h.update(a.tobytes())
    h.update(repr(extra).encode())
    return h.digest()
