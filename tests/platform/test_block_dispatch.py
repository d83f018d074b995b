"""Block._run hands each macro step's entered states, then its sent events, to the hooks in the
order of ``MacroStep.entered_states`` / ``sent_events`` (it reads them from the micro steps), and
the on_enter_<state> lookup (its names are cached) still finds hooks set on the instance."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from rasm.loop import LOOP_KEYS
from rasm.platform.block import Block
from rasm.platform.components import StageError, as_signals

CHART = """\
statechart:
  name: dispatch
  root state:
    name: lifecycle
    initial: instantiated
    states:
      - name: instantiated
        transitions:
          - target: outer
            event: go
            action: send('first', n=1)
      - name: outer
        initial: inner
        on entry: send('entering_outer')
        transitions:
          - target: instantiated
            event: back
        states:
          - name: inner
            on entry: send('entering_inner', depth=2)
            transitions:
              - target: last
                action: send('second')
          - name: last
"""


class Journal(Block):
    def __init__(self, chart: Path) -> None:
        self.journal: list[tuple[str, Any]] = []
        super().__init__("journal", chart=chart)

    def _entered(self, state: str) -> None:
        self.journal.append(("enter", state))
        super()._entered(state)

    def on_event_sent(self, name: str, data: dict[str, Any]) -> None:
        self.journal.append(("sent", (name, data)))

    def on_enter_inner(self) -> None:
        self.journal.append(("hook", "inner"))


class Quiet(Block):
    """Same state names, no hooks: another class's hooks must not leak into it."""


@pytest.fixture
def chart(tmp_path: Path) -> Path:
    path = tmp_path / "dispatch.yaml"
    path.write_text(CHART)
    return path


def expected(steps: list[Any]) -> list[tuple[str, Any]]:
    """What the hooks should see, from the macro steps' own (list-building) properties."""
    out: list[tuple[str, Any]] = []
    for step in steps:
        for state in step.entered_states:
            out.append(("enter", state))
            if state == "inner":
                out.append(("hook", "inner"))
        out.extend(("sent", (e.name, dict(e.data))) for e in step.sent_events)
    return out


def test_hooks_see_entered_states_then_sent_events_in_macro_step_order(chart: Path) -> None:
    block = Journal(chart)
    block.journal.clear()
    steps = block.send("go")
    # several macro steps (the internal events are steps of their own), the first entering
    # outer and inner and sending events in more than one micro step
    assert len(steps) > 2 and len(steps[0].steps) > 1 and len(steps[0].entered_states) > 1
    assert len(steps[0].sent_events) > 1
    assert block.journal == expected(steps)
    assert ("sent", ("entering_inner", {"depth": 2})) in block.journal


def test_a_hook_set_on_the_instance_later_is_called(chart: Path) -> None:
    block = Journal(chart)
    block.send("go")
    block.send("back")
    calls: list[str] = []
    block.on_enter_last = lambda: calls.append("last")  # type: ignore[attr-defined]
    block.on_enter_inner = lambda: calls.append("instance inner")  # type: ignore[method-assign]
    block.send("go")
    assert calls == ["instance inner", "last"]
    quiet = Quiet("quiet", chart=chart)
    quiet.send("go")
    assert quiet.configuration == ["lifecycle", "outer", "last"]
    assert calls == ["instance inner", "last"]


def test_a_monitor_result_using_loop_keys_names_the_first_of_them() -> None:
    forged = sorted(LOOP_KEYS)[-2:]
    with pytest.raises(StageError, match=f"monitor returned {forged[0]!r}, a key the loop"):
        as_signals({"temperature": 1.0, forged[1]: 1, forged[0]: 2})
    signals = {"temperature": 1.0}
    assert as_signals(signals) is signals
