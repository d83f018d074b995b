"""Past-time properties over a chart's macro steps, with states an exploration can compare.

``rasm verify --properties`` judges each property at every macro step, with the semantics of
SPEC §5 (the records are the steps; a step's time is its time). An online monitor keeps absolute
times, so the same situation reached at two times would look like two states and the
exploration would never end. Here each operator's memory is kept *relative to now*: the ages of
the records that still matter, capped where larger ages can no longer change the value (an
unbounded ``once`` keeps one age, capped at its lower bound). So a property's state is a small
hashable tuple, part of the exploration's state.

Besides the context variables a property reads, three functions are signals here:
``in_state("s")`` (state s is active after the step), ``received("e")`` (the step consumed
event e) and ``sent("e")`` (the step sent e).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

from rasm.errors import Location, SourceError
from rasm.properties import ast as A
from rasm.properties.parser import parse_declarations
from rasm.properties.printer import format_value, unparse
from rasm.times import from_nanoseconds

__all__ = ["PastProperty", "Record", "STEP_FUNCTIONS", "calls", "explain", "load_past_properties"]

STEP_FUNCTIONS = ("in_state", "received", "sent")
UNDEFINED = None  # prev() at the first step, a variable the context does not have, x / 0


class Record(NamedTuple):
    """One macro step as the properties see it (a named tuple: the exploration makes one per
    macro step)."""

    time_ns: int
    configuration: frozenset[str]
    received: str | None
    sent: frozenset[str]
    context: Mapping[str, Any]
    transitions: bool = True  # whether a transition fired (False: an ignored event)

    def signal(self, name: str) -> Any:
        value = self.context.get(name, UNDEFINED)
        return value if isinstance(value, bool | int | float | str) else UNDEFINED


def _truth(value: Any) -> bool:
    return value is not UNDEFINED and bool(value)


def _arith(op: str, a: Any, b: Any) -> Any:
    if a is UNDEFINED or b is UNDEFINED or isinstance(a, str) or isinstance(b, str):
        return UNDEFINED
    try:
        if op == "+":
            return a + b
        if op == "-":
            return a - b
        if op == "*":
            return a * b
        return a / b
    except (ZeroDivisionError, OverflowError, TypeError):
        return UNDEFINED


_COMPARE: dict[str, Callable[[Any, Any], bool]] = {
    "==": lambda a, b: a == b, "!=": lambda a, b: a != b,
    "<": lambda a, b: a < b, "<=": lambda a, b: a <= b,
    ">": lambda a, b: a > b, ">=": lambda a, b: a >= b,
}


def _compare(op: str, a: Any, b: Any) -> bool:
    if a is UNDEFINED or b is UNDEFINED:
        return False
    if isinstance(a, float) and math.isnan(a) or isinstance(b, float) and math.isnan(b):
        return False
    try:
        return _COMPARE[op](a, b)
    except TypeError:
        return False


class _Node:
    """A compiled node: ``value(record, states, new)`` reads its children's values; temporal
    nodes read their old state at ``self.slot`` of ``states`` and write the new one to ``new``."""

    slot = -1
    expr: A.Expr  # what it was compiled from (for explanations)

    def value(self, record: Record, states: tuple, new: list, dt: int | None) -> Any:
        raise NotImplementedError


class _Const(_Node):
    def __init__(self, value: Any) -> None:
        self.v = value

    def value(self, record, states, new, dt):
        return self.v


class _Signal(_Node):
    def __init__(self, name: str) -> None:
        self.name = name

    def value(self, record, states, new, dt):
        return record.signal(self.name)


class _StepFunction(_Node):
    def __init__(self, func: str, arg: str) -> None:
        self.func = func
        self.arg = arg

    def value(self, record, states, new, dt):
        if self.func == "in_state":
            return self.arg in record.configuration
        if self.func == "received":
            return record.received == self.arg
        return self.arg in record.sent


class _Time(_Node):
    def value(self, record, states, new, dt):
        return from_nanoseconds(record.time_ns)


class _Op(_Node):
    def __init__(self, op: str, *children: _Node) -> None:
        self.op = op
        self.children = children

    def value(self, record, states, new, dt):  # noqa: C901 - one case per operator
        op, kids = self.op, self.children
        if op == "and":
            a = _truth(kids[0].value(record, states, new, dt))
            b = _truth(kids[1].value(record, states, new, dt))
            return a and b
        if op == "or":
            a = _truth(kids[0].value(record, states, new, dt))
            b = _truth(kids[1].value(record, states, new, dt))
            return a or b
        if op == "->":
            a = _truth(kids[0].value(record, states, new, dt))
            b = _truth(kids[1].value(record, states, new, dt))
            return (not a) or b
        if op == "not":
            return not _truth(kids[0].value(record, states, new, dt))
        values = [kid.value(record, states, new, dt) for kid in kids]
        if op == "neg":
            v = values[0]
            return UNDEFINED if v is UNDEFINED or isinstance(v, str) else -v
        if op in _COMPARE:
            return _compare(op, *values)
        if op in ("+", "-", "*", "/"):
            return _arith(op, *values)
        if op == "abs":
            v = values[0]
            return UNDEFINED if v is UNDEFINED or isinstance(v, str) else abs(v)
        if op in ("min", "max"):
            if UNDEFINED in values:
                return UNDEFINED
            return min(values) if op == "min" else max(values)
        raise AssertionError(op)


class _Prev(_Node):
    def __init__(self, operand: _Node, slot: int) -> None:
        self.operand = operand
        self.slot = slot

    def value(self, record, states, new, dt):
        current = self.operand.value(record, states, new, dt)
        new[self.slot] = current
        return UNDEFINED if dt is None else states[self.slot]


def _aged(ages: tuple, dt: int | None, high: float) -> list:
    """Ages moved on by ``dt``, those past ``high`` dropped (in order, oldest first)."""
    if dt is None:
        return []
    return [age + dt for age in ages if age + dt <= high]


class _Window(_Node):
    """``once``, ``historically`` and ``since`` over the past window [low, high] (ns): the state
    is the ages of the candidate records (oldest first, no two equal); an unbounded window keeps
    only the oldest, capped at ``low`` (older ones decide exactly as it does)."""

    def __init__(self, kind: str, bound: A.Bound, left: _Node | None, right: _Node, slot: int):
        self.kind = kind  # once | historically | since
        self.low = bound.low_ns
        self.high = bound.high_ns
        self.left = left
        self.right = right
        self.slot = slot

    def value(self, record, states, new, dt):
        old = states[self.slot] if dt is not None else ()
        ages = _aged(old, dt, self.high)
        if self.kind == "since":
            if not _truth(self.left.value(record, states, new, dt)):
                ages = []
            hit = _truth(self.right.value(record, states, new, dt))
        else:
            v = _truth(self.right.value(record, states, new, dt))
            hit = v if self.kind == "once" else not v
        if hit and (not ages or ages[-1] != 0):
            ages.append(0)
        if self.high == math.inf and ages:
            ages = [min(ages[0], self.low)]  # the oldest decides
        new[self.slot] = tuple(ages)
        found = any(self.low <= age <= self.high for age in ages)
        return (not found) if self.kind == "historically" else found


class _Aggregate(_Node):
    """``count sum avg min max`` over [low, high]: the state is the (age, value) of every
    record in the window (an unbounded window grows: the exploration then ends inconclusive)."""

    def __init__(self, op: str, bound: A.Bound, operand: _Node, slot: int) -> None:
        self.op = op
        self.low = bound.low_ns
        self.high = bound.high_ns
        self.operand = operand
        self.slot = slot

    def value(self, record, states, new, dt):
        old = states[self.slot] if dt is not None else ()
        entries = [] if dt is None else [(a + dt, v) for a, v in old if a + dt <= self.high]
        v = self.operand.value(record, states, new, dt)
        entries.append((0, v))
        new[self.slot] = tuple(entries)
        inside = [v for a, v in entries if self.low <= a <= self.high]
        if self.op == "count":
            return sum(1 for v in inside if _truth(v))
        values = [v for v in inside if v is not UNDEFINED and not isinstance(v, str | bool)]
        if self.op == "sum":
            return sum(values) if len(values) == len(inside) else UNDEFINED
        if not inside or len(values) != len(inside):
            return UNDEFINED
        if self.op == "avg":
            return sum(values) / len(values)
        return min(values) if self.op == "min" else max(values)


@dataclass
class PastProperty:
    """One property of a verification: its name, formula, the variables it reads."""

    name: str
    formula: A.Expr
    location: Location
    root: _Node
    slots: int
    variables: frozenset[str]

    def initial(self) -> tuple:
        return (None,) * self.slots

    def step(self, state: tuple, record: Record, dt: int | None) -> tuple[bool, tuple]:
        """The property's value at ``record`` (``dt``: ns since the previous record, None at
        the first) and its new state."""
        new = list(state)
        value = _truth(self.root.value(record, state, new, dt))
        return value, tuple(new)


def explain(prop: PastProperty, state: tuple, record: Record, dt: int | None) -> list[str]:
    """Why ``prop`` is false at ``record`` (its state before it): the sub-formulas that made it
    false, innermost last, with the values of the variables they read."""
    lines: list[str] = []
    scratch = list(state)

    def value(node: _Node) -> Any:
        return node.value(record, state, scratch, dt)

    def why(node: _Node, wanted: bool) -> None:
        text = unparse(node.expr)
        lines.append(f"{text} is {'false' if wanted else 'true'}")
        if isinstance(node, _Op):
            kids = node.children
            if node.op == "not":
                why(kids[0], not wanted)
                return
            if node.op == "and" and wanted:  # false: a false side
                side = kids[0] if not _truth(value(kids[0])) else kids[1]
                why(side, True)
                return
            if node.op == "or" and wanted:  # false: both sides false
                why(kids[0], True)
                why(kids[1], True)
                return
            if node.op == "->" and wanted:  # false: left true, right false
                why(kids[0], False)
                why(kids[1], True)
                return
        signals = sorted(_signals(node))
        if signals:
            lines.append("  where " + ", ".join(
                f"{name} = {format_value(record.signal(name))}" for name in signals
            ))

    why(prop.root, True)
    return lines


def _signals(node: _Node) -> set[str]:
    found: set[str] = set()
    stack = [node.expr]
    while stack:
        expr = stack.pop()
        if isinstance(expr, A.Name):
            found.add(expr.name)
        stack.extend(A.children(expr))
    return found


class _Compiler:
    def __init__(self, lets: dict[str, A.Expr], declared: dict[str, str], file: str) -> None:
        self.lets = lets
        self.declared = declared
        self.file = file
        self.slots = 0
        self.variables: set[str] = set()

    def slot(self) -> int:
        self.slots += 1
        return self.slots - 1

    def error(self, message: str, node: Any) -> SourceError:
        where = getattr(node, "location", None) or Location(self.file)
        return SourceError(message, where)

    def compile(self, node: A.Expr) -> _Node:
        compiled = self._compile(node)
        compiled.expr = node
        return compiled

    def _compile(self, node: A.Expr) -> _Node:  # noqa: C901 - one case per node
        if isinstance(node, A.Literal):
            return _Const(node.value)
        if isinstance(node, A.Name):
            if node.name in self.lets:
                return self.compile(self.lets[node.name])
            self.variables.add(node.name)
            return _Signal(node.name)
        if isinstance(node, A.Time):
            return _Time()
        if isinstance(node, A.Not):
            return _Op("not", self.compile(node.operand))
        if isinstance(node, A.Unary):
            return _Op("neg", self.compile(node.operand))
        if isinstance(node, A.Binary):
            return _Op(node.op, self.compile(node.left), self.compile(node.right))
        if isinstance(node, A.Call):
            if node.func in STEP_FUNCTIONS:
                if len(node.args) != 1 or not (
                    isinstance(node.args[0], A.Literal) and isinstance(node.args[0].value, str)
                ):
                    raise self.error(
                        f'{node.func}() takes one name in quotes, as in {node.func}("idle")', node
                    )
                return _StepFunction(node.func, node.args[0].value)
            if node.func == "abs" and len(node.args) == 1:
                return _Op("abs", self.compile(node.args[0]))
            if node.func in ("min", "max") and len(node.args) == 2:
                return _Op(node.func, *map(self.compile, node.args))
            raise self.error(
                f"unknown function {node.func!r} (a verified property may call abs, min, max, "
                "in_state, received and sent)", node,
            )
        if isinstance(node, A.Prev):
            return _Prev(self.compile(node.operand), self.slot())
        if isinstance(node, A.Past):
            return _Window(node.op, node.bound, None, self.compile(node.operand), self.slot())
        if isinstance(node, A.Since):
            return _Window(
                "since", node.bound, self.compile(node.left), self.compile(node.right), self.slot()
            )
        if isinstance(node, A.Aggregate):
            return _Aggregate(node.op, node.bound, self.compile(node.operand), self.slot())
        if isinstance(node, A.Future | A.Until):
            raise self.error(
                "rasm verify judges a property at every step, with past-time operators only "
                "(once, historically, since, prev and the aggregates): write what must have "
                "happened, not what will (e.g. 'in_state(\"done\") -> once received(\"go\")')",
                node,
            )
        raise self.error("not allowed in a verified property", node)


def _strip_always(node: A.Expr) -> A.Expr:
    if isinstance(node, A.Future) and node.op == "always" and node.bound.high == math.inf \
            and node.bound.low == 0:
        return node.operand
    return node


def calls(prop: PastProperty) -> Iterator[A.Call]:
    """The ``in_state``, ``received`` and ``sent`` calls of ``prop``'s formula."""
    stack = [prop.formula]
    while stack:
        node = stack.pop()
        if isinstance(node, A.Call) and node.func in STEP_FUNCTIONS:
            yield node
        stack.extend(A.children(node))


def load_past_properties(text: str, *, source: str) -> list[PastProperty]:
    """The properties of a property file, for ``rasm verify`` (errors at their line and col)."""
    declarations = parse_declarations(text, source=source)
    lets: dict[str, A.Expr] = {}
    declared: dict[str, str] = {}
    out: list[PastProperty] = []
    seen: set[str] = set()
    for item in declarations:
        if isinstance(item, A.Input):
            declared[item.name] = item.type
        elif isinstance(item, A.Event):
            declared[item.name] = "bool"
        elif isinstance(item, A.Let):
            lets[item.name] = item.expr
        elif isinstance(item, A.Property):
            if item.name in seen:
                raise SourceError(f"property {item.name!r} is defined twice", item.location)
            seen.add(item.name)
            compiler = _Compiler(lets, declared, source)
            formula = _strip_always(item.formula)
            root = compiler.compile(formula)
            out.append(PastProperty(
                item.name, formula, item.location, root, compiler.slots,
                frozenset(compiler.variables),
            ))
    if not out:
        raise SourceError("the file has no property to verify", Location(source, 1, 1))
    return out
