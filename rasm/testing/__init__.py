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

The names are loaded on first use: pytest imports the plugin in every run, and importing it
imports this package first, which must not bring hypothesis, sismic or the platform with it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

# public name -> the module that defines it
_PUBLIC = {
    "ChartFailure": "rasm.testing.machine",
    "ChartState": "rasm.testing.machine",
    "PropertyViolation": "rasm.testing.assertions",
    "Trace": "rasm.testing.apps",
    "applicable_monitors": "rasm.testing.monitors",
    "assert_properties": "rasm.testing.assertions",
    "check_trace": "rasm.testing.assertions",
    "failures_dir": "rasm.testing.failures",
    "run_app": "rasm.testing.apps",
    "scenarios": "rasm.testing.scenarios",
    "signal_domains": "rasm.testing.traces",
    "statechart_machine": "rasm.testing.machine",
    "traces": "rasm.testing.traces",
    "watched_states": "rasm.testing.monitors",
    "windows": "rasm.testing.scenarios",
}

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

if TYPE_CHECKING:  # for type checkers and editors: the same names, imported eagerly
    from rasm.testing.apps import Trace, run_app
    from rasm.testing.assertions import PropertyViolation, assert_properties, check_trace
    from rasm.testing.failures import failures_dir
    from rasm.testing.machine import ChartFailure, ChartState, statechart_machine
    from rasm.testing.monitors import applicable_monitors, watched_states
    from rasm.testing.scenarios import scenarios, windows
    from rasm.testing.traces import signal_domains, traces


def __getattr__(name: str) -> object:
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'rasm.testing' has no attribute {name!r}")
    loaded = importlib.import_module(module)
    # Bind every public name the module defines, so that later reads find them directly.
    # Loading rasm.testing.scenarios (or .traces) binds the submodule under the name of its
    # function; this binds the function back.
    for public, home in _PUBLIC.items():
        if home == module:
            globals()[public] = getattr(loaded, public)
    return globals()[name]


def __dir__() -> list[str]:
    return sorted(__all__)
