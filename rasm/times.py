"""Exact time: times and durations as integer nanoseconds.

Times are decimal seconds, and whatever compares them must be exact for any time written with
up to nine decimals: ``0.3 - 0.1`` is 0.2, not the binary ``0.19999999999999998``. A window's
membership ``a <= ti - tj <= b``, ``time - prev(time)`` in a property, a chart's ``after(2)``
entered at 7.7 and looked at 9.7: each is decided on integer numbers of nanoseconds, whose sums,
differences and comparisons are exact. What reads a time as a float keeps doing so; only the
arithmetic that decides goes through here. How a time is read:

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

__all__ = [
    "elapsed_seconds",
    "FAST", "NS_PER_SECOND", "Seconds", "bound_nanoseconds", "float_nanoseconds",
    "format_nanoseconds", "format_seconds", "from_nanoseconds", "nanoseconds", "seconds_value",
    "to_the_nanosecond",
]

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
    if time.__class__ is float and -FAST < time < FAST:  # the common case, first
        return round(time * 1e9)  # type: ignore[operator]
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


def from_nanoseconds(ns: int) -> float:
    """``ns`` nanoseconds as seconds: the float nearest them (±inf beyond the largest float)."""
    try:
        return ns / NS_PER_SECOND  # int / int: rounded once, correctly
    except OverflowError:
        return math.inf if ns > 0 else -math.inf


def seconds_value(time: numbers.Real) -> int | float:
    """A time as a plain number of seconds, as JSON writes it and properties' ``time`` reads
    it: an int (any integral number) as an int, any other (a Fraction, a Decimal) as the float
    nearest it; a float (a :class:`Seconds` too) is returned as it is."""
    if isinstance(time, float):
        return time
    return int(time) if isinstance(time, numbers.Integral) else float(time)


def to_the_nanosecond(time: float) -> float:
    """A float time as the float nearest its nanoseconds: ``0.1 + 0.2`` becomes ``0.3``, the
    float nearest 0.3, which every time written "0.3" reads as. Anything else (an int, a
    :class:`Seconds`, a time that is not finite) is returned as it is: it is exact already, or
    nothing is."""
    if time.__class__ is not float:
        return time
    if -FAST < time < FAST:
        return round(time * 1e9) / 1e9  # both exact below FAST: one correct rounding
    ns = float_nanoseconds(time)
    return time if ns is None else from_nanoseconds(ns)


def elapsed_seconds(start: object, end: object) -> float:
    """``end - start`` in seconds, computed on their exact nanoseconds (epoch times differ by
    ``5.100000143`` in binary floating point where their decimals differ by 5.1)."""
    first, last = nanoseconds(start), nanoseconds(end)
    if first is None or last is None:
        return float(end) - float(start)  # type: ignore[arg-type]
    return from_nanoseconds(last - first)


def format_seconds(time: object) -> str:
    """A time as the decimal number of seconds it stands for, to the nanosecond and as short
    as it goes (``12.5``, ``3``, ``1700000000.123456789``): how every message and report
    writes a time. A number that is not finite, or no number, is written as Python does."""
    ns = nanoseconds(time)
    return str(time) if ns is None else format_nanoseconds(ns)


def format_nanoseconds(ns: int) -> str:
    """``ns`` nanoseconds as a decimal number of seconds: 1500000000 is ``1.5``."""
    sign = "-" if ns < 0 else ""
    whole, fraction = divmod(abs(ns), NS_PER_SECOND)
    return f"{sign}{whole}.{fraction:09d}".rstrip("0").rstrip(".")
