"""``traces(props)``: a hypothesis strategy of traces for a property file's signals.

A trace is a list of records, ``{"time": t, "velocity": 0.3, "anomaly": True}``, with
non-decreasing times starting at 0. What is generated follows the file:

* every **input** (declared, or inferred from how the properties use it) gets values of its type;
  the first record sets every input that has no default, later records update some of them
  (sample-and-hold);
* every **event** is set (to ``true``) on few records, and left out of the others;
* **numbers** stay within their *range*. The property language has no syntax for ranges, so a
  range is read from a comment on the input's own line, ``input velocity: float  # range [0, 1.5]``,
  or given as ``ranges={"velocity": (0, 1.5)}`` (which wins). Without one, numbers lie in
  ``[-M, M]`` where M is 100 or twice the largest constant the properties compare the signal with;
* **strings** are drawn from the string constants the properties compare the signal with, its
  default, and ``"other"``; or from ``ranges={"mode": ["idle", "dock"]}``;
* the **gap** between two records lies in ``[0, max_gap]`` seconds, in milliseconds; ``max_gap``
  defaults to 1.5 times the largest time bound of the file (1 s without bounds), so that windows
  are both met and missed.

Everything shrinks towards short traces, zero gaps, absent updates, no events, and values near
zero (or the range's lower end, or the first string constant).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

from rasm.errors import Misfit
from rasm.properties.ast import (
    COMPARISONS,
    INF,
    Aggregate,
    Binary,
    Bound,
    Expr,
    Future,
    Literal,
    Name,
    Past,
    Since,
    Specification,
    Until,
    walk,
)
from rasm.properties.visitor import Transformer
from rasm.testing._props import PropertyFile, property_file
from rasm.values import fit

__all__ = ["traces", "signal_domains", "Domain"]

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_RANGE_COMMENT = re.compile(rf"#.*?\brange\s*[\[(]\s*({_NUMBER})\s*[,:]\s*({_NUMBER})\s*[\])]")
_EVENT_ONE_IN = 8  # an event is set on about one record in eight
_DEFAULT_SPAN = 100.0


@dataclass(frozen=True)
class Domain:
    """The values generated for one signal: a type and either a numeric range or choices."""

    name: str
    type: str  # float | int | bool | str | any
    low: float | None = None
    high: float | None = None
    choices: tuple[Any, ...] = ()
    required: bool = True  # set by the first record (no declared default)

    def strategy(self) -> st.SearchStrategy[Any]:
        if self.choices:
            return st.sampled_from(self.choices)
        if self.type == "bool":
            return st.booleans()
        if self.type == "int" or self.type == "any":
            return st.integers(math.ceil(self.low), math.floor(self.high))
        return st.floats(self.low, self.high, allow_nan=False, allow_infinity=False)


def _formulas(spec: Specification) -> list[Expr]:
    return [p.formula for p in spec.properties] + [let.expr for let in spec.lets]


def _constants(spec: Specification) -> dict[str, list[Any]]:
    """Constants each signal is compared with anywhere in the file (in order of appearance)."""
    found: dict[str, list[Any]] = {}
    for formula in _formulas(spec):
        for node in walk(formula):
            if not (isinstance(node, Binary) and node.op in COMPARISONS):
                continue
            for a, b in ((node.left, node.right), (node.right, node.left)):
                if isinstance(a, Name) and isinstance(b, Literal):
                    values = found.setdefault(a.name, [])
                    if b.value not in values:
                        values.append(b.value)
    return found


class _Windows(Transformer[list[Bound]]):
    """The bounds of the windows a node and the nodes below it open."""

    def past(
        self, node: Past | Future | Since | Until | Aggregate, *below: list[Bound]
    ) -> list[Bound]:
        return [node.bound, *(bound for bounds in below for bound in bounds)]

    future = since = until = aggregate = past

    def _below(self, node: Expr, *below: list[Bound]) -> list[Bound]:
        return [bound for bounds in below for bound in bounds]

    literal = name = time = unary = not_ = binary = call = prev = _below


def _largest_bound(spec: Specification) -> float | None:
    ends = [
        end
        for formula in _formulas(spec)
        for bound in _Windows().visit(formula)
        for end in (bound.low, bound.high)
        if end != INF
    ]
    return max(ends, default=None)


def _comment_ranges(file: PropertyFile) -> dict[str, tuple[float, float]]:
    lines = file.text.splitlines()
    out = {}
    for item in file.spec.inputs:
        line = item.location.line
        if 1 <= line <= len(lines):
            match = _RANGE_COMMENT.search(lines[line - 1])
            if match:
                out[item.name] = (float(match.group(1)), float(match.group(2)))
    return out


def signal_domains(
    props: str | Path | Specification,
    ranges: Mapping[str, Any] | None = None,
) -> dict[str, Domain]:
    """The domain :func:`traces` draws each input from (events excluded), by signal name.

    Raises ``ValueError`` for a range that names no signal of the file, or that does not fit its
    signal's type.
    """
    file = property_file(props)
    spec = file.spec
    events = {e.name for e in spec.events}
    defaults = {i.name: i.default for i in spec.inputs if i.default is not None}
    constants = _constants(spec)
    given = dict(_comment_ranges(file))
    for name, value in (ranges or {}).items():
        if name not in spec.signals or name in events:
            known = ", ".join(sorted(n for n in spec.signals if n not in events)) or "none"
            raise ValueError(
                f"ranges names {name!r}, which is not an input of {file.source} "
                f"(its inputs: {known}); check the spelling"
            )
        given[name] = value
    domains = {}
    for name, kind in spec.signals.items():
        if name in events:
            continue
        required = name not in defaults
        if name in given:
            domains[name] = _given_domain(name, kind, given[name], required, file.source)
            continue
        if kind == "bool":
            domains[name] = Domain(name, kind, required=required)
        elif kind == "str":
            choices = [c for c in constants.get(name, []) if isinstance(c, str)]
            for extra in (defaults.get(name), "other"):
                if extra is not None and extra not in choices:
                    choices.append(extra)
            domains[name] = Domain(name, kind, choices=tuple(choices), required=required)
        else:
            numbers = [abs(c) for c in constants.get(name, []) if _is_number(c)]
            if _is_number(defaults.get(name)):
                numbers.append(abs(defaults[name]))
            span = max([_DEFAULT_SPAN, *(2 * x for x in numbers)])
            if kind == "any":
                span = 10.0 if not numbers else span
            domains[name] = Domain(name, kind, -span, span, required=required)
    return domains


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _given_domain(name: str, kind: str, value: Any, required: bool, source: str) -> Domain:
    if isinstance(value, tuple) and len(value) == 2 and all(_is_number(v) for v in value):
        low, high = float(value[0]), float(value[1])
        if kind not in ("float", "int", "any"):
            raise ValueError(
                f"range {value!r} for {name!r}: {name} is a {kind} in {source}, not a number; "
                f"give a list of its values instead, e.g. ranges={{{name!r}: [...]}}"
            )
        if not (math.isfinite(low) and math.isfinite(high)) or low > high:
            raise ValueError(
                f"range {value!r} for {name!r} must be (low, high) with finite low <= high"
            )
        if kind == "int" and math.ceil(low) > math.floor(high):
            raise ValueError(f"range {value!r} for the int signal {name!r} holds no integer")
        return Domain(name, kind, low, high, required=required)
    if isinstance(value, list | tuple | set | frozenset) and value:
        choices = tuple(sorted(value, key=repr) if isinstance(value, set | frozenset) else value)
        wrong = [c for c in choices if not _fits(kind, c)]
        if wrong:
            raise ValueError(
                f"ranges[{name!r}] holds {wrong[0]!r}, which is not a {kind} "
                f"(the type of {name} in {source})"
            )
        return Domain(name, kind, choices=choices, required=required)
    raise ValueError(
        f"ranges[{name!r}] must be (low, high) for a number or a non-empty list of values, "
        f"not {value!r}"
    )


def _fits(kind: str, value: Any) -> bool:
    try:
        fit(value, kind, int_as_float=False)
    except Misfit:
        return False
    return True


def _last(k: int) -> bool:
    return k == _EVENT_ONE_IN - 1


def _milliseconds(count: int) -> float:
    return count / 1000


def traces(
    props: str | Path | Specification,
    *,
    min_records: int = 1,
    max_records: int = 50,
    max_gap: float | None = None,
    ranges: Mapping[str, tuple[float, float] | Sequence[Any]] | None = None,
) -> st.SearchStrategy[list[dict[str, Any]]]:
    """A strategy of traces for the signals of ``props`` (a ``.rv`` path or its text).

    Each trace has between ``min_records`` and ``max_records`` records; consecutive times differ
    by at most ``max_gap`` seconds. ``ranges`` maps an input to ``(low, high)`` or to a list of
    its values (see the module documentation for the defaults). Use it with ``@given``::

        @given(traces("props.rv", ranges={"velocity": (0, 1)}))
        def test_limit_holds(trace): ...
    """
    file = property_file(props)
    if min_records < 0 or max_records < min_records:
        raise ValueError(
            f"need 0 <= min_records <= max_records, got min_records={min_records}, "
            f"max_records={max_records}"
        )
    if max_gap is None:
        largest = _largest_bound(file.spec)
        max_gap = 1.5 * largest if largest else 1.0
    if not (max_gap >= 0 and math.isfinite(max_gap)):
        raise ValueError(f"max_gap must be a finite number of seconds >= 0, not {max_gap!r}")
    domains = signal_domains(file, ranges)
    events = [e.name for e in file.spec.events]
    updates = st.fixed_dictionaries({}, optional={n: d.strategy() for n, d in domains.items()})
    first = st.fixed_dictionaries({n: d.strategy() for n, d in domains.items() if d.required})
    sparse = st.integers(0, _EVENT_ONE_IN - 1).map(_last)
    happened = st.fixed_dictionaries({e: sparse for e in events})
    # whole milliseconds (integers shrink more predictably than floats), never above max_gap
    gap = st.integers(0, math.floor(max_gap * 1000)).map(_milliseconds)
    rows = st.lists(st.tuples(gap, updates, happened), min_size=min_records, max_size=max_records)

    @st.composite
    def build(draw: st.DrawFn) -> list[dict[str, Any]]:
        drawn = draw(rows)
        initial = draw(first) if drawn else {}
        trace, time = [], 0.0
        for index, (step, values, fired) in enumerate(drawn):
            if index:
                time = round(time + step, 6)
            record: dict[str, Any] = {"time": time}
            if index == 0:
                record.update(initial)
            record.update(values)
            record.update({e: True for e, on in fired.items() if on})
            trace.append(record)
        return trace

    return build()
