"""Explaining violations: which sub-formula failed, where, and the signal values behind it.

Every sub-formula of a violated property is compiled as a *probe* (a property of its own,
warmed up like its parent, so its values are the ones it had inside the parent) and the trace
is run once more through those probes. An explanation then walks down from the property: for
``and`` the false conjuncts, for ``->`` the consequent, for ``historically`` the record inside
the window where the operand failed, for a comparison the values of both sides, and so on.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from rasm.properties.ast import (
    COMPARISONS,
    Aggregate,
    Binary,
    Call,
    Expr,
    Future,
    Literal,
    Name,
    Not,
    Past,
    Prev,
    Property,
    Since,
    Specification,
    Time,
    Unary,
    Until,
    children,
)
from rasm.properties.loader import signals_of
from rasm.properties.monitor import Monitor
from rasm.properties.printer import format_value, unparse
from rasm.properties.times import nanoseconds

__all__ = ["Explanation", "explain"]

MAX_LINES = 12


@dataclass(frozen=True)
class Explanation:
    """Why ``property`` was false at record ``index``: text lines and the signal values."""

    property: str
    index: int
    time: float
    lines: tuple[str, ...]
    signals: dict[str, object]


def _subformulas(node: Expr) -> list[Expr]:
    found: list[Expr] = []

    def walk(n: Expr) -> None:
        # a literal is its own explanation, but the property itself needs its table (its start)
        if not isinstance(n, Literal) or n is node:
            found.append(n)
        for c in children(n):
            walk(c)

    walk(node)
    return found


class _Tables:
    """Every sub-formula's value at every judged record, from one run of the probes."""

    def __init__(self, spec: Specification, prop: Property, records: Sequence) -> None:
        nodes = _subformulas(prop.formula)
        probes = tuple(Property(f"#{k}", node) for k, node in enumerate(nodes))
        probe_spec = Specification(
            source=spec.source,
            inputs=spec.inputs,
            events=spec.events,
            lets=(),
            properties=probes,
            signals=spec.signals,
        )
        reads = [tuple(signals_of(prop.formula))] * len(probes)
        runs = Monitor(probe_spec, reads=reads).run(records)
        self.values = {node: run for node, run in zip(nodes, runs, strict=True)}

    def value(self, node: Expr, index: int):
        if isinstance(node, Literal):
            return node.value
        run = self.values[node]
        return run.values[index - run.start]


class _Explainer:
    def __init__(self, tables: _Tables, times: Sequence[float], start: int) -> None:
        self.tables = tables
        self.times = times
        self.ns = [nanoseconds(t) for t in times]  # exact: what the windows compare
        self.start = start
        self.lines: list[str] = []

    def say(self, depth: int, text: str) -> None:
        if len(self.lines) < MAX_LINES:
            self.lines.append("  " * depth + text)

    def at(self, j: int) -> str:
        return f"record {j} (time {self.times[j]:g})"

    def val(self, node: Expr, j: int):
        return self.tables.value(node, j)

    def shown(self, node: Expr, j: int) -> str:
        return f"{unparse(node)} = {format_value(self.val(node, j))}"

    def past_window(self, node, i: int) -> range:
        """The records j <= i with a <= t_i - t_j <= b, newest first (found by bisection)."""
        a, b = node.bound.low_ns, node.bound.high_ns
        ns = self.ns
        low = bisect_left(ns, ns[i] - b, self.start, i + 1)
        high = bisect_right(ns, ns[i] - a, self.start, i + 1) - 1
        return range(high, low - 1, -1)

    def future_window(self, node, i: int) -> range:
        """The records j >= i with a <= t_j - t_i <= b, oldest first."""
        a, b = node.bound.low_ns, node.bound.high_ns
        ns = self.ns
        low = bisect_left(ns, ns[i] + a, i)
        high = bisect_right(ns, ns[i] + b, i) - 1
        return range(low, high + 1)

    def leaves(self, node: Expr, i: int, depth: int) -> None:
        # the values of the operands that are not literals, e.g. "velocity = 0.7"
        for child in children(node):
            if not isinstance(child, Literal):
                self.say(depth, self.shown(child, i))

    def explain(self, node: Expr, i: int, want: bool, depth: int) -> None:  # noqa: C901
        """Say why ``node`` was ``not want`` at record ``i``."""
        if len(self.lines) >= MAX_LINES or depth > 8:
            return
        text = unparse(node)
        failed = "held" if not want else "failed"
        if isinstance(node, Name):
            self.say(depth, f"{node.name} was {format_value(self.val(node, i))}")
            return
        if isinstance(node, Not):
            self.say(depth, f"{text} {failed}:")
            self.explain(node.operand, i, not want, depth + 1)
            return
        if isinstance(node, Binary) and node.op in ("and", "or", "->"):
            self.say(depth, f"{text} {failed}:")
            parts = [(node.left, want), (node.right, want)]
            if node.op == "->":
                parts = [(node.left, not want), (node.right, want)]
            decisive = (node.op == "and") == want or (node.op == "->" and want)
            for child, child_want in parts:
                if self.val(child, i) is (not child_want):
                    self.explain(child, i, child_want, depth + 1)
                    if decisive and node.op != "->":
                        return
            return
        if isinstance(node, Binary) and node.op in COMPARISONS:
            self.say(depth, f"{text} {failed}:")
            self.leaves(node, i, depth + 1)
            return
        if isinstance(node, Past) or isinstance(node, Future):
            window = (self.past_window if isinstance(node, Past) else self.future_window)(node, i)
            exists = node.op in ("once", "eventually")
            if exists == want:
                # nothing in the window did it
                where = _span(self.times, window)
                self.say(depth, f"{text} {failed}: {unparse(node.operand)} never "
                                f"{'held' if want else 'failed'} {where}")
                return
            witness = next((j for j in window if self.val(node.operand, j) is (not want)), None)
            self.say(depth, f"{text} {failed}:")
            if witness is not None:
                self.say(depth + 1, f"at {self.at(witness)}:")
                self.explain(node.operand, witness, want, depth + 2)
            return
        if isinstance(node, (Since, Until)):
            self.say(depth, f"{text} {failed}")
            self.say(depth + 1, self.shown(node.left, i))
            self.say(depth + 1, self.shown(node.right, i))
            return
        if isinstance(node, (Aggregate, Prev, Call, Unary, Binary, Time)):
            self.say(depth, self.shown(node, i))
            return
        self.say(depth, f"{text} {failed}")


def _span(times: Sequence[float], window: range) -> str:
    if not window:
        return "(no record in the window)"
    first, last = min(window), max(window)
    return f"in records {first}–{last} (times {times[first]:g}–{times[last]:g})"


def explain(
    spec: Specification,
    records: Sequence[tuple[float, Mapping[str, object]]],
    violations: Mapping[str, Sequence[int]],
) -> dict[tuple[str, int], Explanation]:
    """Explain the given violations ``{property name: [record index, …]}`` of a trace."""
    result: dict[tuple[str, int], Explanation] = {}
    times = [t for t, _ in records]
    wanted = sorted({i for indices in violations.values() for i in indices})
    snapshots = _snapshots(spec, records, wanted)
    for prop in spec.properties:
        indices = violations.get(prop.name)
        if not indices:
            continue
        tables = _Tables(spec, prop, records)
        start = tables.values[prop.formula].start
        names = signals_of(prop.formula)
        for i in indices:
            explainer = _Explainer(tables, times, start)
            explainer.explain(prop.formula, i, True, 0)
            signals = {n: snapshots[i].get(n) for n in names}
            result[(prop.name, i)] = Explanation(
                prop.name, i, times[i], tuple(explainer.lines), signals
            )
    return result


def _snapshots(spec: Specification, records, wanted: list[int]) -> dict[int, dict]:
    events = {e.name for e in spec.events}
    current = {i.name: i.default for i in spec.inputs if i.default is not None}
    out: dict[int, dict] = {}
    targets = set(wanted)
    last = max(wanted) if wanted else -1
    for index, (_, record) in enumerate(records):
        if index > last:
            break
        for name in events:
            current[name] = False
        current.update(record)
        if index in targets:
            out[index] = dict(current)
    return out


