"""rasm.times: how times are written, and a float time to the nanosecond."""

from __future__ import annotations

import math
from decimal import Decimal
from fractions import Fraction

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm.times import (
    Seconds,
    format_nanoseconds,
    format_seconds,
    from_nanoseconds,
    nanoseconds,
    seconds_value,
    to_the_nanosecond,
)


@pytest.mark.parametrize(
    ("time", "text"),
    [(12.5, "12.5"), (3, "3"), (3.0, "3"), (0, "0"), (-0.5, "-0.5"), (1e-9, "0.000000001"),
     (1234567.8, "1234567.8"), (Fraction(1, 3), "0.333333333"), (Decimal("0.30"), "0.3"),
     (Seconds("1700000000.123456789"), "1700000000.123456789"), (math.nan, "nan"),
     (math.inf, "inf"), ("soon", "soon")],
)
def test_a_time_is_written_as_the_decimal_it_stands_for(time, text):
    assert format_seconds(time) == text


@given(st.integers(-10**20, 10**20))
def test_the_written_decimal_is_exactly_the_nanoseconds(ns):
    assert Decimal(format_nanoseconds(ns)) * 10**9 == ns


@given(st.integers(0, 2**23 * 10**9))
def test_a_float_time_to_the_nanosecond_is_the_float_of_its_decimal(ns):
    decimal = float(f"{Decimal(ns).scaleb(-9):f}")
    assert from_nanoseconds(ns) == decimal
    off = math.nextafter(decimal, math.inf)  # the same decimal, a rounding error away
    if nanoseconds(off) == ns:
        assert to_the_nanosecond(off) == decimal


def test_sums_of_tenths_read_as_their_decimals():
    assert to_the_nanosecond(0.1 + 0.2) == 0.3
    assert to_the_nanosecond(0.1 * 7) == 0.7
    assert to_the_nanosecond(3) == 3 and isinstance(to_the_nanosecond(3), int)
    assert math.isnan(to_the_nanosecond(math.nan))


def test_a_plain_number_of_seconds_for_json():
    assert seconds_value(Fraction(1, 10)) == 0.1 and seconds_value(Fraction(4, 2)) == 2.0
    assert isinstance(seconds_value(Fraction(4, 2)), float) and seconds_value(True) == 1
    assert seconds_value(Decimal("2.5")) == 2.5
    exact = Seconds("1700000000.123456789")
    assert seconds_value(exact) is exact
