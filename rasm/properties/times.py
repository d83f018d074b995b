"""Exact time: record times and window bounds as integer nanoseconds.

Times are decimal seconds, and window membership ``a <= ti - tj <= b`` must be decided exactly
for any time written with up to nine decimals: ``0.3 - 0.1`` is 0.2, not the binary
``0.19999999999999998``. The monitors therefore carry every time as an integer number of
nanoseconds, whose differences and comparisons are exact.

* an int is exact;
* a float stands for the shortest decimal that reads back as it (``repr``): ``0.1`` is
  100000000 ns, not the binary fraction nearest 0.1;
* a :class:`~decimal.Decimal`, a :class:`~fractions.Fraction` and a :class:`Seconds` are exact;
* a time finer than a nanosecond is rounded to the nearest one (a half to even).
"""

from __future__ import annotations

import math
import numbers
from decimal import Decimal
from fractions import Fraction

__all__ = ["NS_PER_SECOND", "Seconds", "bound_nanoseconds", "float_nanoseconds", "nanoseconds"]

NS_PER_SECOND = 10**9
UNIT_NS = {"ms": 10**6, "s": NS_PER_SECOND, "min": 60 * NS_PER_SECOND}

# Below FAST (2**21 s, about 24 days) round(t * 1e9) is exact. Let t be the float nearest a
# decimal D = N / 10**9 (N an integer, |N| < 2**21 * 10**9 < 0.94 * 2**51), so t = D(1 + e1)
# with |e1| <= 2**-53; 1e9 is exact, and the product rounds once: t * 1e9 = N(1 + e1)(1 + e2).
# Its distance to N is at most |N| (2 * 2**-53 + 2**-106) < 0.94 * (1 + 2**-53) / 2 < 1/2, so
# the nearest integer is N. Any decimal with up to nine decimals that reads as t is that D:
# below 2**23 floats are less than 1e-9 apart, so no two such decimals read as the same float.
FAST = 2.0**21


class Seconds(float):
    """A record time read from a trace's text: a float for everything that reads seconds,
    carrying the exact nanoseconds of the text (``ns``) for the monitors.

    For the times whose float loses digits: ``1700000000.123456789`` reads as the float
    ``1700000000.1234567``, but its ``ns`` is 1700000000123456789.
    """

    ns: int

    def __new__(cls, text: str) -> Seconds:
        value = super().__new__(cls, text)
        value.ns = round(Fraction(text) * NS_PER_SECOND)
        return value


def float_nanoseconds(time: float) -> int | None:
    """A float time in integer nanoseconds (see the module docstring); None if not finite."""
    if -FAST < time < FAST:
        return round(time * 1e9)
    if math.isfinite(time):
        return round(Fraction(repr(time)) * NS_PER_SECOND)
    return None


def nanoseconds(time: object) -> int | None:
    """``time`` (seconds) as exact integer nanoseconds; None if it is not a finite number."""
    if isinstance(time, bool):
        return None
    if isinstance(time, Seconds):
        return time.ns
    if isinstance(time, numbers.Integral):
        return int(time) * NS_PER_SECOND
    if isinstance(time, Decimal):
        return round(Fraction(time) * NS_PER_SECOND) if time.is_finite() else None
    if isinstance(time, numbers.Rational):
        return round(Fraction(time) * NS_PER_SECOND)
    if isinstance(time, numbers.Real):  # a float, or a float-like number (numpy's)
        return float_nanoseconds(float(time))
    return None


def bound_nanoseconds(text: str, unit: str | None) -> int | None:
    """A window bound written ``text`` (a decimal number) in ``unit`` (ms, s, min; None: s) as
    exact integer nanoseconds; None when it is not a whole number of nanoseconds."""
    exact = Fraction(text) * UNIT_NS[unit or "s"]
    return exact.numerator if exact.denominator == 1 else None
