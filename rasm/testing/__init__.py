"""Property-based testing of statecharts and adaptation traces (hypothesis + pytest).

* :func:`traces` — a strategy of traces for the signals a property file reads;
* :func:`statechart_machine` — a hypothesis state machine exploring a chart, checking its
  contracts, the property statecharts that apply and your invariant;
* :func:`run_app` — run an application on the simulated clock and get its adaptation
  :class:`Trace`; :func:`scenarios` — a strategy of the disturbance schedules it declares;
* :func:`assert_properties` — a property file must hold on a trace (failures explained as
  ``rasm check`` explains them, the trace saved).

The pytest plugin (:mod:`rasm.testing.plugin`, loaded automatically) adds the ``rasm_app``
fixture. The tutorial is ``docs/testing.md``.
"""

from rasm.testing.apps import run_app
from rasm.testing.assertions import PropertyViolation, assert_properties, check_trace
from rasm.testing.failures import failures_dir
from rasm.testing.machine import ChartFailure, ChartState, statechart_machine
from rasm.testing.monitors import applicable_monitors, watched_states
from rasm.testing.scenarios import scenarios, windows
from rasm.testing.traces import signal_domains, traces
from rasm.trace import Trace

__all__ = [
    "ChartFailure",
    "ChartState",
    "PropertyViolation",
    "Trace",
    "applicable_monitors",
    "assert_properties",
    "check_trace",
    "failures_dir",
    "run_app",
    "scenarios",
    "signal_domains",
    "statechart_machine",
    "traces",
    "watched_states",
    "windows",
]
