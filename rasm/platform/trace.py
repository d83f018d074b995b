"""Moved: the trace format is :mod:`rasm.trace`, the loop's keys :mod:`rasm.loop`.

The names stay importable from here for the platform modules that still import them.
"""

from rasm.loop import LOOP_KEYS  # moved to rasm.loop
from rasm.trace import TraceWriter  # moved to rasm.trace

__all__ = ["LOOP_KEYS", "TraceWriter"]
