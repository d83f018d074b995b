"""One property's code in the robustness semantics (SPEC §12): a float per record.

A second generator on the base the boolean one stands on (:mod:`rasm.properties.emitter`): it
walks the formula top-down, and where a formula compares values (``x <= 0.5``,
``avg[0, 5s](t) <= 40``, ``count[0, 2](p) >= 1``) it has the values computed exactly as the
boolean semantics computes them (:class:`~rasm.properties.formula_code.FormulaGenerator`, over
the same names) and turns the comparison into a distance. Robustness known at its own record
is a Python expression (:class:`Now`); above a future operator it is a stream of final values
in record order (:class:`Late`, :mod:`rasm.properties.robust_ops`).

The lines go after the property's boolean lines (:mod:`rasm.properties.codegen`) only when the
monitor is asked for robustness: the boolean code is the same either way.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from rasm.properties.ast import (
    COMPARISONS,
    Binary,
    Expr,
    Future,
    Literal,
    Name,
    Not,
    Past,
    Prev,
    Since,
    Specification,
    Until,
    children,
)
from rasm.properties.emitter import Emitter, Later, Names, signal_variable
from rasm.properties.emitter import Now as ValueNow
from rasm.properties.formula_code import FormulaGenerator, normalise
from rasm.properties.lines import Block, Code, Line
from rasm.properties.robust_ops import (
    RCMP,
    FutureWindow,
    Ordered,
    PastStream,
    Pointwise,
    PrevStream,
    SinceCore,
    SinceStream,
    UntilStream,
    as_float,
    compare_interval,
)
from rasm.properties.streams import CountStream
from rasm.properties.types import TypeScope
from rasm.properties.units import is_time, looks_ahead
from rasm.properties.visitor import Visitor

__all__ = ["RobustCode", "RobustnessGenerator"]


@dataclass(frozen=True)
class Now:
    """A robustness known at its own record: the source of the expression computing it."""

    source: str


@dataclass(frozen=True)
class Late:
    """Robustness values that come late, final and in record order, in ``stream.out``."""

    stream: object


RValue = Now | Late


@dataclass(frozen=True)
class RobustCode:
    """One property's robustness lines, at each record and at the end, and where its values
    are: known at each record, in the variable ``value``; else they come late, final and in
    record order, in the deque ``out`` of the stream the constant ``top`` names."""

    body: tuple[Line, ...]
    finish: tuple[Line, ...]
    top: str | None = None
    out: str | None = None
    value: str | None = None


def _neg(v):
    return -v


def _neg_interval(x):
    return (-x[1], -x[0])


def _min_interval(x, y):
    return (min(x[0], y[0]), min(x[1], y[1]))


def _max_interval(x, y):
    return (max(x[0], y[0]), max(x[1], y[1]))


def _implies(a, b):
    a = -a
    return a if a > b else b


def _implies_interval(x, y):
    return (max(-x[1], y[0]), max(-x[0], y[1]))


def _compare_interval(op: str):
    return lambda x, y: compare_interval(op, x, y)


def _is_number(source: str) -> bool:
    """``source`` is a number's literal (as the boolean compile writes one: ``repr``)."""
    try:
        float(source)
    except ValueError:
        return False
    return True


_NUMBERS = ("int", "float")
# robustness of `a op b` for two numbers, neither nan: (source over a and b)
_DISTANCE = {"<": "{b} - {a}", "<=": "{b} - {a}", ">": "{a} - {b}", ">=": "{a} - {b}",
             "==": "-abs({a} - {b})", "!=": "abs({a} - {b})"}


class RobustnessGenerator(Emitter, Visitor[RValue]):
    """The robustness lines of each property in turn (:meth:`compile`)."""

    def __init__(self, spec: Specification, names: Names) -> None:
        super().__init__(names)
        self._types = TypeScope({k: v for k, v in spec.signals.items() if v != "any"})
        # the values compared, computed as the boolean semantics computes them
        self._values = FormulaGenerator(spec, names)
        self._tuple: str | None = None
        self._names.constants.update(RCMP=RCMP, AS_FLOAT=as_float)

    def compile(self, number: int, formula: Expr) -> RobustCode:
        self._begin(number)
        self._tuple = None  # the record's (i, tn) (_record)
        values = self._values
        values._begin(number)
        values._lines, values._finish = self._lines, self._finish  # one list of lines
        values._root = values._owed = values._order = None
        values._windows, values._prevs, values._counts = {}, {}, {}
        value = self.visit(formula)
        if isinstance(value, Now):
            held = self.fresh("r")
            self._code(f"{held} = {value.source}")
            return RobustCode(tuple(self._lines), tuple(self._finish), value=held)
        top = self.constant("top", value.stream)
        out = self.constant("ro", value.stream.out)
        return RobustCode(tuple(self._lines), tuple(self._finish), top=top, out=out)

    def _code(self, *texts: str) -> None:
        self._lines += map(Code, texts)

    def _record(self) -> str:
        """The variable holding the record's ``(i, tn)``, which the windows keep: one tuple
        per record for them all (made where the first window needs it: window lines run at
        every record, so every later one reads it)."""
        if self._tuple is None:
            self._tuple = self.fresh("it")
            self._code(f"{self._tuple} = (i, tn)")
        return self._tuple

    def _held(self, source: str) -> str:
        """``source`` in a variable, so that it is computed once."""
        if source.isidentifier() or source in ("INF", "-INF") or _is_number(source):
            return source
        name = self.fresh("v")
        self._code(f"{name} = {source}")
        return name

    def _stream(self, stream: object, *now: str, index: bool = False) -> Late:
        """``stream``, stepped at every record with the immediate values ``now``."""
        name = self.constant("rs", stream)
        args = "".join(f", {v}" for v in now)
        self._code(f"{name}.step({'i' if index else 'tn'}{args})")
        return Late(stream)

    def _pointwise(self, parts: list[RValue], function, interval, template: str) -> Late:
        """:class:`Pointwise`'s step written out: ``template`` is the function's source over
        its arguments ``{0}``, ``{1}``, … (each a plain name, read as often as need be). At
        least one of ``parts`` comes late, so at most one is immediate: each record's waits
        in ``held`` (None where there is none) for the late ones."""
        sources = [part.stream if isinstance(part, Late) else None for part in parts]
        now = [self._held(part.source) for part in parts if isinstance(part, Now)]
        assert len(now) < len(parts) <= 2
        stream = Pointwise(sources, function, interval)
        queues = [self.constant("pq", part.stream.out) for part in parts
                  if isinstance(part, Late)]
        held, out = self.constant("ph", stream.held), self.constant("px", stream.out)
        self._code(f"{held}.append({now[0] if now else None})")
        args = [self.fresh("a") for _ in parts]
        immediate = [x for x, part in zip(args, parts, strict=True) if isinstance(part, Now)]
        take: list[Line] = [Code(f"{immediate[0]} = {held}.popleft()"
                                 if immediate else f"{held}.popleft()")]
        late = iter(queues)
        take += [Code(f"{x} = {next(late)}.popleft()")
                 for x, part in zip(args, parts, strict=True) if isinstance(part, Late)]
        take.append(Code(f"{out}.append({template.format(*args)})"))
        self._lines.append(Block(f"while {' and '.join(queues)}:", tuple(take)))
        return Late(stream)

    # ----------------------------------------------------------------- atoms
    def literal(self, node: Literal) -> RValue:
        return Now("INF" if node.value else "-INF")

    def name(self, node: Name) -> RValue:
        return Now(f"(INF if {signal_variable(node.name)} else -INF)")

    def _not_a_formula(self, node: Expr, *args) -> RValue:
        raise TypeError(f"{type(node).__name__} is a value, not a formula")

    time = unary = call = aggregate = _not_a_formula

    # ----------------------------------------------------------------- pointwise
    def not_(self, node: Not) -> RValue:
        part = self.visit(node.operand)
        if isinstance(part, Now):
            return Now(f"(-{part.source})")
        return self._pointwise([part], _neg, _neg_interval, "-{0}")

    def binary(self, node: Binary) -> RValue:
        if node.op in COMPARISONS:
            return self._compare(node)
        parts = [self.visit(node.left), self.visit(node.right)]
        if all(isinstance(part, Now) for part in parts):
            a, b = (self._held(part.source) for part in parts)
            if node.op == "and":
                return Now(self._held(f"{a} if {a} < {b} else {b}"))
            if node.op == "or":
                return Now(self._held(f"{a} if {a} > {b} else {b}"))
            return Now(self._held(f"-{a} if -{a} > {b} else {b}"))
        if node.op == "and":
            return self._pointwise(parts, min, _min_interval, "{0} if {0} < {1} else {1}")
        if node.op == "or":
            return self._pointwise(parts, max, _max_interval, "{0} if {0} > {1} else {1}")
        return self._pointwise(parts, _implies, _implies_interval,
                               "-{0} if -{0} > {1} else {1}")

    def _compare(self, node: Binary) -> RValue:
        op, operands = node.op, children(node)
        exact = any(map(is_time, operands)) and not looks_ahead(node)
        parts = self._values._in_units(operands, [self._value(x) for x in operands], exact)
        if any(isinstance(part, Later) for part in parts):
            # a count compared with a value known at its record: an open value lies in the
            # count's range, as the boolean comparison decides it (CountStream)
            ranges = len([part for part in parts if isinstance(part, Later)]) == 1
            late = [Late(self._ordered(part, ranges)) if isinstance(part, Later)
                    else Now(part.source) for part in parts]
            return self._pointwise(late, RCMP[op], _compare_interval(op),
                                   f"RCMP[{op!r}]({{0}}, {{1}})")
        a, b = (self._held(part.source) for part in parts)
        if exact:  # nanoseconds (ints, or a float where a value is undefined or infinite)
            return Now(self._held(f"RCMP[{op!r}]({a}, {b}) / 1000000000"))
        if all(self._types.check(x) in _NUMBERS for x in operands):
            out = self.fresh("v")
            self._code(f"{out} = {_DISTANCE[op].format(a=a, b=b)}",
                       f"if {out} != {out}: {out} = RCMP[{op!r}]({a}, {b})")
            return Now(out)
        return Now(self._held(f"RCMP[{op!r}]({a}, {b})"))

    def _value(self, node: Expr) -> ValueNow | Later:
        """A value compared: its source, or the stream of its values where it comes late."""
        return self._values.visit(normalise(node))  # as the boolean compile sees it

    def _ordered(self, part: Later, ranges: bool = False) -> Ordered:
        ordered = Ordered(part.stream, ranges and isinstance(part.stream, CountStream))
        self._stream(ordered, index=True)
        return ordered

    # ----------------------------------------------------------------- past
    def prev(self, node: Prev) -> RValue:
        part = self.visit(node.operand)
        if isinstance(part, Late):
            return self._stream(PrevStream(part.stream, -math.inf))
        held = self.variable("rp", -math.inf)  # undefined at the first record
        out = self.fresh("v")
        self._code(f"{out} = {held}", f"{held} = {part.source}")
        return Now(out)

    def past(self, node: Past) -> RValue:
        part = self.visit(node.operand)
        high, a, b = node.op == "once", node.bound.low_ns, node.bound.high_ns
        if isinstance(part, Late):
            return self._stream(PastStream(part.stream, high, a, b))
        return Now(self._past_from_now(high, a, b, self._held(part.source)))

    def _past_from_now(self, high: bool, a: int, b: int | float, value: str) -> str:
        """:class:`PastWindow`'s ``push`` written out (a call per record costs more than its
        work): the max (``high``) or min of ``value`` over the window, in a variable."""
        empty = "-INF" if high else "INF"
        if a == 0 and b == math.inf:  # the best so far
            best = self.variable("rb", -math.inf if high else math.inf)
            self._code(f"if {value} {'>' if high else '<'} {best}: {best} = {value}")
            return best
        # a monotonic wedge of (ns, value), each dominated value dropped as a better one comes
        worse, out = "<=" if high else ">=", self.fresh("v")
        wedge = self.constant("rq", deque())
        if a == 0:  # the record enters its own window at once, and is its last
            self._code(f"while {wedge} and {wedge}[-1][1] {worse} {value}: {wedge}.pop()",
                        f"{wedge}.append((tn, {value}))",
                        f"while tn - {wedge}[0][0] > {b}: {wedge}.popleft()",
                        f"{out} = {wedge}[0][1]")
            return out
        young, item = self.constant("ry", deque()), self.fresh("it")
        self._code(f"{young}.append((tn, {value}))")
        self._lines.append(Block(f"while tn - {young}[0][0] >= {a}:", (  # old enough
            Code(f"{item} = {young}.popleft()"),
            Code(f"while {wedge} and {wedge}[-1][1] {worse} {item}[1]: {wedge}.pop()"),
            Code(f"{wedge}.append({item})"),
        )))
        if b != math.inf:
            self._code(f"while {wedge} and tn - {wedge}[0][0] > {b}: {wedge}.popleft()")
        self._code(f"{out} = {wedge}[0][1] if {wedge} else {empty}")
        return out

    def since(self, node: Since) -> RValue:
        parts = [self.visit(node.left), self.visit(node.right)]
        a, b = node.bound.low_ns, node.bound.high_ns
        if all(isinstance(part, Now) for part in parts):
            core = self.constant("rc", SinceCore(a, b))
            left, right = (self._held(part.source) for part in parts)
            return Now(self._held(f"{core}.push(tn, {left}, {right})"))
        return self._pair(SinceStream, parts, a, b)

    def _pair(self, cls, parts: list[RValue], a, b) -> Late:
        sources = [part.stream if isinstance(part, Late) else None for part in parts]
        now = [self._held(part.source) for part in parts if isinstance(part, Now)]
        return self._stream(cls(*sources, a, b), *now)

    # ----------------------------------------------------------------- future
    def future(self, node: Future) -> RValue:
        """:class:`FutureWindow`'s step written out in the generated code (one per operator
        per record: a method call and its attribute lookups cost more than the work), over
        the window's own deques (the object reads them for its intervals), the records
        numbered by ``i``."""
        part = self.visit(node.operand)
        high, a, b = node.op == "eventually", node.bound.low_ns, node.bound.high_ns
        window = FutureWindow(part.stream if isinstance(part, Late) else None, high, a, b)
        if a == 0:
            return self._future_from_now(window, part)
        outs, vals, wedge, out = (self.constant(prefix, queue) for prefix, queue in (
            ("fo", window.outs), ("fv", window.vals), ("fe", window.wedge), ("fx", window.out)))
        self._code(f"{outs}.append({self._record()})")
        times = None
        if isinstance(part, Late):  # the operand's values come late, in record order
            times, queue = self.constant("ft", window.times), self.constant("fq", part.stream.out)
            k, t = self.fresh("k"), self.fresh("t")
            self._code(f"{times}.append({self._record()})")
            self._lines.append(Block(f"while {queue}:", (
                Code(f"{k}, {t} = {times}.popleft()"),
                Code(f"{vals}.append(({k}, {t}, {queue}.popleft()))"),
            )))
        else:
            self._code(f"{vals}.append((i, tn, {self._held(part.source)}))")
        j, tj, first, last, item, v = (self.fresh(x) for x in ("j", "tj", "f", "l", "it", "v"))
        waits = f"tn <= {last}" + (f" or ({times} and {times}[0][1] <= {last})" if times else "")
        worse = "<=" if high else ">="
        enter = (Code(f"{v} = {item}[2]"),
                 Code(f"while {wedge} and {wedge}[-1][2] {worse} {v}: {wedge}.pop()"),
                 Code(f"{wedge}.append({item})"))
        if a == 0:
            # the values not entered yet are those of records from j on (the windows close in
            # record order), all in j's window up to its end: each enters; the wedge's newest
            # is in j's window, so it is not empty
            close: tuple[Line, ...] = (
                Block(f"while {vals} and {vals}[0][1] <= {last}:",
                      (Code(f"{item} = {vals}.popleft()"), *enter)),
                Code(f"while {wedge}[0][0] < {j}: {wedge}.popleft()"),
                Code(f"{out}.append({wedge}[0][2])"),
            )
        else:
            close = (
                Code(f"{first} = {tj} + {a}"),
                Block(f"while {vals} and {vals}[0][1] <= {last}:", (
                    Code(f"{item} = {vals}.popleft()"),
                    Block(f"if {item}[1] >= {first} and {item}[0] >= {j}:", enter),
                )),
                Code(f"while {wedge} and ({wedge}[0][1] < {first} or {wedge}[0][0] < {j}): "
                     f"{wedge}.popleft()"),
                Code(f"{out}.append({wedge}[0][2] if {wedge} else {'-INF' if high else 'INF'})"),
            )
        self._lines.append(Block(f"while {outs}:", (
            Code(f"{j}, {tj} = {outs}[0]"),
            Code(f"{last} = {tj} + {b}"),
            Code(f"if {waits}: break"),
            *close,
            Code(f"{outs}.popleft()"),
        )))
        return Late(window)

    def _future_from_now(self, window: FutureWindow, part: RValue) -> Late:
        """A window from the record itself (``a`` = 0): each value enters the wedge as it
        comes, once the windows that end before its record have taken theirs (those windows
        hold every value entered so far, and the wedge's newest is in each), so no value
        waits outside it."""
        outs, wedge, out = (self.constant(prefix, queue) for prefix, queue in (
            ("fo", window.outs), ("fe", window.wedge), ("fx", window.out)))
        b, worse = window.b, "<=" if window.high else ">="
        j, v, k, t = (self.fresh(x) for x in ("j", "v", "k", "t"))
        close = (  # the oldest open window: the values from its record on are in the wedge
            Code(f"{j} = {outs}.popleft()[0]"),
            Code(f"while {wedge}[0][0] < {j}: {wedge}.popleft()"),
            Code(f"{out}.append({wedge}[0][2])"),
        )

        def enter(k: str, t: str, v: str) -> tuple[Line, ...]:
            return (Code(f"while {wedge} and {wedge}[-1][2] {worse} {v}: {wedge}.pop()"),
                    Code(f"{wedge}.append(({k}, {t}, {v}))"))

        if isinstance(part, Now):
            value = self._held(part.source)
            self._lines += [Block(f"while {outs} and tn - {outs}[0][1] > {b}:", close),
                            *enter("i", "tn", value), Code(f"{outs}.append({self._record()})")]
            return Late(window)
        # the operand's values come late, in record order: ``times`` holds the records whose
        # value is still to come (the same (i, tn) as ``outs``)
        times = self.constant("ft", window.times)
        queue = self.constant("fq", part.stream.out)
        record = self._record()
        self._code(f"{outs}.append({record})", f"{times}.append({record})")
        self._lines += [
            Block(f"while {queue}:", (
                Code(f"{k}, {t} = {times}.popleft()"),
                Block(f"while {t} - {outs}[0][1] > {b}:", close),
                Code(f"{v} = {queue}.popleft()"),
                *enter(k, t, v),
            )),
            # the windows that end before the first record whose value is still to come (or
            # before this record): complete, with all their values in
            Block(f"while {outs} and ({times}[0][1] if {times} else tn) - {outs}[0][1] > {b}:",
                  close),
        ]
        return Late(window)

    def until(self, node: Until) -> RValue:
        parts = [self.visit(node.left), self.visit(node.right)]
        return self._pair(UntilStream, parts, node.bound.low_ns, node.bound.high_ns)

