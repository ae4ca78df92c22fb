"""The vectorised fixed-point CSV writer equals csv.writer over Python's "%.Nf", byte for byte."""

from __future__ import annotations

import csv
import io
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.app.fixedtext import csv_cell, fixed_csv


def _reference(header: list[str], columns: list[tuple[np.ndarray, int]], tail: str | None) -> str:
    """What the export wrote before: csv.writer over the Python-formatted strings."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    cols = [[f"%.{d}f" % v for v in values.tolist()] for values, d in columns]
    if tail is not None:
        cols.append([tail] * len(cols[0]))
    w.writerows(zip(*cols, strict=True))
    return buf.getvalue()


#: Values where a formatter must be careful: exact ties (half to even on the binary value),
#: near ties, signs of zero, tiny negatives that round to zero, powers of ten, the 2**52
#: limit of exact float integers, huge values, non-finite values, subnormals.
EDGES = [
    0.0,
    -0.0,
    0.5,
    1.5,
    2.5,
    -2.5,
    0.125,
    0.375,
    1.005,
    2.675,
    0.045,
    1e-9,
    -1e-9,
    -4e-7,
    9.9999995,
    9.99999949999,
    99.995,
    999999.9999995,
    0.1,
    0.7,
    123456.789,
    -123456.789,
    2.0**52,
    2.0**52 + 1,
    2.0**53,
    4503599.6270496,
    1e15,
    1e16,
    1e22,
    1.7976931348623157e308,
    -1e300,
    5e-324,
    -5e-324,
    math.inf,
    -math.inf,
    math.nan,
    1000.0,
    999.99,
    9.5,
    10.5,
]


@pytest.mark.parametrize("digits", [0, 1, 2, 4, 5, 6, 9, 15])
def test_edges_equal_python(digits: int) -> None:
    values = np.array(EDGES * 3)
    cols = [(values, digits), (values[::-1].copy(), 6)]
    assert fixed_csv(["a", "b"], cols, tail="cal") == _reference(["a", "b"], cols, "cal")


def test_ties_half_even_on_the_binary_value() -> None:
    # 0.125 and 0.375 are exact binary ties at 2 digits; 2.675 is just below its "tie"
    text = fixed_csv(["v"], [(np.array([0.125, 0.375, 2.675, -0.125]), 2)])
    assert text == "v\n0.12\n0.38\n2.67\n-0.12\n"


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=0, max_size=60),
    st.integers(min_value=0, max_value=12),
)
def test_random_floats_equal_python(values: list[float], digits: int) -> None:
    arr = np.array(values, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        cols = [(arr, digits), (arr * 1000.0, 2)]
        assert fixed_csv(["x", "y"], cols) == _reference(["x", "y"], cols, None)


def test_many_rows_cross_chunks_and_scales() -> None:
    rng = np.random.default_rng(7)
    n = 20_000  # several chunks
    cols = [
        (np.arange(n) / 1000.0, 6),
        (rng.normal(0.0, 1e4, n), 2),
        (rng.uniform(-1.0, 1.0, n) * 10.0 ** rng.integers(-8, 9, n), 5),
        (rng.integers(-(2**40), 2**40, n) / 7.0, 4),
    ]
    cols[3][0][::97] = np.inf
    assert fixed_csv(list("abcd"), cols, tail="bone") == _reference(list("abcd"), cols, "bone")


def test_bit_patterns_near_ties() -> None:
    """Neighbours (one ulp either side) of decimal ties at 4 and 6 digits."""
    base = np.array([k + 0.5 for k in range(0, 2000, 7)]) / 10**4
    ulps = np.concatenate([np.nextafter(base, 0.0), base, np.nextafter(base, 1.0)])
    for digits in (4, 6):
        cols = [(ulps, digits)]
        assert fixed_csv(["v"], cols) == _reference(["v"], cols, None)


def test_tail_and_header_quoted_as_csv_writes_them() -> None:
    cols = [(np.array([1.0, 2.0]), 1)]
    for tail in ["plain", "a,b", 'say "x"', "two\nlines", ""]:
        assert fixed_csv(["h,1", "h2"][:1], cols, tail=tail) == _reference(["h,1"], cols, tail)
    assert csv_cell("a,b") == '"a,b"'


def test_empty_and_bad_arguments() -> None:
    assert fixed_csv(["a"], [(np.array([]), 3)]) == "a\n"
    with pytest.raises(ValueError, match="differ in length"):
        fixed_csv(["a", "b"], [(np.zeros(2), 1), (np.zeros(3), 1)])
    with pytest.raises(ValueError, match="digits"):
        fixed_csv(["a"], [(np.zeros(2), 16)])


def test_float32_and_int_columns_are_formatted_as_float64() -> None:
    cols32 = [(np.array([0.1, 2.5], dtype=np.float32), 9)]
    ref = [(np.array([0.1, 2.5], dtype=np.float32).astype(np.float64), 9)]
    assert fixed_csv(["v"], cols32) == _reference(["v"], ref, None)
