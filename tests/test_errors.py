"""One exception hierarchy: every error rasm raises on purpose is a RasmError."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import pytest
from sismic.exceptions import CodeEvaluationError
from sismic.exceptions import StatechartError as SismicStatechartError

import rasm
from rasm.errors import ExecutionError, RasmError, StatechartError
from rasm.statechart import Interpreter, load_statechart


def rasm_modules():
    for info in pkgutil.walk_packages(rasm.__path__, "rasm."):
        if info.name.endswith(".__main__"):  # running it is the command line itself
            continue
        try:
            yield importlib.import_module(info.name)
        except ImportError as exc:  # an optional dependency of an optional part
            pytest.skip(f"{info.name}: {exc}")


def test_every_public_exception_class_of_rasm_is_a_rasm_error():
    outside = []
    for module in rasm_modules():
        for name, cls in vars(module).items():
            if (
                inspect.isclass(cls)
                and issubclass(cls, BaseException)
                and cls.__module__ == module.__name__
                and not name.startswith("_")
                and not issubclass(cls, RasmError)
            ):
                outside.append(f"{module.__name__}.{name}")
    # a real Ctrl-C stays a KeyboardInterrupt: nothing may catch it as an error
    assert outside == ["rasm.errors.Interrupted"]


CHART = """\
statechart:
  name: divide
  root state:
    name: root
    initial: a
    states:
      - name: a
        transitions:
          - target: a
            event: go
            action: x = 1 / 0
"""


def test_a_failed_step_is_an_execution_error_raised_from_what_sismic_raised():
    interp = Interpreter(load_statechart(text=CHART))
    interp.execute()
    interp.queue("go")
    with pytest.raises(ExecutionError) as caught:
        interp.execute()
    error = caught.value
    assert isinstance(error, StatechartError) and isinstance(error, RasmError)
    assert isinstance(error.cause, CodeEvaluationError) and error.__cause__ is error.cause
    assert str(error).startswith("CodeEvaluationError: 'division by zero' occurred")
    assert interp.configuration == ["root", "a"]  # rolled back, and the chart goes on


def test_an_edited_chart_is_rasms_error_and_sismics():
    from rasm.statechart.fast import ChartEditedError

    assert issubclass(ChartEditedError, StatechartError)
    assert issubclass(ChartEditedError, SismicStatechartError)
