"""The statechart fast path: sismic's semantics, several times faster.

:class:`FastInterpreter` runs a chart exactly as ``sismic.interpreter.Interpreter`` does (the
differential tests compare them on random charts), from tables computed once per chart
(:mod:`~rasm.statechart.fast.tables`); :class:`PropertyListener` executes a bound property
statechart only for the meta-events it can react to (:mod:`~rasm.statechart.fast.meta_guards`).
It reads sismic's private attributes, hence the pinned sismic versions.
"""

from rasm.statechart.fast.interpreter import FastInterpreter
from rasm.statechart.fast.listener import PropertyListener
from rasm.statechart.fast.tables import ChartEditedError

__all__ = ["ChartEditedError", "FastInterpreter", "PropertyListener"]
