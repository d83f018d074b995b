"""One property's code: the generator that turns a formula into generated lines.

Sub-formulas that only look at the past are *immediate*: their value at record i is known at
record i, and they become straight-line code with their state in closure variables (a last
witness time, a deque of not-yet-old-enough witnesses). Anything above a future operator is a
*stream* (``rasm.properties.streams``) whose values come late, each as soon as it is decided
and in any order; the generated code feeds the streams their immediate inputs and reads the
property's verdicts off the top stream.
:mod:`rasm.properties.codegen` puts the properties' lines together into one program.

``time`` is exact (:func:`is_time`): its value is the record's time in integer nanoseconds
(``tn``), and so are the sums, differences, negations, ``abs``, ``min``, ``max`` and ``prev`` of
times; a number they meet is read as a time (to the nanosecond) and a comparison with one is
made in nanoseconds. Where a time meets anything else (``*``, ``/``, an aggregate, the value of
a probe) it becomes the float nearest its seconds. So ``time - prev(time) >= 0.2`` holds at 0.3
after 0.1, as ``once[0.2, 0.2]`` does.
"""

from __future__ import annotations

import math
from collections import deque
from fractions import Fraction

from rasm.errors import SourceError
from rasm.properties.ast import (
    COMPARISONS,
    INF,
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
    Since,
    Specification,
    Time,
    Unary,
    Until,
    children,
)
from rasm.properties.expr import _ARITH, _ARITH_NAMES, _COMPARE, HELPERS, _max2, _min2
from rasm.properties.operators import WindowCore
from rasm.properties.printer import unparse
from rasm.properties.streams import (
    AggregateStream,
    InOrder,
    JoinStream,
    PrevStream,
    SinceStream,
    Source,
    UntilStream,
    WindowStream,
)
from rasm.properties.times import NS_PER_SECOND, from_nanoseconds, nanoseconds
from rasm.properties.types import TypeScope

__all__ = ["FormulaGenerator", "is_time", "normalise", "signal_variable"]


def is_time(node: Expr) -> bool:
    """Whether ``node``'s value is a time or a duration, carried as exact nanoseconds: ``time``,
    and the ``prev``, negation, ``abs``, ``min``, ``max``, sums and differences of times.

    Not where a future operator's value takes part in the arithmetic (``time -
    count[0, 1](eventually p)``): such values come late, through streams that compute in
    seconds, so there times are the floats of their seconds."""
    if isinstance(node, Time):
        return True
    if isinstance(node, (Prev, Unary)):
        return is_time(node.operand)
    if isinstance(node, Binary) and node.op in ("+", "-") or isinstance(node, Call):
        return any(map(is_time, children(node))) and not _looks_ahead(node)
    return False


def _looks_ahead(node: Expr) -> bool:
    return isinstance(node, (Future, Until)) or any(map(_looks_ahead, children(node)))


def _as_nanoseconds(value: object) -> object:
    """A number that meets a time, as exact nanoseconds (:mod:`rasm.times`: a float stands for
    its shortest decimal); what is no finite number stays as it is (undefined stays undefined,
    inf infinite, a string fails the operator as it would have)."""
    if value.__class__ is bool:
        return int(value) * NS_PER_SECOND  # true is 1, as in any arithmetic
    ns = nanoseconds(value)
    return value if ns is None else ns


def _as_seconds(value: object) -> object:
    """A time in nanoseconds as the float nearest its seconds (undefined stays undefined)."""
    return from_nanoseconds(value) if value.__class__ is int else value / NS_PER_SECOND


def normalise(node: Expr) -> Expr:
    """Rewrite historically/always via once/eventually: ``historically φ = not once not φ``."""
    if isinstance(node, Past) and node.op == "historically":
        inner = Past(
            "once",
            node.bound,
            Not(normalise(node.operand), location=node.location),
            location=node.location,
        )
        return Not(inner, location=node.location)
    if isinstance(node, Future) and node.op == "always":
        inner = Future(
            "eventually",
            node.bound,
            Not(normalise(node.operand), location=node.location),
            location=node.location,
        )
        return Not(inner, location=node.location)
    if isinstance(node, (Unary, Not, Prev, Past, Future, Aggregate)):
        return type(node)(**{**_fields(node), "operand": normalise(node.operand)})
    if isinstance(node, (Binary, Since, Until)):
        return type(node)(
            **{**_fields(node), "left": normalise(node.left), "right": normalise(node.right)}
        )
    if isinstance(node, Call):
        return Call(node.func, tuple(normalise(a) for a in node.args), location=node.location)
    return node


def _fields(node) -> dict:
    return {name: getattr(node, name) for name in node.__dataclass_fields__}


def _number(x: int | float) -> str:
    """A bound (integer nanoseconds, or inf) as source."""
    return "INF" if x == INF else repr(x)


class FormulaGenerator:
    """The lines of each property in turn, with the constants and closure variables they
    read (shared by all properties of a specification)."""

    def __init__(self, spec: Specification) -> None:
        self.spec = spec
        self.types = TypeScope({k: v for k, v in spec.signals.items() if v != "any"})
        self.constants: dict[str, object] = {"deque": deque, "INF": INF, "NAN": math.nan}
        self.constants.update(HELPERS, _ns=_as_nanoseconds, _seconds=_as_seconds)
        self.state: dict[str, object] = {}
        self.count = 0
        self.lines: list = []
        self.finish_lines: list = []
        self.root: Expr | None = None  # the property's formula being compiled
        self.root_number = 0
        self.owned: list[list[str]] = []  # per property: its constants and closure variables
        # the root's dict of the records it owes a verdict (online), and its InOrder: made by
        # the root when it gives early verdicts (inline_pointwise), else by generate()
        self.owed: str | None = None
        self.order: str | None = None
        # inline future windows by their Source (kept alive here, so never confused with a
        # later one): (index of their first line, pending deque, upper bound), for the parent
        # that may keep the records it decides out of them (skip_window)
        self.windows: dict[Source, tuple[int, str, int]] = {}
        self.prevs: dict[tuple[int, str], str] = {}  # (property, operand) -> its prev's value

    def fresh(self, prefix: str) -> str:
        self.count += 1
        return f"{prefix}{self.count}"

    def constant(self, prefix: str, value: object) -> str:
        name = self.fresh(prefix)
        self.constants[name] = value
        self.owned[self.root_number].append(name)
        return name

    def variable(self, prefix: str, initial: object, *, owned: bool = True) -> str:
        name = self.fresh(prefix)
        self.state[name] = initial
        if owned:
            self.owned[self.root_number].append(name)
        return name

    # ----------------------------------------------------------------- nodes
    def emit(self, node: Expr):
        """Return ``("imm", python_expression)`` or ``("stream", Stream)`` for ``node``."""
        if isinstance(node, Literal):
            return "imm", repr(node.value)
        if isinstance(node, Name):
            return "imm", signal_variable(node.name)
        if isinstance(node, Time):
            return "imm", "tn"
        if isinstance(node, Future):  # only eventually, after normalise()
            (kind, value) = self.emit(node.operand)
            a, b = node.bound.low_ns, node.bound.high_ns
            if kind == "imm":
                return self.inline_future(a, b, None, value)
            return self.stream(WindowStream, [(kind, value)], False, a, b)
        if isinstance(node, Until):
            left, right = self.emit(node.left), self.emit(node.right)
            a, b = node.bound.low_ns, node.bound.high_ns
            if left[0] == right[0] == "imm":
                return self.inline_future(a, b, left[1], right[1])
            return self.stream(UntilStream, [left, right], a, b)
        parts = self.in_units(node, [self.emit(c) for c in _operands(node)])
        streams = [k for k, (kind, _) in enumerate(parts) if kind == "stream"]
        if len(streams) == 1 and isinstance(node, (Not, Unary, Binary, Call)):
            return self.inline_pointwise(node, parts, streams[0])
        if streams:
            return self.stream_of(node, parts)
        values = [value for _, value in parts]
        if isinstance(node, Not):
            return "imm", f"(not {values[0]})"
        if isinstance(node, Unary):
            return "imm", f"(-{values[0]})"
        if isinstance(node, Binary):
            return "imm", _binary(node.op, values[0], values[1], self.integers(node))
        if isinstance(node, Call):
            return "imm", f"{_call(node.func)}({', '.join(values)})"
        if isinstance(node, Prev):
            # the same prev(φ) twice in a property holds the same values (its lines run on the
            # same records, and φ's text names the same values): one pair of lines serves both
            key = (self.root_number, values[0])
            if key not in self.prevs:
                held = self.variable("p", self.undefined(node.operand))
                out = self.fresh("v")
                self.lines += [f"{out} = {held}", f"{held} = {values[0]}"]
                self.prevs[key] = out
            return "imm", self.prevs[key]
        a, b = node.bound.low_ns, node.bound.high_ns
        if isinstance(node, Past):  # once, after normalise()
            return "imm", self.once(a, b, values[0])
        if isinstance(node, Since):
            return "imm", self.since(a, b, values[0], values[1])
        if isinstance(node, Aggregate):
            if node.op == "count" and a == 0:
                return "imm", self.count_window(b, values[0])
            core = self.constant("w", WindowCore(node.op, a, b))
            out = self.fresh("v")
            self.lines.append(f"{out} = {core}.push(tn, {values[0]})")
            return "imm", out
        raise TypeError(f"cannot compile {node!r}")

    def in_units(self, node: Expr, parts: list) -> list:
        """The immediate operands of ``node`` in the units it computes in: nanoseconds for time
        arithmetic and for a comparison with a time (:func:`is_time`), seconds elsewhere."""
        operands = _operands(node)
        exact = is_time(node) or (
            isinstance(node, Binary)
            and node.op in COMPARISONS
            and any(map(is_time, operands))
            and not _looks_ahead(node)
        )
        out = []
        for child, (kind, value) in zip(operands, parts, strict=True):
            if kind == "imm":
                value = self.nanoseconds(child, value) if exact else self.seconds(child, value)
            out.append((kind, value))
        return out

    def property_value(self, node: Expr, kind: str, value):
        """What a property's formula gives as its value: seconds where it is a time (an
        explanation's probe of ``time - prev(time)`` shows 0.2)."""
        return self.seconds(node, value) if kind == "imm" else value

    @staticmethod
    def nanoseconds(node: Expr, value: str) -> str:
        """Source of ``node``'s value in nanoseconds (``value``: its source as emitted)."""
        if is_time(node):
            return value
        number = node.value if isinstance(node, Literal) else None
        if isinstance(number, (int, float)) and not isinstance(number, bool):
            if math.isfinite(number):
                exact = Fraction(repr(number)) * NS_PER_SECOND  # the decimal, as written
                if exact.denominator != 1:
                    raise SourceError(
                        f"{unparse(node)} is finer than a nanosecond, the resolution of times: "
                        "a number added to or compared with a time is a time",
                        node.location,
                    )
                return repr(exact.numerator)
        return f"_ns({value})"

    @staticmethod
    def seconds(node: Expr, value: str) -> str:
        """Source of ``node``'s value in seconds (``value``: its source as emitted)."""
        if not is_time(node):
            return value
        return "t" if isinstance(node, Time) else f"_seconds({value})"

    def undefined(self, node: Expr) -> object:
        # prev(φ) at a property's first record: a boolean is false, anything else undefined
        return False if self.types.check(node) == "bool" else math.nan

    def integers(self, node: Binary) -> bool:
        """Both operands are ints: plain Python arithmetic is exact and cannot raise."""
        return self.types.check(node.left) == "int" and self.types.check(node.right) == "int"

    def once(self, a: int, b: int | float, value: str) -> str:
        if a == 0 and b == INF:  # once, unbounded: a flag
            seen = self.variable("f", False)
            self.lines.append(f"if {value}: {seen} = True")
            return seen
        last = self.variable("l", None)
        out = self.fresh("v")
        if a == 0:
            self.lines.append(f"if {value}: {last} = tn")
        else:
            pending = self.constant("q", deque())
            self.lines += [
                f"if {value}: {pending}.append(tn)",
                f"while {pending} and tn - {pending}[0] >= {_number(a)}: "
                f"{last} = {pending}.popleft()",
            ]
        self.lines.append(f"{out} = {self.within(last, b)}")
        return out

    def count_window(self, b: int | float, value: str) -> str:
        """``count[0,b](value)`` of a two-valued operand, written into the step function.

        The same count as :class:`WindowCore`'s (the records whose value is true, from ``t - b``
        to ``t``) without a call per record: only the times of the true records are kept.
        """
        if b == INF:  # nothing ever leaves the window: a counter
            total = self.variable("n", 0)
            self.lines.append(f"if {value}: {total} += 1")
            return total
        times = self.constant("q", deque())
        out = self.fresh("v")
        self.lines += [
            f"if {value}: {times}.append(tn)",
            f"while {times} and tn - {times}[0] > {_number(b)}: {times}.popleft()",
            f"{out} = len({times})",
        ]
        return out

    def since(self, a: int, b: int | float, left: str, right: str) -> str:
        last = self.variable("l", None)
        out = self.fresh("v")
        if a == 0:
            self.lines += [f"if not {left}: {last} = None", f"if {right}: {last} = tn"]
        else:
            pending = self.constant("q", deque())
            self.lines += [
                f"if not {left}:",
                f"    {last} = None",
                f"    {pending}.clear()",
                f"if {right}: {pending}.append(tn)",
                f"while {pending} and tn - {pending}[0] >= {_number(a)}: "
                f"{last} = {pending}.popleft()",
            ]
        self.lines.append(f"{out} = {self.within(last, b)}")
        return out

    @staticmethod
    def within(last: str, b: int | float) -> str:
        if b == INF:
            return f"{last} is not None"
        return f"{last} is not None and tn - {last} <= {_number(b)}"

    # ----------------------------------------------------------------- streams
    def stream_of(self, node: Expr, parts):
        """``node`` over two streams, or a temporal operator or ``prev`` over one."""
        if isinstance(node, Binary):
            plain = _ARITH.get(node.op) or _COMPARE.get(node.op)
            return self.stream(JoinStream, parts, node.op, plain)
        if isinstance(node, Call):
            plain = {"abs": abs, "min": _min2, "max": _max2}[node.func]
            return self.stream(JoinStream, parts, node.func, plain)
        if isinstance(node, Prev):
            return self.stream(PrevStream, parts, self.undefined(node.operand))
        a, b = node.bound.low_ns, node.bound.high_ns
        if isinstance(node, Past):
            return self.stream(WindowStream, parts, True, a, b)
        if isinstance(node, Since):
            return self.stream(SinceStream, parts, a, b)
        if isinstance(node, Aggregate):
            return self.stream(AggregateStream, parts, node.op, a, b)
        raise TypeError(f"cannot compile {node!r}")

    def stream(self, cls, parts, *args):
        inputs = [value if kind == "stream" else None for kind, value in parts]
        stream = cls(inputs, *args)
        name = self.constant("s", stream)
        immediate = [value for kind, value in parts if kind == "imm"]
        self.lines.append(f"{name}.step(i, t, tn{''.join(', ' + v for v in immediate)})")
        self.finish_lines.append(f"{name}.finish()")
        return "stream", stream

    # ----------------------------------------------------------------- inline streams
    def inline_future(self, a: int, b: int, left: str | None, right: str):
        """``eventually[a,b] right`` (left None) or ``left until[a,b] right``, both immediate.

        Written into the step function: open records wait in ``pending``, oldest first; a
        witness decides those old enough true, a record beyond the oldest ones' window (or, for
        until, a false left side) decides them false; decided ones go to the output queue,
        in record order.
        """
        source = Source(ordered=True)  # open records are decided oldest first
        out = self.constant("o", source.out)
        pending = self.constant("w", deque())
        lines = [
            f"{pending}.append((i, t, tn))",
            f"while tn - {pending}[0][2] > {_number(b)}:",
            f"    _j, _tj, _tn = {pending}.popleft()",
            f"    {out}.append((_j, _tj, _tn, False))",
            f"if {right}:",
        ]
        if a == 0:
            lines += [f"    while {pending}:"]
        else:
            lines += [f"    while {pending} and tn - {pending}[0][2] >= {_number(a)}:"]
        lines += [
            f"        _j, _tj, _tn = {pending}.popleft()",
            f"        {out}.append((_j, _tj, _tn, True))",
        ]
        if left is not None:
            lines += [
                f"if not {left}:",
                f"    while {pending}:",
                f"        _j, _tj, _tn = {pending}.popleft()",
                f"        {out}.append((_j, _tj, _tn, False))",
            ]
        self.windows[source] = (len(self.lines), pending, b)
        self.lines += lines
        # at the end of the trace the still-open windows are inconclusive
        self.finish_lines += [
            f"while {pending}:",
            f"    _j, _tj, _tn = {pending}.popleft()",
            f"    {out}.append((_j, _tj, _tn, None))",
        ]
        return "stream", source

    def inline_pointwise(self, node: Expr, parts, position: int):
        """A non-temporal operator over one stream and at most one immediate value, in
        Kleene logic.

        Where the immediate value alone decides (a false side of ``and``, a true side of ``or``,
        a false trigger of ``->``) the value is given at once; the stream's value for that record
        is then skipped when it comes (or never made, :meth:`skip_window`). Other records wait
        for the stream's value. At the property's root the early value is a verdict.
        """
        immediate = [value for kind, value in parts if kind == "imm"]
        decides = _decider(node, position) if immediate else None
        # in record order if its operand's values are and none is given early
        source = Source(ordered=parts[position][1].ordered and decides is None)
        out = self.constant("o", source.out)
        child = self.constant("c", parts[position][1].out)
        names = ["_v" if kind == "stream" else "_w" for kind, _ in parts]
        drain = [f"while {child}:", f"    _j, _tj, _tn, _v = {child}.popleft()"]
        if decides is None:
            if immediate:  # each record's immediate value waits for the stream's
                held = self.constant("b", {})
                self.lines.append(f"{held}[i] = {immediate[0]}")
                drain.append(f"    _w = {held}.pop(_j)")
        else:
            early, value, other = decides
            early = early.format(w=immediate[0])
            # a record the immediate value does not decide had the one value that does not
            # decide: nothing to hold but which records wait (none when the window skips the
            # others: it never gives them)
            names = ["_v" if kind == "stream" else other for kind, _ in parts]
            if not self.skip_window(parts[position][1], position, early):
                waiting = self.constant("b", set())
                self.lines.append(f"if not ({early}): {waiting}.add(i)")
                drain += [f"    if _j not in {waiting}: continue  # given at once",
                          f"    {waiting}.discard(_j)"]
            if node is self.root:
                # the verdict now; online, any other record is owed a verdict by the stream
                self.owed = self.constant("owed", {})
                self.lines += [
                    f"if {early}:",
                    ("EMIT", self.root_number, "i", "t", value, "    ", self.in_order()),
                    ("ONLINE", "else:", None),
                    ("ONLINE", f"    {self.owed}[i] = t", None),
                ]
            else:
                self.lines.append(f"if {early}: {out}.append((i, t, tn, {value}))")
        drain.append(f"    {out}.append((_j, _tj, _tn, {_kleene(node, names, position)}))")
        self.lines += drain
        self.finish_lines += drain
        return "stream", source

    def in_order(self) -> str:
        """The property's :class:`InOrder`: its verdicts in record order, offline."""
        if self.order is None:
            self.order = self.constant("order", InOrder())
        return self.order

    def skip_window(self, child: Source, position: int, early: str) -> bool:
        """Keep the records ``early`` decides out of the inline window ``child``.

        Their value is given at once, so the window need not wait for their witness: the
        step function then does no window work for them. Only for an inline window (a stream
        class is stepped every record) whose record is decided by the operand before it (its
        lines, computing ``early``, come first).
        """
        window = self.windows.pop(child, None)
        if window is None or position != 1:
            return False
        start, pending, b = window
        self.lines[start] = f"if not ({early}): {self.lines[start]}"
        # the window may now be empty: the current record is not always in it
        self.lines[start + 1] = f"while {pending} and tn - {pending}[0][2] > {_number(b)}:"
        return True


def _decider(node: Expr, position: int) -> tuple[str, str, str] | None:
    """When the immediate operand ``w`` alone decides ``node``: (test on w, the value then,
    w's value otherwise)."""
    if not isinstance(node, Binary):
        return None
    if node.op == "and":
        return "not {w}", "False", "True"
    if node.op == "or":
        return "{w}", "True", "False"
    if node.op == "->":
        return ("not {w}", "True", "True") if position == 1 else ("{w}", "True", "False")
    return None


def _kleene(node: Expr, names: list[str], position: int) -> str:
    """Source of ``node`` over ``names`` where ``names[position]`` may be None (inconclusive).

    Python's ``and``/``or`` are Kleene's when their left operand is two-valued, so the
    immediate operand goes first.
    """
    v = names[position]
    if isinstance(node, Not):
        return f"(None if {v} is None else not {v})"
    if isinstance(node, Binary) and node.op in ("and", "or"):
        other = names[1 - position]
        return f"({other} {node.op} {v})"
    if isinstance(node, Binary) and node.op == "->":
        if position == 1:
            return f"((not {names[0]}) or {v})"
        return f"({names[1]} or (None if {v} is None else not {v}))"
    if isinstance(node, Unary):
        plain = f"(-{v})"
    elif isinstance(node, Binary):
        plain = _binary(node.op, names[0], names[1])
    else:
        plain = f"{_call(node.func)}({', '.join(names)})"
    return f"(None if {v} is None else {plain})"


def _operands(node: Expr) -> list[Expr]:
    if isinstance(node, (Unary, Not, Prev, Past, Aggregate)):
        return [node.operand]
    if isinstance(node, (Binary, Since)):
        return [node.left, node.right]
    if isinstance(node, Call):
        return list(node.args)
    return []


def _binary(op: str, left: str, right: str, integers: bool = False) -> str:
    """Source of ``left op right``; ``integers``: both operands are ints (exact arithmetic)."""
    if op == "and":
        return f"({left} and {right})"
    if op == "or":
        return f"({left} or {right})"
    if op == "->":
        return f"((not {left}) or {right})"
    if op in _ARITH_NAMES and (op == "/" or not integers):
        # IEEE-754 without exceptions (rasm.properties.expr): an int too large for a float meeting
        # a float gives ±inf, x / 0 is undefined
        return f"{_ARITH_NAMES[op]}({left}, {right})"
    if op == "!=":
        if left.isidentifier() and right.isidentifier():
            # _ne's body inline: two variables are cheap to read twice, a call is not
            return f"({left} == {left} and {right} == {right} and {left} != {right})"
        return f"_ne({left}, {right})"
    return f"({left} {op} {right})"


def _call(func: str) -> str:
    return {"abs": "abs", "min": "_min2", "max": "_max2"}[func]


def signal_variable(name: str) -> str:
    """The generated code's variable holding signal ``name``'s current value."""
    return f"g_{name}"
