"""host/model/signals.py: the runs of a mask (still moments, moving blocks)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from host.model.signals import true_runs


@given(st.lists(st.booleans(), max_size=60))
def test_true_runs_are_the_maximal_runs_of_true(bits: list[bool]) -> None:
    runs = true_runs(np.array(bits, dtype=bool))
    covered = [False] * len(bits)
    for a, b in runs:
        assert 0 <= a < b <= len(bits)
        assert all(bits[a:b])
        # maximal: the samples either side are False or outside
        assert a == 0 or not bits[a - 1]
        assert b == len(bits) or not bits[b]
        covered[a:b] = [True] * (b - a)
    assert covered == bits
    assert runs == sorted(runs)
