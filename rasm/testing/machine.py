"""``statechart_machine(chart)``: explore a statechart with hypothesis' stateful testing.

The machine starts the chart on a simulated clock, then repeatedly waits a little (the clock
advances, so ``after()`` timers can fire) and sends one event. After every macro step it checks:

1. the chart's **contracts** (sismic raises ``ContractError``);
2. the **property statecharts** that apply to the chart (``monitors/*.yaml``, judged by
   :mod:`rasm.testing.monitors`; sismic raises ``PropertyStatechartError``);
3. your **invariant**, ``invariant(state)`` with ``state.configuration`` the set of active state
   names and ``state.context`` the chart's variables: it fails if it returns ``False`` or raises
   ``AssertionError``;
4. that the step did not raise (a guard or action crashing is a bug too).

A failure reports the shortest event sequence hypothesis found, as a list, and saves it as an
events file (``.rasm/failures/<chart>-<hash>.jsonl``) that ``rasm simulate CHART --events FILE``
replays step for step.
"""

from __future__ import annotations

import ast
import copy
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, Phase, settings, target
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, rule
from sismic.exceptions import ContractError, PropertyStatechartError
from sismic.model import Statechart

from rasm.errors import ExecutionError, RasmError
from rasm.statechart import Interpreter, SimulatedClock, load_statechart
from rasm.testing.failures import is_final_example, save_jsonl
from rasm.testing.monitors import applicable_monitors
from rasm.times import format_seconds

__all__ = ["ChartState", "ChartFailure", "statechart_machine", "chart_events", "timer_delays"]

MAX_STEPS_PER_EVENT = 1000  # eventless transitions that never settle are a bug of their own


@dataclass(frozen=True)
class ChartState:
    """What an invariant sees after a macro step.

    ``events`` are the events sent so far as the lines of the events file: ``{"time", "event"
    [, "data"]}`` dicts, not names (``[e["event"] for e in state.events]`` gives the names).
    """

    configuration: frozenset[str]
    context: Mapping[str, Any]
    time: float
    events: tuple[dict[str, Any], ...] = field(default=())

    def active(self, name: str) -> bool:
        """Whether state ``name`` is active."""
        return name in self.configuration


class ChartFailure(RasmError, AssertionError):
    """A chart broke a contract, a monitor or an invariant; the message says how to replay it.

    ``events`` is the sequence sent (``{"time", "event"[, "data"]}`` dicts, the lines of the
    events file), ``configuration`` the active states when it failed, ``reason`` what failed,
    and ``saved`` the events file (None while hypothesis is still shrinking).
    """

    def __init__(
        self,
        message: str,
        *,
        reason: str = "",
        events: Sequence[dict[str, Any]] = (),
        configuration: frozenset[str] = frozenset(),
        saved: Path | None = None,
    ) -> None:
        super().__init__(message)
        self.reason = reason
        self.events = list(events)
        self.configuration = configuration
        self.saved = saved


# --------------------------------------------------------------------------- chart analysis


def chart_events(chart: Statechart) -> list[str]:
    """The events the chart's transitions react to, sorted."""
    return sorted({t.event for t in chart.transitions if t.event})


def _timer_arguments(chart: Statechart) -> list[ast.AST]:
    found = []
    for transition in chart.transitions:
        if not transition.guard:
            continue
        try:
            tree = ast.parse(transition.guard.strip(), mode="eval")
        except SyntaxError:
            continue
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id in ("after", "idle")
                and len(node.args) == 1
            ):
                found.append(node.args[0])
    return found


def timer_delays(chart: Statechart, context: Mapping[str, Any] | None = None) -> list[float]:
    """Waits worth trying between events: 0, and for each timer ``after(t)``/``idle(t)`` of the
    chart (a number, or a variable of its initial context) ``t/2`` and ``t``; 1 s without timers."""
    values: set[float] = set()
    for arg in _timer_arguments(chart):
        value: Any = None
        if isinstance(arg, ast.Constant):
            value = arg.value
        elif isinstance(arg, ast.Name) and context is not None:
            value = context.get(arg.id)
        if isinstance(value, int | float) and not isinstance(value, bool) and value > 0:
            values.update((value / 2, float(value)))
    if not values:
        values.add(1.0)
    return [0.0, *sorted(values)]


def _initial_context(chart: Statechart, initial: Mapping[str, Any] | None) -> dict[str, Any]:
    probe = Interpreter(chart, clock=SimulatedClock(), initial_context=copy.deepcopy(initial))
    try:
        probe.execute()
    except Exception:  # a broken initial step is reported by the machine itself
        pass
    return dict(probe.context)


def _load(chart: str | Path | Statechart) -> tuple[Statechart, str | None]:
    if isinstance(chart, Statechart):
        return chart, None
    if isinstance(chart, Path) or (isinstance(chart, str) and "\n" not in chart):
        path = Path(chart)
        if not path.is_file():
            raise FileNotFoundError(
                f"no statechart file {path} (pass a YAML path, the YAML text, or a Statechart)"
            )
        return load_statechart(path), str(path)
    return load_statechart(text=chart), None


def _event_strategies(
    chart: Statechart, events: Iterable[str] | Mapping[str, Any] | None
) -> dict[str, st.SearchStrategy[dict[str, Any]] | None]:
    if events is None:
        names = chart_events(chart)
        if not names:
            raise ValueError(
                f"statechart {chart.name!r} reacts to no event; pass events=[...] to say what "
                f"to send it"
            )
        return {name: None for name in names}
    if isinstance(events, str) or not isinstance(events, Iterable):
        raise TypeError(
            f"events must be a list of event names (or a dict), not {type(events).__name__}"
            if not isinstance(events, str)
            else "events must be a list of event names (or a dict), not one string"
        )
    if isinstance(events, Mapping):
        out = {}
        for name, data in events.items():
            if data is None or isinstance(data, st.SearchStrategy):
                out[name] = data
            elif isinstance(data, Mapping):
                out[name] = st.just(dict(data))
            else:
                raise TypeError(
                    f"events[{name!r}] must be None, a dict of event data, or a strategy of "
                    f"such dicts, not {type(data).__name__}"
                )
    else:
        out = {name: None for name in events}
    if not out:
        raise ValueError("events is empty: give at least one event name to send")
    return out


def _delay_strategy(
    chart: Statechart, delays: Sequence[float] | st.SearchStrategy | None, context: dict
) -> st.SearchStrategy[float]:
    if isinstance(delays, st.SearchStrategy):
        return delays
    values = list(delays) if delays is not None else timer_delays(chart, context)
    if not values or any(not (isinstance(d, int | float) and d >= 0) for d in values):
        raise ValueError(f"delays must be numbers of seconds >= 0, got {values!r}")
    return st.sampled_from([float(d) for d in values])


# --------------------------------------------------------------------------- running


class _Broken(Exception):
    """A check failed; ``kind`` tells failures apart when a sequence is minimised."""

    def __init__(self, kind: str, why: str) -> None:
        super().__init__(why)
        self.kind = kind
        self.why = why


class _Runner:
    """One run of the chart on a simulated clock, with every check after every macro step."""

    def __init__(
        self,
        chart: Statechart,
        monitors: Sequence[Statechart],
        invariant: Callable[[ChartState], Any] | None,
        initial_context: Mapping[str, Any] | None,
    ) -> None:
        self.clock = SimulatedClock()
        self.interpreter = Interpreter(
            chart, clock=self.clock, initial_context=copy.deepcopy(initial_context)
        )
        for monitor in monitors:
            self.interpreter.bind_property_statechart(monitor)
        self.invariant = invariant
        self.sent: list[dict[str, Any]] = []
        self.visited: set[str] = set()

    def start(self) -> None:
        self.settle()

    def send(self, time: float, name: str, data: Mapping[str, Any]) -> None:
        self.clock.time = max(self.clock.time, round(time, 9))
        item: dict[str, Any] = {"time": self.clock.time, "event": name}
        if data:
            item["data"] = dict(data)
        self.sent.append(item)
        self.interpreter.queue(name, **dict(data))
        self.settle()

    def state(self) -> ChartState:
        return ChartState(
            frozenset(self.interpreter.configuration),
            dict(self.interpreter.context),
            self.clock.time,
            tuple(self.sent),
        )

    def settle(self) -> None:
        for _ in range(MAX_STEPS_PER_EVENT):
            try:
                step = self.interpreter.execute_once()
            except ExecutionError as failure:  # the step was rolled back: what did it raise?
                raise _broken(failure.cause) from None
            except Exception as error:  # noqa: BLE001 - a crashing step is a finding
                raise _broken(error) from None
            if step is None:
                return
            self.visited.update(self.interpreter.configuration)
            self.check_invariant()
        raise _Broken("unstable", f"the chart did not settle within {MAX_STEPS_PER_EVENT} steps")

    def check_invariant(self) -> None:
        if self.invariant is None:
            return
        try:
            result = self.invariant(self.state())
        except AssertionError as error:
            raise _Broken(
                "invariant",
                f"the invariant failed: {error}" if str(error) else "the invariant failed",
            ) from None
        if result is False:
            name = getattr(self.invariant, "__name__", "invariant")
            raise _Broken("invariant", f"the invariant {name}() returned False")


def _broken(error: BaseException) -> _Broken:
    """The finding of a step that raised ``error``: a contract, a monitor, or a crash."""
    if isinstance(error, ContractError):
        return _Broken(
            "contract", f"a contract failed: {type(error).__name__}: {_contract(error)}"
        )
    if isinstance(error, PropertyStatechartError):
        monitor = error.property_statechart.statechart
        about = (monitor.description or "").strip().splitlines()
        return _Broken(
            f"monitor {monitor.name}",
            f"the property statechart {monitor.name!r} reached its final state"
            + (f" ({about[0].strip()} …)" if about else ""),
        )
    return _Broken(
        f"raised {type(error).__name__}", f"the step raised {type(error).__name__}: {error}"
    )


def _replay(make: Callable[[], _Runner], events: Sequence[dict[str, Any]]):
    """Run ``events`` on a fresh runner: ``(runner, _Broken or None)``."""
    runner = make()
    try:
        runner.start()
        for item in events:
            runner.send(item["time"], item["event"], item.get("data") or {})
    except _Broken as broken:
        return runner, broken
    return runner, None


def _minimise(
    make: Callable[[], _Runner], events: list[dict[str, Any]], kind: str
) -> list[dict[str, Any]]:
    """Drop events (and move times earlier) while the same kind of failure still happens.

    hypothesis shrinks the sequence already; this finishes the job on the exact sequence, so that
    no single event can be removed and no event can be sent earlier (one-minimal).
    """

    def fails(candidate: list[dict[str, Any]]) -> bool:
        _, broken = _replay(make, candidate)
        return broken is not None and broken.kind == kind

    current = list(events)
    changed = True
    while changed:
        changed = False
        for index in range(len(current)):
            candidate = current[:index] + current[index + 1 :]
            if fails(candidate):
                current, changed = candidate, True
                break
        if changed:
            continue
        for index, item in enumerate(current):
            earlier = current[index - 1]["time"] if index else 0.0
            if item["time"] > earlier:
                candidate = [dict(e) for e in current]
                shift = item["time"] - earlier
                for later in candidate[index:]:
                    later["time"] = round(later["time"] - shift, 9)
                if fails(candidate):
                    current, changed = candidate, True
                    break
    return current


# --------------------------------------------------------------------------- reporting


def _format_sequence(events: Sequence[dict[str, Any]]) -> list[str]:
    if not events:
        return ["    (no event: the initial step)"]
    lines = []
    for k, item in enumerate(events, start=1):
        data = f"  {item['data']}" if item.get("data") else ""
        lines.append(f"    {k}. t={format_seconds(item['time'])}  {item['event']}{data}")
    return lines


# --------------------------------------------------------------------------- the machine


def statechart_machine(
    chart: str | Path | Statechart,
    *,
    invariant: Callable[[ChartState], Any] | None = None,
    events: Iterable[str] | Mapping[str, Any] | None = None,
    monitors: Iterable[str | Path | Statechart] | None = None,
    delays: Sequence[float] | st.SearchStrategy[float] | None = None,
    initial_context: Mapping[str, Any] | None = None,
    steps: int = 20,
) -> type[RuleBasedStateMachine]:
    """A hypothesis state machine that explores ``chart`` (a YAML path, YAML text or Statechart).

    * ``events``: the events to send; default, every event its transitions name. A dict maps an
      event to its data: ``None``, a dict, or a strategy of dicts (JSON values, so that the
      saved events file replays it).
    * ``monitors``: property statecharts to bind; default, those of ``monitors/`` that apply
      (see :mod:`rasm.testing.monitors`); ``[]`` binds none.
    * ``delays``: the waits before each event (numbers or a strategy); default
      :func:`timer_delays`.
    * ``initial_context``: the chart's initial variables (a replay with ``rasm simulate`` starts
      from the chart's own defaults instead).
    * ``steps``: the most events in one sequence (hypothesis' ``stateful_step_count``).

    Run it under pytest with ``TestChart = statechart_machine(...).TestCase``; change its budget
    with ``TestChart.settings = settings(max_examples=..., stateful_step_count=...)``.
    """
    statechart, path = _load(chart)
    if invariant is not None and not callable(invariant):
        raise TypeError(
            f"invariant must be a function of the chart's state returning a bool (e.g. "
            f"lambda state: not state.active('fault')), not {type(invariant).__name__}"
        )
    if initial_context is not None and not isinstance(initial_context, Mapping):
        raise TypeError(
            f"initial_context must be a dict of the chart's variables, "
            f"not {type(initial_context).__name__}"
        )
    if not isinstance(steps, int) or isinstance(steps, bool) or steps < 1:
        raise ValueError(f"steps must be an int >= 1 (the longest sequence), not {steps!r}")
    data_strategies = _event_strategies(statechart, events)
    bound = (
        applicable_monitors(statechart, monitors)
        if monitors is None
        else [m if isinstance(m, Statechart) else load_statechart(m) for m in monitors]
    )
    context0 = _initial_context(statechart, initial_context)
    delay = _delay_strategy(statechart, delays, context0)
    names = list(data_strategies)
    by_event = {n: [t for t in statechart.transitions if t.event == n] for n in names}
    where = path or f"<{statechart.name}>"
    chart_arg = path or "CHART.yaml"

    def make() -> _Runner:
        return _Runner(statechart, bound, invariant, initial_context)

    class StatechartMachine(RuleBasedStateMachine):
        """Sends events to the chart; checks contracts, monitors and the invariant."""

        def __init__(self) -> None:
            super().__init__()
            self.runner = make()
            self._checked(self.runner.start)

        @rule(data=st.data(), delay=delay)
        def send(self, data: st.DataObject, delay: float) -> None:
            """Wait ``delay``, then send one event: mostly one an active state reacts to (an
            event nobody handles changes nothing but what the monitors see), one time in five
            any event of the list."""
            __tracebackhide__ = True
            expected = self._expected()
            anything = not expected or data.draw(st.integers(0, 4), label="any event?") == 4
            name = data.draw(st.sampled_from(names if anything else expected), label="event")
            strategy = data_strategies[name]
            self._send(name if strategy is None else (name, data.draw(strategy)), delay)

        def _expected(self) -> list[str]:
            active = self.runner.interpreter.configuration
            return [name for name in names if any(t.source in active for t in by_event[name])]

        def _send(self, event: Any, delay: float) -> None:
            __tracebackhide__ = True
            name, data = (event, {}) if isinstance(event, str) else event
            time = self.runner.clock.time + delay
            self._checked(lambda: self.runner.send(time, name, data))

        def teardown(self) -> None:
            # guide the search towards sequences that reach more of the chart
            target(float(len(self.runner.visited)), label="states visited")

        def _checked(self, action: Callable[[], None]) -> None:
            __tracebackhide__ = True  # pytest shows the user's test, not this machinery
            try:
                action()
            except _Broken as broken:
                self._fail(broken)

        def _fail(self, broken: _Broken) -> None:
            __tracebackhide__ = True
            runner, events, saved = self.runner, self.runner.sent, None
            final = is_final_example()
            if final:
                events = _minimise(make, list(events), broken.kind)
                runner, again = _replay(make, events)
                broken = again or broken
            configuration = frozenset(runner.interpreter.configuration)
            lines = [
                f"statechart {statechart.name!r} ({where}): {broken.why}",
                f"after {len(events)} event(s), the shortest sequence found:",
                *_format_sequence(events),
                f"configuration: {', '.join(sorted(configuration)) or '(none)'}",
            ]
            if final:
                saved = save_jsonl(statechart.name, events)
                lines.append(f"replay it: rasm simulate {chart_arg} --events {saved}")
            raise ChartFailure(
                "\n".join(lines),
                reason=broken.why,
                events=events,
                configuration=configuration,
                saved=saved,
            ) from None

    StatechartMachine.__name__ = StatechartMachine.__qualname__ = _class_name(statechart.name)
    StatechartMachine.TestCase.settings = settings(
        deadline=None,
        # no explain phase: it re-runs the failure under a tracer and adds nothing to the list
        phases=[Phase.explicit, Phase.reuse, Phase.generate, Phase.target, Phase.shrink],
        stateful_step_count=steps,
        suppress_health_check=list(HealthCheck),
    )
    return StatechartMachine


def _contract(error: ContractError) -> str:
    obj = error.obj
    where = getattr(obj, "name", None) or str(obj)
    return f"{error.condition!r} on {where}"


def _class_name(name: str) -> str:
    words = [w for w in "".join(c if c.isalnum() else " " for c in name).split() if w]
    title = "".join(w[:1].upper() + w[1:] for w in words) or "Chart"
    return title + "Machine" if not title[0].isdigit() else "Chart" + title + "Machine"
