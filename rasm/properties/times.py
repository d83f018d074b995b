"""Exact time for the monitors: :mod:`rasm.times`, under the name the property modules import.

The functions live in :mod:`rasm.times`, below both the monitors and the statecharts, whose
timers compare the same way.
"""

from rasm.times import (
    FAST,
    NS_PER_SECOND,
    UNIT_NS,
    Seconds,
    bound_nanoseconds,
    float_nanoseconds,
    format_nanoseconds,
    format_seconds,
    from_nanoseconds,
    nanoseconds,
    seconds_value,
    to_the_nanosecond,
)

__all__ = [
    "FAST", "NS_PER_SECOND", "UNIT_NS", "Seconds", "bound_nanoseconds", "float_nanoseconds",
    "format_nanoseconds", "format_seconds", "from_nanoseconds", "nanoseconds", "seconds_value",
    "to_the_nanosecond",
]
