"""core.keep.kept: a bounded store in front of a computation."""
from __future__ import annotations

import pytest

from lensrt.core.keep import kept


def test_kept_computes_once_per_key_and_stays_bounded():
    calls = []

    def compute(v):
        calls.append(v)
        return [v]

    store: dict = {}
    first = kept(store, "a", lambda: compute(1), 2)
    assert kept(store, "a", lambda: compute(99), 2) is first and calls == [1]
    kept(store, "b", lambda: compute(2), 2)
    kept(store, "c", lambda: compute(3), 2)  # the store held its limit: emptied, then c kept
    assert list(store) == ["c"] and calls == [1, 2, 3]
    assert kept(store, ["unhashable"], lambda: compute(4), 2) == [4] and "c" in store  # computed, not kept
    with pytest.raises(ZeroDivisionError):  # an error is raised and nothing is kept
        kept(store, "d", lambda: 1 / 0, 2)
    assert "d" not in store
