"""The loop's per-iteration dispatch against its straightforward versions.

``Block._entered`` keeps the core task's sub-states (neither a mode nor lifecycle work) in a cache
that sends them straight to their hook; ``StageRunner.call`` passes arguments on to the stage
function (so the orchestrator needs no closure per stage). Both are compared here with the plain
code they replace, on generated inputs.
"""

from __future__ import annotations

import sys
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.platform import block as block_module
from rasm.platform.block import MODES, Block
from rasm.platform.stages import StageRunner

LIFECYCLE_WORK = ("configuration", "initialization", "fault", "terminated")
SUBSTATES = ("idle", "monitoring", "analysing", "suspended")
# states with a hook on the probe: a sub-state, a mode without lifecycle work, and lifecycle states
# (whose hooks the block never calls: it does their work itself)
HOOKED = ("monitoring", "idle", "initialized", "fault", "configuration")


class Probe:
    """Just what ``_entered`` touches, every effect written to ``journal``."""

    def __init__(self) -> None:
        self.journal: list[tuple[str, str]] = []
        self._mode = "instantiated"
        self._listeners = [lambda block, mode: self.journal.append(("listener", mode))]
        for state in HOOKED:
            setattr(self, f"on_enter_{state}", lambda s=state: self.journal.append(("hook", s)))

    def _lifecycle_work(self, state: str) -> None:
        self.journal.append(("work", state))

    _entered = Block._entered


def straightforward_entered(probe: Probe, state: str) -> None:
    """``Block._entered`` before the sub-state cache, its lifecycle work journaled."""
    if state in MODES:
        probe._mode = state
        for listener in list(probe._listeners):
            listener(probe, state)
    if state not in LIFECYCLE_WORK:
        hook = getattr(probe, f"on_enter_{state}", None)
        if hook is not None:
            hook()
    else:
        probe._lifecycle_work(state)


# fresh names too, so that first entries (which fill the cache) are checked as well as later ones
states = st.lists(
    st.sampled_from(MODES + SUBSTATES) | st.text("abcxyz_", min_size=1, max_size=4), max_size=30
)


@given(states, st.booleans())
def test_entered_dispatches_like_the_straightforward_code(sequence: list[str], fresh: bool) -> None:
    if fresh:  # the cache is the process's: start from an empty one half of the time
        block_module._SUBSTATE_HOOKS.clear()
    fast, plain = Probe(), Probe()
    for state in sequence:
        fast._entered(state)
        straightforward_entered(plain, state)
        assert fast.journal == plain.journal
        assert fast._mode == plain._mode
    # every cached name is interned (the type's attribute cache keeps interned names only)
    for state, name in block_module._SUBSTATE_HOOKS.items():
        assert name == f"on_enter_{state}" and name is sys.intern(name)
        assert state not in MODES and state not in LIFECYCLE_WORK


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
    st.booleans(),
)
def test_call_passes_its_arguments_on_like_a_closure(kind: str, value: Any, isolate: bool) -> None:
    runner = StageRunner(isolate=isolate)
    try:
        with_args = runner.call(stage, 30.0, kind, value)
        closure = runner.call(lambda: stage(kind, value), 30.0)
        assert summary(with_args) == summary(closure)
        assert with_args.ok == (kind == "return")
        assert not with_args.ok or with_args.result == value
    finally:
        runner.close()
