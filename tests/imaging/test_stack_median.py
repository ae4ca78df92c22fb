"""``imaging.stack.median`` is ``float(np.median(x))`` (without importing numpy.ma)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.imaging.stack import median


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.floats(allow_nan=True, allow_infinity=True, width=64) | st.sampled_from([0.5, -0.0]),
        min_size=1,
        max_size=12,
    )
)
def test_median_is_numpys(values: list[float]) -> None:
    want = float(np.median(np.array(values)))
    got = median(np.array(values))
    assert (math.isnan(got) and math.isnan(want)) or got == want
