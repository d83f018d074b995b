"""The brute-force reference for chart verification: a breadth-first search over deep copies of
stock sismic interpreters, keyed by configuration, context and history memory (and, for charts
with timers, the absolute time: such searches are bounded by depth). What ``rasm verify``'s
exploration must agree with, and what benchmarks/verify.py measures it against."""

from __future__ import annotations

import copy
from collections import deque
from collections.abc import Iterable
from typing import Any

from sismic.clock import SimulatedClock
from sismic.exceptions import SismicError
from sismic.interpreter import Interpreter
from sismic.model import Event, Statechart

from rasm.statechart.simulate import MAX_STEPS

__all__ = ["brute_force"]


def _freeze(value: Any) -> Any:
    if isinstance(value, list | tuple):
        return tuple(_freeze(v) for v in value)
    if isinstance(value, dict):
        return tuple(sorted((k, _freeze(v)) for k, v in value.items()))
    return value


def _key(it: Interpreter, with_time: bool) -> tuple:
    return (
        frozenset(it._configuration),
        tuple(sorted((k, _freeze(v)) for k, v in it.context.items())),
        tuple(sorted((k, tuple(v) if v else None) for k, v in it._memory.items())),
        it.clock.time if with_time else None,
    )


def _settle(it: Interpreter, configurations: set[frozenset[str]], max_steps: int) -> None:
    """Macro step by macro step until stable, noting the configuration after each one (as
    ``rasm simulate`` prints them; ``Interpreter.execute`` would show only the last)."""
    for _ in range(max_steps):
        if it.execute_once() is None:
            return
        configurations.add(frozenset(it._configuration))
    raise RuntimeError("a step never settles")  # internal events sent forever: rasm reports it


def brute_force(
    statechart: Statechart,
    events: Iterable[tuple[str, dict[str, Any]]],
    clock: Iterable[float] = (),
    *,
    max_depth: int | None = None,
    max_states: int = 1_000_000,
    max_steps: int = MAX_STEPS,
) -> tuple[set[frozenset[str]], int]:
    """Every configuration stock sismic reaches after a macro step, from every stable state
    trying each event (name, data) and each clock advance; and the number of states."""
    events = list(events)
    clock = list(clock)
    with_time = bool(clock)
    root = Interpreter(statechart, clock=SimulatedClock())
    configurations: set[frozenset[str]] = set()
    _settle(root, configurations, max_steps)
    seen = {_key(root, with_time)}
    frontier = deque([(root, 0)])
    memo_key = id(statechart)
    while frontier:
        it, depth = frontier.popleft()
        if max_depth is not None and depth >= max_depth:
            continue
        moves = [(name, data, 0.0) for name, data in events] + [(None, {}, dt) for dt in clock]
        for name, data, dt in moves:
            nxt = copy.deepcopy(it, memo={memo_key: statechart})
            if dt:
                nxt.clock.time = nxt.clock.time + dt
            if name is not None:
                nxt.queue(Event(name, **data))
            try:
                _settle(nxt, configurations, max_steps)
            except SismicError:
                continue
            key = _key(nxt, with_time)
            if key not in seen:
                seen.add(key)
                if len(seen) > max_states:
                    raise RuntimeError("the brute force reached its state budget")
                frontier.append((nxt, depth + 1))
    return configurations, len(seen)
