"""Checking a trace in parts: each part's verdicts exactly those of one pass over the whole.

A bounded property's value at a record depends on the records its windows reach (back by its
past bounds and ``prev``, ahead by its future bounds) and on the signals' held values
(sample-and-hold). A part of the trace — the records it *answers for* — is therefore checked on
a little more than itself:

- before it, the records the properties' past reaches from its first record (found by walking
  the formula: a past window from a record, ``prev`` one record back; :func:`past_depth`);
- before those, nothing but each signal's last value, *carried* into the first record read;
- after it, the records up to the first one later than its last record plus the properties'
  longest future reach (:func:`future_reach`), so that every verdict it answers for is decided.

The verdicts of the records it answers for are then those of one pass; so are its counts,
violations, errors, vacuity and (by :func:`explain_part`, once the parts before it are counted)
its explanations. A property with an unbounded past (``once``, ``historically``, ``since`` or an
aggregate without an upper bound) reaches every record before: it is checked in one pass
(:func:`splittable`). A trace is read as a :class:`Part` — :class:`ListPart` for records in
memory; :mod:`rasm.trace_parts` reads a JSONL file by byte ranges.
"""

from __future__ import annotations

import math
import re
from bisect import bisect_right
from collections.abc import Collection, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from itertools import chain, islice
from typing import Protocol

from rasm.properties.ast import (
    Aggregate,
    Expr,
    Future,
    Past,
    Prev,
    Since,
    Specification,
    Until,
    children,
)
from rasm.properties.check import (
    CHUNK,
    ERRORS_NAMED,
    EXPLAINED,
    NAMED,
    SUMMARISED,
    CheckReport,
    PropertyReport,
    _Tally,
    _Times,
)
from rasm.properties.codegen import checked_signals
from rasm.properties.explain import Explanation, explain
from rasm.properties.monitor import Monitor
from rasm.properties.outcome import PropertyOutcome
from rasm.properties.times import nanoseconds
from rasm.properties.vacuity import Vacuity

__all__ = [
    "ListPart", "Part", "PartResult", "check_part", "explain_part", "future_reach", "merge_parts",
    "past_depth", "splittable", "subspec",
]

Record = tuple[float, Mapping[str, object]]
FROM_START = math.inf  # a past that reaches the first record of the trace


class Part(Protocol):
    """One part of a trace, and the records around it, each read when asked for."""

    def inside(self) -> Iterator[Record]:
        """The records the part answers for, in order."""

    def beyond(self) -> Iterator[Record]:
        """The records after the part, in order."""

    def earlier(self) -> Iterator[Record]:
        """The records before the part, newest first."""

    def held_before(self, count: int, names: Collection[str]) -> dict[str, object]:
        """The last value each of ``names`` was given by a record older than the ``count``
        records just before the part (where none was, the name is left out)."""


class ListPart:
    """Records ``start`` to ``end`` of a trace in memory."""

    def __init__(self, records: Sequence[Record], start: int, end: int) -> None:
        self.records, self.start, self.end = records, start, end

    def inside(self) -> Iterator[Record]:
        return iter(self.records[self.start:self.end])

    def beyond(self) -> Iterator[Record]:
        return iter(self.records[self.end:])

    def earlier(self) -> Iterator[Record]:
        return (self.records[j] for j in range(self.start - 1, -1, -1))

    def held_before(self, count: int, names: Collection[str]) -> dict[str, object]:
        wanted, found = set(names), {}
        for j in range(self.start - count - 1, -1, -1):
            if not wanted:
                break
            record = self.records[j][1]
            for name in wanted & record.keys():
                found[name] = record[name]
            wanted -= record.keys()
        return found


# --------------------------------------------------------------------------- reaches


def _nodes(formula: Expr) -> Iterator[Expr]:
    stack = [formula]
    while stack:
        node = stack.pop()
        yield node
        stack.extend(children(node))


def splittable(formula: Expr) -> bool:
    """Whether the formula's past is bounded (no past window without an upper bound): only
    such a property can be checked in parts."""
    return not any(isinstance(n, (Past, Since, Aggregate)) and n.bound.high_ns == math.inf
                   for n in _nodes(formula))


def future_reach(formula: Expr) -> int:
    """How far ahead (ns) of a record the formula's value there may look."""
    if isinstance(formula, Future):
        return formula.bound.high_ns + future_reach(formula.operand)
    if isinstance(formula, Until):
        return formula.bound.high_ns + max(future_reach(formula.left), future_reach(formula.right))
    return max((future_reach(c) for c in children(formula)), default=0)


class _Behind:
    """The times (ns) of the records before a part, newest first, read as they are needed;
    record 0 is the part's first."""

    def __init__(self, first_ns: int, earlier: Iterator[Record]) -> None:
        self.earlier = earlier
        self.records: list[Record] = []
        self.negated = [-first_ns]  # non-decreasing, for bisect
        self.ended = False

    def more(self) -> bool:
        if self.ended:
            return False
        item = next(self.earlier, None)
        if item is None:
            self.ended = True
            return False
        self.records.append(item)
        self.negated.append(-nanoseconds(item[0]))
        return True

    def oldest_within(self, k: int | float, span: int) -> int | float:
        """The oldest record (number back) whose time is within ``span`` ns before record k's,
        FROM_START when the window may reach the first record of the trace."""
        if k == FROM_START:
            return FROM_START
        while len(self.negated) <= k and self.more():
            pass
        if len(self.negated) <= k:
            return FROM_START
        limit = self.negated[k] + span  # the negated time of the window's start
        while self.negated[-1] <= limit and self.more():
            pass
        if self.negated[-1] <= limit:
            return FROM_START
        return bisect_right(self.negated, limit, k) - 1


def past_depth(formula: Expr, behind: _Behind, k: int | float = 0) -> int | float:
    """How many records before record ``k`` (counted back from a part's first) the formula's
    values at that record and every later one may depend on (FROM_START: all of them).

    Each past window is placed at the oldest record the outer operators reach (a value at an
    older record reaches no later), each ``prev`` steps one record back; a future window
    starts at its own record."""
    if k == FROM_START:
        return FROM_START
    if isinstance(formula, Prev):
        return past_depth(formula.operand, behind, k + 1)
    if isinstance(formula, (Past, Since, Aggregate)):
        k = behind.oldest_within(k, formula.bound.high_ns)
    return max([k, *(past_depth(c, behind, k) for c in children(formula))])


def subspec(spec: Specification, names: Collection[str]) -> Specification:
    """The specification with only the properties ``names`` (its declarations and the types of
    all its signals kept, so every record is checked as the whole file checks it)."""
    return replace(spec, properties=tuple(p for p in spec.properties if p.name in names))


# --------------------------------------------------------------------------- one part


@dataclass
class PropertyPart:
    """One property over the records a part answers for; indices count from its first."""

    outcome: PropertyOutcome
    violations: list[tuple[int, float]]
    first_errors: list[tuple[int, float, str]]
    held: list[bool]  # per antecedent of ->: held on a record of the part
    missing: tuple[str, ...] = ()


@dataclass
class PartResult:
    """What :func:`check_part` found: per property, and the number of records of the part.

    ``read_from`` is how many records before the part were read (its monitor counts from the
    first of them)."""

    records: int
    properties: list[PropertyPart]
    read_from: int = 0


def _events(spec: Specification) -> set[str]:
    return {e.name for e in spec.events}


def _prepare(spec: Specification, part: Part) -> tuple[list[Record], Iterator[Record], int]:
    """The records to feed before the part's (the first of all carrying the signals' held
    values), the part's own records, and how many records before the part are fed."""
    inside = part.inside()
    first = next(inside, None)
    if first is None:
        return [], iter(()), 0
    behind = _Behind(nanoseconds(first[0]), part.earlier())
    depth = max((past_depth(p.formula, behind) for p in spec.properties), default=0)
    if depth == FROM_START:
        while behind.more():
            pass
        depth = len(behind.records)
    else:
        while len(behind.records) < depth and behind.more():
            pass
    depth = min(int(depth), len(behind.records))
    fed = [*reversed(behind.records[:depth]), first]
    held = set(checked_signals(spec)) - _events(spec) - fed[0][1].keys()
    carried = part.held_before(depth, held) if held else {}
    if carried:
        fed[0] = (fed[0][0], {**carried, **fed[0][1]})
    return fed[:-1], chain([fed[-1]], inside), depth


def check_part(spec: Specification, part: Part, *, chunk: int = CHUNK,
               named: bool = False) -> PartResult:
    """Check every property of ``spec`` (each of bounded past: :func:`splittable`) on the
    records ``part`` answers for, as one pass over the whole trace would.

    ``named``: keep only the first violations of each property (as a text report names
    them); the counts count them all."""
    fed, own, depth = _prepare(spec, part)
    first = next(own, None)
    if first is None:
        return PartResult(0, [PropertyPart(PropertyOutcome(p.name), [], [], [])
                              for p in spec.properties])
    monitor = Monitor(spec)
    vacuity = Vacuity(spec)
    vacuity.counted = (depth, None)
    tallies = [_Tally(p.name, NAMED if named else None, None) for p in spec.properties]
    times = _Times()
    ahead = max((future_reach(p.formula) for p in spec.properties), default=0)
    count = 0  # records fed
    inside: int | None = None  # the part's own records, once all are read
    last_ns = 0
    beyond = part.beyond()

    def records() -> Iterator[Record]:
        nonlocal inside, last_ns
        yield from fed
        n = 0
        for record in chain([first], own):
            n += 1
            yield record
            last_ns = record[0]
        inside = n
        vacuity.counted = (depth, depth + n)
        last_ns = nanoseconds(last_ns)
        for record in beyond:
            yield record
            if nanoseconds(record[0]) > last_ns + ahead:
                return

    def take() -> None:
        end = None if inside is None else depth + inside
        for k, tally in enumerate(tallies):
            at, values, errors = monitor.take(k)  # the verdicts of records at, at + 1, …
            low = max(depth - at, 0)
            high = len(values) if end is None else max(min(len(values), end - at), 0)
            if low >= high:
                continue
            kept = {j: why for j, why in errors.items() if at + low <= j < at + high}
            tally.add(at + low, values[low:high], kept, times)
        owed = [s + monitor.verdicts_taken(k) for k, s in enumerate(monitor.starts)
                if s is not None]
        times.forget_before(min([*owed, count]))

    stream = records()
    while batch := list(islice(stream, chunk)):
        monitor.feed(batch)
        vacuity.feed(batch)
        times.held.extend([t for t, _ in batch])
        count += len(batch)
        take()
    monitor.settle()
    vacuity.settle()
    take()
    assert inside is not None
    results = []
    for k, (prop, tally) in enumerate(zip(spec.properties, tallies, strict=True)):
        held = [h for _, h in vacuity.antecedents(prop.name)]
        missing = monitor.missing(prop.name) if monitor.starts[k] is None else ()
        results.append(PropertyPart(
            tally.outcome,
            [(j - depth, t) for j, t in tally.violations],
            [(j - depth, t, why) for j, t, why in tally.first_errors],
            held,
            missing,
        ))
    return PartResult(inside, results, depth)


# --------------------------------------------------------------------------- the whole


_AT_RECORD = re.compile(r"(raised \S+ at record )(\d+)")


def _shifted(why: str, offset: int, depth: int) -> str:
    """An error's reason, its record counted in the whole trace (a part's monitor counts from
    the first record it read)."""
    return _AT_RECORD.sub(lambda m: f"{m[1]}{int(m[2]) - depth + offset}", why, count=1)


def merge_parts(spec: Specification, results: Sequence[PartResult], *, trace: str,
                named: bool = False) -> CheckReport:
    """The report of one pass over the whole trace, from its parts' in order."""
    reports = []
    offsets = [0]
    for result in results:
        offsets.append(offsets[-1] + result.records)
    vacuity = Vacuity(spec)  # (its antecedents, in order: the parts' flags are theirs)
    for k, prop in enumerate(spec.properties):
        outcome = PropertyOutcome(prop.name)
        violations: list[tuple[int, float]] = []
        first_errors: list[tuple[int, float, str]] = []
        held: list[bool] | None = None
        for result, offset in zip(results, offsets, strict=False):
            if not result.records:  # a part of blank lines judged nothing
                continue
            part = result.properties[k]
            o = part.outcome
            outcome.judged += o.judged
            outcome.violations += o.violations
            outcome.inconclusive += o.inconclusive
            outcome.errors += o.errors
            if outcome.first_error is None and o.first_error is not None:
                outcome.first_error = _shifted(o.first_error, offset, result.read_from)
            room = None if not named else NAMED - len(violations)
            violations.extend((j + offset, t) for j, t in part.violations[:room])
            first_errors.extend(
                (j + offset, t, _shifted(why, offset, result.read_from))
                for j, t, why in part.first_errors[:ERRORS_NAMED - len(first_errors)]
            )
            held = part.held if held is None else [a or b for a, b in zip(
                held, part.held, strict=True)]
        counted = [r for r in results if r.records]
        if not outcome.judged and counted:
            outcome.missing = counted[-1].properties[k].missing
        outcome.vacuous = tuple(untested for n, (untested, _) in enumerate(
            vacuity.antecedents(prop.name)) if not (held and held[n]))
        reports.append(PropertyReport(prop.name, str(prop.location), outcome, violations, None,
                                      first_errors))
    return CheckReport(spec.source, trace, offsets[-1], reports)


def wanted_explanations(report: CheckReport) -> dict[str, list[int]]:
    """The violations a text report explains: each property's first ones."""
    limit = EXPLAINED + SUMMARISED
    return {r.name: [i for i, _ in r.violations[:limit]] for r in report.properties
            if r.violations}


def explain_part(spec: Specification, part: Part, wanted: Mapping[str, Iterable[int]],
                 offset: int) -> dict[tuple[str, int], Explanation]:
    """Explain the violations ``wanted`` (indices in the whole trace) that lie in ``part``,
    whose first record is record ``offset`` of the whole trace, as one pass explains them."""
    fed, own, depth = _prepare(spec, part)
    records = chain(fed, own, part.beyond())
    return explain(spec, records, {k: list(v) for k, v in wanted.items()},
                   first=offset - depth)
