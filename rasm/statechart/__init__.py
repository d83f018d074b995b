"""The statechart layer: load (with validation), execute (atomic steps), run live, export.

Charts are sismic YAML files; ``load_statechart`` returns a sismic ``Statechart`` and
``Interpreter`` is sismic's interpreter made faster, atomic and deadline-aware.
"""

from rasm.statechart.clock import Clock, MonotonicClock, SimulatedClock
from rasm.statechart.export import FORMATS, export
from rasm.statechart.interpreter import Interpreter, StepFailure
from rasm.statechart.load import ChartProblem, check_statechart, load_statechart, source_of
from rasm.statechart.runner import ChartRunner

__all__ = [
    "FORMATS",
    "ChartProblem",
    "ChartRunner",
    "Clock",
    "Interpreter",
    "MonotonicClock",
    "SimulatedClock",
    "StepFailure",
    "check_statechart",
    "export",
    "load_statechart",
    "source_of",
]
