"""User stage code runs within a time budget, inline or on a worker the loop can walk away from."""

from __future__ import annotations

import time
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.platform.stages import StageRunner


class Boom(Exception):
    pass


def stage(kind: str, value: Any) -> Any:
    """A stage function: returns ``value``, raises, or exits."""
    if kind == "raise":
        raise Boom(value)
    if kind == "exit":
        raise SystemExit(value)
    return value


def summary(outcome: Any) -> tuple[Any, ...]:
    """An outcome without its wall-clock duration and traceback text (the frames differ)."""
    error = outcome.error
    return (
        outcome.ok,
        outcome.result,
        type(error),
        None if error is None else error.args,
        bool(outcome.traceback),
        outcome.timed_out,
        type(outcome.duration),
    )


@settings(max_examples=60, deadline=None)
@given(
    st.sampled_from(["return", "raise", "exit"]),
    st.none() | st.integers() | st.text(max_size=5),
)
def test_a_stage_call_ends_alike_inline_and_on_a_worker(kind: str, value: Any) -> None:
    inline, isolated = StageRunner(isolate=False), StageRunner(isolate=True)
    try:
        outcome = inline.call(stage, 30.0, kind, value)
        assert summary(outcome) == summary(isolated.call(stage, 30.0, kind, value))
        assert outcome.ok == (kind == "return")
        assert not outcome.ok or outcome.result == value
        assert outcome.ok or (outcome.error is not None and outcome.traceback)
    finally:
        inline.close()
        isolated.close()


def test_a_stage_over_its_budget_times_out_inline_and_on_a_worker() -> None:
    def slow() -> str:
        time.sleep(0.05)
        return "late"

    for isolate in (False, True):
        runner = StageRunner(isolate=isolate)
        try:
            outcome = runner.call(slow, 0.01)
            assert outcome.timed_out and not outcome.ok and outcome.result is None
        finally:
            runner.close()
