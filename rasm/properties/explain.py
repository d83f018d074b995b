"""Explaining violations: which sub-formula failed, where, and the signal values behind it.

Every sub-formula of a violated property is compiled as a *probe* (a property of its own,
warmed up like its parent, so its values are the ones it had inside the parent) and the trace
is run once more through those probes. An explanation then walks down from the property: for
``and`` the false conjuncts, for ``->`` the consequent, for ``historically`` the record inside
the window where the operand failed, for a comparison the values of both sides, and so on.

The records pass by one chunk at a time (:class:`Explainer`): only those an explanation still
to give may look at are kept — from as far back as its past windows reach to as far ahead as its
future windows do — and never more than ``keep`` of them. A past window that reaches further
back than the records kept says so ("… earlier records not kept"); the verdicts themselves are
exact either way. Values are abridged: a long string shows its start and its length.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from itertools import islice

from rasm.properties.ast import (
    BOOLEAN,
    COMPARISONS,
    Binary,
    Expr,
    Future,
    Literal,
    Name,
    Not,
    Past,
    Property,
    Since,
    Specification,
    Until,
    children,
    walk,
)
from rasm.properties.loader import signals_of
from rasm.properties.monitor import Monitor
from rasm.properties.printer import format_value, unparse
from rasm.properties.times import format_seconds, nanoseconds
from rasm.properties.visitor import Transformer, Visitor

__all__ = ["ABRIDGE", "KEEP", "Explainer", "Explanation", "abridge", "explain"]

MAX_LINES = 12
KEEP = 65_536  # records kept for the explanations still to give, at most
ABRIDGE = 80  # characters of a string value shown in an explanation


def abridge(value: object) -> object:
    """``value`` as an explanation shows it: a string longer than :data:`ABRIDGE` characters
    is cut, with its length (one 10 MB value is not 10 MB of explanation)."""
    if isinstance(value, str) and len(value) > ABRIDGE:
        return f"{value[:ABRIDGE]}… ({len(value):,} characters)"
    return value


@dataclass(frozen=True)
class Explanation:
    """Why ``property`` was false at record ``index``: text lines and the signal values
    (abridged)."""

    property: str
    index: int
    time: float
    lines: tuple[str, ...]
    signals: dict[str, object]


def _subformulas(node: Expr) -> list[Expr]:
    # a literal is its own explanation, but the property itself needs its table (its start)
    return [n for n in walk(node) if not isinstance(n, Literal) or n is node]


# how far before and after a record (ns) an explanation of a node there may look
Reach = tuple[int | float, int | float]


class _Reach(Transformer[Reach]):
    """How far an explanation may look: it walks down through ``not``, ``and``, ``or``,
    ``->`` and the windows of the temporal operators; every other node is shown by its value
    at the record itself."""

    def past(self, node: Past, operand: Reach) -> Reach:
        back, ahead = operand
        return back + node.bound.high_ns, ahead

    def future(self, node: Future, operand: Reach) -> Reach:
        back, ahead = operand
        return back, ahead + node.bound.high_ns

    def not_(self, node: Not, operand: Reach) -> Reach:
        return operand

    def binary(self, node: Binary, left: Reach, right: Reach) -> Reach:
        if node.op in BOOLEAN:
            return max(left[0], right[0]), max(left[1], right[1])
        return 0, 0

    def _here(self, node: Expr, *operands: Reach) -> Reach:
        return 0, 0

    literal = name = time = unary = call = prev = since = until = aggregate = _here


_REACH = _Reach()


def _reach(node: Expr) -> Reach:
    """How far before and after a record (ns) an explanation of ``node`` there may look."""
    return _REACH.visit(node)


class _Rows:
    """The records kept for one property's explanations: their times (as given and in exact
    ns) and every probe's values, by record index, from ``first`` on. A probe's values arrive
    when it has decided them (a future window's later), so each probe has its own end."""

    def __init__(self, probes: int, first: int = 0) -> None:
        self.first = first  # the index of the oldest record kept
        self.times: list = []
        self.ns: list[int] = []
        self.values: list[list] = [[] for _ in range(probes)]
        self.value_first: list[int | None] = [None] * probes  # the index of values[k][0]
        self.dropped_ns: int | None = None  # the time of the newest record no longer kept

    @property
    def end(self) -> int:
        return self.first + len(self.times)

    def add(self, records: Sequence[tuple[float, Mapping[str, object]]]) -> None:
        self.times.extend(t for t, _ in records)
        self.ns.extend(nanoseconds(t) for t, _ in records)

    def add_values(self, k: int, first: int, values: list) -> None:
        """Probe ``k``'s values of records ``first``, ``first + 1``, …; those of records no
        longer kept are left out."""
        if not values:
            return
        if self.value_first[k] is None:
            self.value_first[k] = max(first, self.first)
        kept = self.values[k]
        skip = self.value_first[k] + len(kept) - first
        kept.extend(values[skip:] if skip > 0 else values)

    def delivered(self) -> int:
        """The records below this index have every probe's value."""
        ends = [f + len(v) for f, v in zip(self.value_first, self.values, strict=True)
                if f is not None]
        return min(ends) if len(ends) == len(self.values) else -1

    def drop_before(self, index: int) -> None:
        cut = index - self.first
        if cut <= 0:
            return
        self.dropped_ns = self.ns[min(cut, len(self.ns)) - 1]
        del self.times[:cut], self.ns[:cut]
        self.first = index
        for k, first in enumerate(self.value_first):
            if first is not None and first < index:
                del self.values[k][: index - first]
                self.value_first[k] = index

    def value(self, k: int, index: int):
        first = self.value_first[k]
        assert first is not None
        return self.values[k][index - first]


class _Part:
    """One violated property: its probes run over the records as they come, and its wanted
    violations explained as soon as every record their windows reach has its values."""

    def __init__(self, spec: Specification, prop: Property, wanted: list[int], keep: int,
                 first: int = 0) -> None:
        self.name = prop.name
        self.offset = first  # the index of the first record fed (its monitor counts from 0)
        self.formula = prop.formula
        self.keep = keep
        self.reads = tuple(signals_of(prop.formula))
        nodes = _subformulas(prop.formula)
        self.probes = len(nodes)
        self.number = {node: k for k, node in enumerate(nodes)}  # equal nodes: one of them
        probe_spec = Specification(
            source=spec.source,
            inputs=spec.inputs,
            events=spec.events,
            lets=(),
            properties=tuple(Property(f"#{k}", node) for k, node in enumerate(nodes)),
            signals=spec.signals,
        )
        self.monitor = Monitor(probe_spec, reads=[self.reads] * len(nodes))
        self.rows = _Rows(len(nodes), first)
        self.back, self.ahead = _reach(prop.formula)
        self.pending = sorted(set(wanted))
        self.explained: list[Explanation] = []

    @property
    def done(self) -> bool:
        return not self.pending

    def feed(self, records: list, snapshots: Mapping[int, dict]) -> None:
        self.rows.add(records)
        self.monitor.feed(records)
        self._take()
        self._explain_ready(snapshots, final=False)
        self._trim(snapshots)

    def finish(self, snapshots: Mapping[int, dict]) -> None:
        if self.pending:
            self.monitor.settle()
            self._take()
            self._explain_ready(snapshots, final=True)

    def _take(self) -> None:
        for k in range(self.probes):
            first, values, _ = self.monitor.take(k)
            self.rows.add_values(k, first + self.offset, values)

    def _explain_ready(self, snapshots: Mapping[int, dict], final: bool) -> None:
        rows = self.rows
        delivered = rows.end if final else rows.delivered()
        while self.pending and self.pending[0] < rows.end:
            i = self.pending[0]
            if not final:
                # every record up to the farthest its future windows reach has its values
                after = bisect_right(rows.ns, rows.ns[i - rows.first] + self.ahead,
                                     i - rows.first) + rows.first
                if after >= rows.end or delivered < after:
                    return
            self._explain(i, snapshots)
            self.pending.pop(0)

    def _explain(self, i: int, snapshots: Mapping[int, dict], lines: tuple[str, ...] = ()) -> None:
        start = (self.monitor.starts[0] or 0) + self.offset
        if not lines:
            explainer = _Explainer(self.rows, self.number, start)
            explainer.explain(self.formula, i, True, 0)
            lines = tuple(explainer.lines)
        held = snapshots.get(i, {})
        self.explained.append(Explanation(
            self.name, i, self.rows.times[i - self.rows.first], lines,
            {n: abridge(held.get(n)) for n in self.reads},
        ))

    def _trim(self, snapshots: Mapping[int, dict]) -> None:
        """Keep only the records the explanations still to give may look at (``keep`` at
        most: one whose own record would go is given without its detail)."""
        rows = self.rows
        if not self.pending:
            rows.drop_before(rows.end)
            return
        i = self.pending[0]
        anchor = rows.ns[i - rows.first] if i < rows.end else rows.ns[-1] if rows.ns else None
        if anchor is not None:
            oldest = bisect_left(rows.ns, anchor - self.back) + rows.first
            rows.drop_before(min(oldest, i))
        excess = len(rows.times) - self.keep
        if excess > 0:
            cut = rows.first + excess
            while self.pending and self.pending[0] < cut:
                i = self.pending.pop(0)
                self._explain(i, snapshots, (
                    f"(not explained: the records it depends on span more than {self.keep:,}; "
                    "rasm check keeps no more of them)",
                ))
            rows.drop_before(cut)


class Explainer:
    """Explains the violations ``{property name: [record index, …]}`` of one trace, fed to it
    in order, part by part (:meth:`feed`), holding no more of it than the explanations still to
    give need (at most ``keep`` records per property); :meth:`finish` at the end of the trace.
    Feeding can stop as soon as :attr:`done`. ``first`` is the index of the first record fed
    (a part of a trace checked in parts begins further on)."""

    def __init__(self, spec: Specification, violations: Mapping[str, Sequence[int]], *,
                 keep: int = KEEP, first: int = 0) -> None:
        self._parts = [
            _Part(spec, prop, list(violations[prop.name]), keep, first)
            for prop in spec.properties if violations.get(prop.name)
        ]
        self._snapshots = _Snapshots(spec, [i for p in self._parts for i in p.pending])
        self.records = first

    @property
    def done(self) -> bool:
        """Every violation asked for is explained."""
        return all(part.done for part in self._parts)

    def feed(self, records: Iterable[tuple[float, Mapping[str, object]]]) -> None:
        """The next records of the trace."""
        records = list(records)
        self._snapshots.feed(self.records, records)
        for part in self._parts:
            if not part.done:
                part.feed(records, self._snapshots.taken)
        self.records += len(records)

    def finish(self) -> dict[tuple[str, int], Explanation]:
        """The end of the trace: every explanation, by (property, record index)."""
        for part in self._parts:
            part.finish(self._snapshots.taken)
        return {(e.property, e.index): e for part in self._parts for e in part.explained}


class _Snapshots:
    """The properties' signals' held values at each of the records ``wanted`` (sample-and-hold,
    events false where not set)."""

    def __init__(self, spec: Specification, wanted: Iterable[int]) -> None:
        self.names = list(spec.signals)
        self.events = [e.name for e in spec.events]
        self.current: dict[str, object] = {
            i.name: i.default for i in spec.inputs if i.default is not None
        }
        self.wanted = set(wanted)
        self.last = max(self.wanted, default=-1)
        self.taken: dict[int, dict] = {}

    def feed(self, first: int, records: list) -> None:
        current, events = self.current, self.events
        for index, (_, record) in enumerate(records, first):
            if index > self.last:
                return
            for name in events:
                current[name] = False
            current.update(record)
            if index in self.wanted:
                self.taken[index] = {n: current[n] for n in self.names if n in current}


class _Explainer(Visitor[None]):
    """One explanation, read from the records kept (``rows``): a pass whose methods say why
    a node was ``not want`` at record ``i``, ``depth`` levels in."""

    def __init__(self, rows: _Rows, number: Mapping[Expr, int], start: int) -> None:
        self.rows = rows
        self.number = number
        self.start = start
        self.lines: list[str] = []

    def say(self, depth: int, text: str) -> None:
        if len(self.lines) < MAX_LINES:
            self.lines.append("  " * depth + text)

    def time_of(self, j: int):
        return self.rows.times[j - self.rows.first]

    def at(self, j: int) -> str:
        return f"record {j} (time {format_seconds(self.time_of(j))})"

    def val(self, node: Expr, j: int):
        if isinstance(node, Literal):
            return node.value
        return self.rows.value(self.number[node], j)

    def shown(self, node: Expr, j: int) -> str:
        return f"{unparse(node)} = {format_value(abridge(self.val(node, j)))}"

    def past_window(self, node, i: int) -> tuple[range, bool]:
        """The records j <= i with a <= t_i - t_j <= b, newest first (found by bisection), and
        whether the window reaches judged records no longer kept."""
        a, b = node.bound.low_ns, node.bound.high_ns
        rows = self.rows
        ns, first = rows.ns, rows.first
        now = ns[i - first]
        lowest = max(self.start, first) - first
        low = bisect_left(ns, now - b, lowest, i - first + 1)
        high = bisect_right(ns, now - a, lowest, i - first + 1) - 1
        # a judged record no longer kept may lie in the window (when the newest of them is
        # newer than the window's start it may, and one not older than its end surely does)
        clipped = (self.start < first and rows.dropped_ns is not None
                   and now - b <= rows.dropped_ns)
        return range(high + first, low + first - 1, -1), clipped

    def future_window(self, node, i: int) -> tuple[range, bool]:
        """The records j >= i with a <= t_j - t_i <= b, oldest first (none is left out: they
        are kept until every explanation that looks at them is given)."""
        a, b = node.bound.low_ns, node.bound.high_ns
        ns, first = self.rows.ns, self.rows.first
        now = ns[i - first]
        low = bisect_left(ns, now + a, i - first)
        high = bisect_right(ns, now + b, i - first) - 1
        return range(low + first, high + first + 1), False

    def leaves(self, node: Expr, i: int, depth: int) -> None:
        # the values of the operands that are not literals, e.g. "velocity = 0.7"
        for child in children(node):
            if not isinstance(child, Literal):
                self.say(depth, self.shown(child, i))

    def explain(self, node: Expr, i: int, want: bool, depth: int) -> None:
        """Say why ``node`` was ``not want`` at record ``i``."""
        if len(self.lines) < MAX_LINES and depth <= 8:
            self.visit(node, i, want, depth)

    def name(self, node: Name, i: int, want: bool, depth: int) -> None:
        self.say(depth, f"{node.name} was {format_value(abridge(self.val(node, i)))}")

    def not_(self, node: Not, i: int, want: bool, depth: int) -> None:
        self.say(depth, f"{unparse(node)} {_failed(want)}:")
        self.explain(node.operand, i, not want, depth + 1)

    def binary(self, node: Binary, i: int, want: bool, depth: int) -> None:
        if node.op in COMPARISONS:
            self.say(depth, f"{unparse(node)} {_failed(want)}:")
            self.leaves(node, i, depth + 1)
            return
        if node.op not in BOOLEAN:  # arithmetic: its value
            self.say(depth, self.shown(node, i))
            return
        self.say(depth, f"{unparse(node)} {_failed(want)}:")
        parts = [(node.left, want), (node.right, want)]
        if node.op == "->":
            parts = [(node.left, not want), (node.right, want)]
        decisive = (node.op == "and") == want or (node.op == "->" and want)
        for child, child_want in parts:
            if self.val(child, i) is (not child_want):
                self.explain(child, i, child_want, depth + 1)
                if decisive and node.op != "->":
                    return

    def past(self, node: Past, i: int, want: bool, depth: int) -> None:
        self.window(node, *self.past_window(node, i), want, depth)

    def future(self, node: Future, i: int, want: bool, depth: int) -> None:
        self.window(node, *self.future_window(node, i), want, depth)

    def window(self, node: Past | Future, window: range, clipped: bool, want: bool,
               depth: int) -> None:
        """``node`` at a record whose ``window`` of records is this (``clipped``: judged
        records in it are no longer kept)."""
        text, failed = unparse(node), _failed(want)
        exists = node.op in ("once", "eventually")
        if exists == want:
            # nothing in the window did it
            where = self.span(window)
            if clipped:
                where += f"; its records before record {self.rows.first} were not kept"
            self.say(depth, f"{text} {failed}: {unparse(node.operand)} never "
                            f"{'held' if want else 'failed'} {where}")
            return
        witness = next((j for j in window if self.val(node.operand, j) is (not want)), None)
        self.say(depth, f"{text} {failed}:")
        if witness is not None:
            self.say(depth + 1, f"at {self.at(witness)}:")
            self.explain(node.operand, witness, want, depth + 2)
        elif clipped:
            self.say(depth + 1, f"at a record before record {self.rows.first} (not kept)")

    def since(self, node: Since | Until, i: int, want: bool, depth: int) -> None:
        self.say(depth, f"{unparse(node)} {_failed(want)}")
        self.say(depth + 1, self.shown(node.left, i))
        self.say(depth + 1, self.shown(node.right, i))

    until = since

    def _value(self, node: Expr, i: int, want: bool, depth: int) -> None:
        self.say(depth, self.shown(node, i))

    aggregate = prev = call = unary = time = _value

    def literal(self, node: Literal, i: int, want: bool, depth: int) -> None:
        self.say(depth, f"{unparse(node)} {_failed(want)}")

    def span(self, window: range) -> str:
        if not window:
            return "(no record in the window)"
        first, last = min(window), max(window)
        since, until = format_seconds(self.time_of(first)), format_seconds(self.time_of(last))
        return f"in records {first}–{last} (times {since}–{until})"


def _failed(want: bool) -> str:
    return "failed" if want else "held"


def explain(
    spec: Specification,
    records: Iterable[tuple[float, Mapping[str, object]]],
    violations: Mapping[str, Sequence[int]],
    *,
    keep: int = KEEP,
    chunk: int = 16_384,
    first: int = 0,
) -> dict[tuple[str, int], Explanation]:
    """Explain the given violations ``{property name: [record index, …]}`` of a trace (read
    only as far as the explanations need); ``first`` is the index of the first record given."""
    explainer = Explainer(spec, violations, keep=keep, first=first)
    records = iter(records)
    while not explainer.done and (part := list(islice(records, chunk))):
        explainer.feed(part)
    return explainer.finish()
