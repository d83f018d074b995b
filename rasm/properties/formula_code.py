"""One property's code in the boolean semantics: the generator that turns a formula into lines.

Sub-formulas that only look at the past are *immediate* (:class:`~rasm.properties.emitter.Now`):
their value at record i is known at record i, and they become straight-line code with their
state in closure variables (a last witness time, a deque of not-yet-old-enough witnesses).
Anything above a future operator comes *late* (:class:`~rasm.properties.emitter.Later`): a
stream (``rasm.properties.streams``) whose values come each as soon as it is decided and in any
order; the generated code feeds the streams their immediate inputs and reads the property's
verdicts off the top stream. :mod:`rasm.properties.codegen` puts the properties' lines together
into one program.

Times are exact (:mod:`rasm.properties.units`): time arithmetic computes in integer nanoseconds.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

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
    rebuild,
)
from rasm.properties.emitter import (
    Emitter,
    Later,
    Names,
    Now,
    PropertyCode,
    Value,
    late_positions,
    signal_variable,
)
from rasm.properties.expr import _ARITH, _ARITH_NAMES, _COMPARE, _max2, _min2
from rasm.properties.lines import Block, Code, Emit, Online
from rasm.properties.operators import FutureOr, WindowCore
from rasm.properties.streams import (
    AggregateStream,
    CountStream,
    InOrder,
    JoinStream,
    PrevStream,
    SinceStream,
    Source,
    UntilStream,
    WindowStream,
)
from rasm.properties.types import TypeScope
from rasm.properties.units import in_seconds, is_time, looks_ahead
from rasm.properties.visitor import Transformer

__all__ = ["FormulaGenerator", "normalise"]


class _Normalise(Transformer[Expr]):
    """``historically φ`` as ``not once not φ`` and ``always φ`` as ``not eventually not φ``;
    every other node as it is, over its normalised sub-expressions."""

    def past(self, node: Past, operand: Expr) -> Expr:
        if node.op == "once":
            return rebuild(node, [operand])
        inner = Past("once", node.bound, Not(operand, location=node.location),
                     location=node.location)
        return Not(inner, location=node.location)

    def future(self, node: Future, operand: Expr) -> Expr:
        if node.op == "eventually":
            return rebuild(node, [operand])
        inner = Future("eventually", node.bound, Not(operand, location=node.location),
                       location=node.location)
        return Not(inner, location=node.location)

    def _same(self, node: Expr, *operands: Expr) -> Expr:
        return rebuild(node, operands)

    literal = name = time = unary = not_ = binary = call = prev = since = until = aggregate = _same


_NORMALISE = _Normalise()


def normalise(node: Expr) -> Expr:
    """Rewrite historically/always via once/eventually: ``historically φ = not once not φ``."""
    return _NORMALISE.visit(node)


def _number(x: int | float) -> str:
    """A bound (integer nanoseconds, or inf) as source."""
    return "INF" if x == INF else repr(x)


@dataclass(frozen=True)
class _InlineWindow:
    """An inline future window: the index of its first line, its deque of open records, its
    upper bound; for the parent that may keep the records it decides out of it."""

    start: int
    pending: str
    high: int | float


# When the immediate operand ``w`` alone decides a pointwise node: (test on w, the node's
# value then, w's value otherwise)
Decider = tuple[str, str, str]


class FormulaGenerator(Emitter, Transformer[Value]):
    """The lines of each property in turn (:meth:`compile`); the constants and closure
    variables they read are named in the program's ``names``."""

    def __init__(self, spec: Specification, names: Names) -> None:
        super().__init__(names)
        self._types = TypeScope({k: v for k, v in spec.signals.items() if v != "any"})
        self._root: Expr | None = None  # the property's formula being compiled
        # the root's dict of the records it owes a verdict (online), and its InOrder: made by
        # the root when it gives early verdicts (_inline_pointwise), else by compile()
        self._owed: str | None = None
        self._order: str | None = None
        # inline future windows by their Source (kept alive here, so never confused with a
        # later one), for the parent that may keep the records it decides out of them
        self._windows: dict[Source, _InlineWindow] = {}
        self._prevs: dict[str, str] = {}  # the source of prev's operand -> prev's value
        # counts over late values (CountStream) by stream, with their constants' names, for
        # the comparison that may be their parent
        self._counts: dict[CountStream, str] = {}

    def compile(self, number: int, formula: Expr, robustness: str | None = None) -> PropertyCode:
        """Property ``number``'s lines: its formula's value at each record, and the verdicts
        taken off it.

        ``robustness``: online, each verdict carries its robustness, from the variable of
        that name (a float) where the property's value is known at each record, else from
        the dict of that name (record -> final robustness; the verdicts whose robustness is
        not final yet carry None).
        """
        self._begin(number)
        self._root = root = normalise(formula)
        self._owed = self._order = None
        self._windows, self._prevs, self._counts = {}, {}, {}
        value = self.visit(root)
        body, finish = self._lines, self._finish
        if isinstance(value, Now):
            # a property's value is in seconds where it is a time (an explanation's probe of
            # ``time - prev(time)`` shows 0.2)
            emit = Emit(number, "i", "t", in_seconds(root, value.source), robustness=robustness)
            return PropertyCode(tuple(body), tuple(finish), late=False, verdicts=(emit,))
        stream = value.stream
        top = self.constant("r", stream.out)
        # verdicts that may come out of record order go back in order offline
        order = None if stream.ordered else self._in_order()
        if self._owed is not None:  # the root gives early verdicts: it owes the others
            forget = Online(f"del {self._owed}[_j]")
        elif stream.ordered:  # owed in record order: a queue
            self._owed = self.constant("owed", deque())
            body.insert(0, Online(f"{self._owed}.append((i, t))"))
            forget = Online(f"{self._owed}.popleft()")
        else:
            self._owed = self.constant("owed", {})
            body.insert(0, Online(f"{self._owed}[i] = t"))
            forget = Online(f"del {self._owed}[_j]")
        # a verdict given, the record is no longer owed (in this order: a verdict that
        # fails to be made leaves its record owed)
        take: tuple = (Code(f"_j, _tj, _tn, _v = {top}.popleft()"),)
        if robustness is not None:
            # (mostly empty: where verdicts come early, their robustness is final later)
            take += (Online(f"_r = {robustness}.pop(_j, None) if {robustness} else None"),)
        drain = Block(f"while {top}:", (
            *take,
            Emit(number, "_j", "_tj", "_v", order, robustness and "_r", final=False),
            forget,
        ))
        return PropertyCode(tuple(body), tuple(finish), late=True, owed=self._owed, order=order,
                            verdicts=(drain,))

    def _code(self, *texts: str) -> None:
        self._lines += map(Code, texts)

    # ----------------------------------------------------------------- atoms
    def literal(self, node: Literal) -> Value:
        return Now(repr(node.value))

    def name(self, node: Name) -> Value:
        return Now(signal_variable(node.name))

    def time(self, node: Time) -> Value:
        return Now("tn")

    # ----------------------------------------------------------------- pointwise
    def not_(self, node: Not, operand: Value) -> Value:
        (part,) = self._in_units(children(node), [operand], False)
        if isinstance(part, Later) and isinstance(part.stream, FutureOr):
            part.stream.negate()  # (its values go to this node only)
            return part
        if isinstance(part, Later):
            return self._inline_pointwise(
                node, [part], 0, None, lambda v: f"(None if {v[0]} is None else not {v[0]})"
            )
        return Now(f"(not {part.source})")

    def unary(self, node: Unary, operand: Value) -> Value:
        (part,) = self._in_units(children(node), [operand], is_time(node))
        if isinstance(part, Later):
            return self._inline_pointwise(
                node, [part], 0, None, lambda v: f"(None if {v[0]} is None else (-{v[0]}))"
            )
        return Now(f"(-{part.source})")

    def binary(self, node: Binary, left: Value, right: Value) -> Value:
        op = node.op
        exact = is_time(node) or (
            op in COMPARISONS and any(map(is_time, children(node))) and not looks_ahead(node)
        )
        parts = self._in_units(children(node), [left, right], exact)
        late = late_positions(parts)
        if len(late) == 1 and op in COMPARISONS:
            # a count over values that come late, compared with a value known at its record:
            # decided as soon as the count's possible range fixes the comparison
            position = late[0]
            stream = parts[position].stream  # type: ignore[union-attr]
            count = self._counts.pop(stream, None)
            if count is not None:
                stream.compare(op, position)
                self._code(f"{count}.against(i, {parts[1 - position].source})")
                return parts[position]
        if len(late) == 2:
            return self._stream(JoinStream, parts, op, _ARITH.get(op) or _COMPARE.get(op))
        if late:
            position = late[0]
            return self._inline_pointwise(
                node, parts, position, _decider(op, position),
                lambda names: _kleene_binary(op, names, position),
                passes=op in ("and", "or") or (op == "->" and position == 1),
            )
        return Now(_binary(op, parts[0].source, parts[1].source, self._integers(node)))

    def call(self, node: Call, *args: Value) -> Value:
        parts = self._in_units(children(node), list(args), is_time(node))
        late = late_positions(parts)
        function = _call(node.func)
        if len(late) > 1:
            plain = {"abs": abs, "min": _min2, "max": _max2}[node.func]
            return self._stream(JoinStream, parts, node.func, plain)
        if late:
            position = late[0]
            return self._inline_pointwise(
                node, parts, position, None,
                lambda v: f"(None if {v[position]} is None else {function}({', '.join(v)}))",
            )
        return Now(f"{function}({', '.join(part.source for part in parts)})")

    # ----------------------------------------------------------------- past
    def prev(self, node: Prev, operand: Value) -> Value:
        (part,) = self._in_units(children(node), [operand], is_time(node))
        if isinstance(part, Later):
            return self._stream(PrevStream, [part], self._undefined(node.operand))
        # the same prev(φ) twice in a property holds the same values (its lines run on the
        # same records, and φ's text names the same values): one pair of lines serves both
        if part.source not in self._prevs:
            held = self.variable("p", self._undefined(node.operand))
            out = self.fresh("v")
            self._code(f"{out} = {held}", f"{held} = {part.source}")
            self._prevs[part.source] = out
        return Now(self._prevs[part.source])

    def past(self, node: Past, operand: Value) -> Value:  # once, after normalise()
        (part,) = self._in_units(children(node), [operand], False)
        a, b = node.bound.low_ns, node.bound.high_ns
        if isinstance(part, Later):
            return self._stream(WindowStream, [part], True, a, b)
        return Now(self._once(a, b, part.source))

    def since(self, node: Since, left: Value, right: Value) -> Value:
        parts = self._in_units(children(node), [left, right], False)
        a, b = node.bound.low_ns, node.bound.high_ns
        if late_positions(parts):
            return self._stream(SinceStream, parts, a, b)
        return Now(self._since(a, b, parts[0].source, parts[1].source))

    def aggregate(self, node: Aggregate, operand: Value) -> Value:
        (part,) = self._in_units(children(node), [operand], False)
        a, b = node.bound.low_ns, node.bound.high_ns
        if isinstance(part, Later):
            if node.op == "count":  # a comparison above may decide it early (binary)
                stream = CountStream([part.stream], a, b)
                name = self.constant("s", stream)
                self._counts[stream] = name
                self._code(f"{name}.step(i, t, tn)")
                self._finish.append(Code(f"{name}.finish()"))
                return Later(stream)
            return self._stream(AggregateStream, [part], node.op, a, b)
        if node.op == "count" and a == 0:
            return Now(self._count_window(b, part.source))
        core = self.constant("w", WindowCore(node.op, a, b))
        out = self.fresh("v")
        self._code(f"{out} = {core}.push(tn, {part.source})")
        return Now(out)

    # ----------------------------------------------------------------- future
    def future(self, node: Future, operand: Value) -> Value:  # eventually, after normalise()
        a, b = node.bound.low_ns, node.bound.high_ns
        if isinstance(operand, Now):
            return self._inline_future(a, b, None, operand.source)
        return self._future_late(a, b, operand, True)

    def visit(self, node: Expr) -> Value:
        # ``eventually not φ`` (``always φ`` is ``not eventually not φ``) over values of φ that
        # come late: the window takes φ's values as they are (no pass negating each)
        if node.__class__ is Future and node.operand.__class__ is Not:
            operand = super().visit(node.operand.operand)
            if isinstance(operand, Later):
                return self._future_late(node.bound.low_ns, node.bound.high_ns, operand, False)
            return self.future(node, self.not_(node.operand, operand))
        return super().visit(node)

    def _future_late(self, a: int, b: int, operand: Later, hit: bool) -> Later:
        """``eventually[a,b]`` of values that come late (of their negation: ``hit`` False):
        one call per record, taking the operand's values (:class:`FutureOr`)."""
        window = FutureOr(a, b, hit)
        name, queue = self.constant("fw", window), self.constant("c", operand.stream.out)
        self._code(f"{name}.step(i, t, tn, {queue})")
        self._finish.append(Code(f"{name}.finish({queue})"))
        return Later(window)

    def until(self, node: Until, left: Value, right: Value) -> Value:
        a, b = node.bound.low_ns, node.bound.high_ns
        if isinstance(left, Now) and isinstance(right, Now):
            return self._inline_future(a, b, left.source, right.source)
        return self._stream(UntilStream, [left, right], a, b)

    # ----------------------------------------------------------------- immediate helpers
    def _undefined(self, node: Expr) -> object:
        # prev(φ) at a property's first record: a boolean is false, anything else undefined
        return False if self._types.check(node) == "bool" else math.nan

    def _integers(self, node: Binary) -> bool:
        """Both operands are ints: plain Python arithmetic is exact and cannot raise."""
        return self._types.check(node.left) == "int" and self._types.check(node.right) == "int"

    def _once(self, a: int, b: int | float, value: str) -> str:
        if a == 0 and b == INF:  # once, unbounded: a flag
            seen = self.variable("f", False)
            self._code(f"if {value}: {seen} = True")
            return seen
        last = self.variable("l", None)
        out = self.fresh("v")
        if a == 0:
            self._code(f"if {value}: {last} = tn")
        else:
            pending = self.constant("q", deque())
            self._code(
                f"if {value}: {pending}.append(tn)",
                f"while {pending} and tn - {pending}[0] >= {_number(a)}: "
                f"{last} = {pending}.popleft()",
            )
        self._code(f"{out} = {_within(last, b)}")
        return out

    def _count_window(self, b: int | float, value: str) -> str:
        """``count[0,b](value)`` of a two-valued operand, written into the step function.

        The same count as :class:`WindowCore`'s (the records whose value is true, from ``t - b``
        to ``t``) without a call per record: only the times of the true records are kept.
        """
        if b == INF:  # nothing ever leaves the window: a counter
            total = self.variable("n", 0)
            self._code(f"if {value}: {total} += 1")
            return total
        times = self.constant("q", deque())
        out = self.fresh("v")
        self._code(
            f"if {value}: {times}.append(tn)",
            f"while {times} and tn - {times}[0] > {_number(b)}: {times}.popleft()",
            f"{out} = len({times})",
        )
        return out

    def _since(self, a: int, b: int | float, left: str, right: str) -> str:
        last = self.variable("l", None)
        out = self.fresh("v")
        if a == 0:
            self._code(f"if not {left}: {last} = None", f"if {right}: {last} = tn")
        else:
            pending = self.constant("q", deque())
            self._code(
                f"if not {left}:",
                f"    {last} = None",
                f"    {pending}.clear()",
                f"if {right}: {pending}.append(tn)",
                f"while {pending} and tn - {pending}[0] >= {_number(a)}: "
                f"{last} = {pending}.popleft()",
            )
        self._code(f"{out} = {_within(last, b)}")
        return out

    # ----------------------------------------------------------------- streams
    def _stream(self, cls, parts: list[Value], *args) -> Later:
        """A stream of class ``cls`` over ``parts``, stepped at every record with the
        immediate ones."""
        stream = cls([part.stream if isinstance(part, Later) else None for part in parts], *args)
        name = self.constant("s", stream)
        immediate = "".join(f", {part.source}" for part in parts if isinstance(part, Now))
        self._code(f"{name}.step(i, t, tn{immediate})")
        self._finish.append(Code(f"{name}.finish()"))
        return Later(stream)

    def _inline_future(self, a: int, b: int, left: str | None, right: str) -> Later:
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
        self._windows[source] = _InlineWindow(len(self._lines), pending, b)
        self._code(*lines)
        # at the end of the trace the still-open windows are inconclusive
        self._finish += map(Code, [
            f"while {pending}:",
            f"    _j, _tj, _tn = {pending}.popleft()",
            f"    {out}.append((_j, _tj, _tn, None))",
        ])
        return Later(source)

    def _inline_pointwise(
        self,
        node: Expr,
        parts: list[Value],
        position: int,
        decides: Decider | None,
        kleene: Callable[[list[str]], str],
        passes: bool = False,
    ) -> Later:
        """A non-temporal operator over one stream (``parts[position]``) and at most one
        immediate value, in Kleene logic: ``kleene(names)`` is its source over the names of
        its operands' values, the stream's possibly None (inconclusive).

        Where the immediate value alone decides (``decides``: a false side of ``and``, a true
        side of ``or``, a false trigger of ``->``) the value is given at once; the stream's
        value for that record is then skipped when it comes (or never made,
        :meth:`_skip_window`). Other records wait for the stream's value. At the property's
        root the early value is a verdict. ``passes``: where the immediate value does not
        decide, the node's value is the stream's (``true and v``, ``true -> v``); if the
        window never makes the others, its values are then the node's as they come (one
        queue for both, nothing to pass on).
        """
        child = parts[position]
        assert isinstance(child, Later)
        immediate = [part.source for part in parts if isinstance(part, Now)]
        if not immediate:
            decides = None
        # in record order if its operand's values are and none is given early
        source = Source(ordered=child.stream.ordered and decides is None)
        stream = self.constant("c", child.stream.out)
        skipped = decides is not None and self._skip_window(
            child.stream, position, decides[0].format(w=immediate[0]))
        if skipped and passes:
            source.out = child.stream.out
        out = self.constant("o", source.out)
        names = ["_v" if isinstance(part, Later) else "_w" for part in parts]
        drain = [f"while {stream}:", f"    _j, _tj, _tn, _v = {stream}.popleft()"]
        if decides is None:
            if immediate:  # each record's immediate value waits for the stream's
                held = self.constant("b", {})
                self._code(f"{held}[i] = {immediate[0]}")
                drain.append(f"    _w = {held}.pop(_j)")
        else:
            early, value, other = decides
            early = early.format(w=immediate[0])
            # a record the immediate value does not decide had the one value that does not
            # decide: nothing to hold but which records wait (none when the window skips the
            # others: it never gives them)
            names = ["_v" if isinstance(part, Later) else other for part in parts]
            if not skipped:
                waiting = self.constant("b", set())
                self._code(f"if not ({early}): {waiting}.add(i)")
                drain += [f"    if _j not in {waiting}: continue  # given at once",
                          f"    {waiting}.discard(_j)"]
            if node is self._root:
                # the verdict now; online, any other record is owed a verdict by the stream
                self._owed = self.constant("owed", {})
                self._lines += [
                    Block(f"if {early}:", (Emit(self._number, "i", "t", value, self._in_order()),)),
                    Online("else:"),
                    Online(f"    {self._owed}[i] = t"),
                ]
            else:
                self._code(f"if {early}: {out}.append((i, t, tn, {value}))")
        if source.out is child.stream.out:
            return Later(source)
        drain.append(f"    {out}.append((_j, _tj, _tn, {kleene(names)}))")
        self._code(*drain)
        self._finish += map(Code, drain)
        return Later(source)

    def _in_order(self) -> str:
        """The property's :class:`InOrder`: its verdicts in record order, offline."""
        if self._order is None:
            self._order = self.constant("order", InOrder())
        return self._order

    def _skip_window(self, child: Source | object, position: int, early: str) -> bool:
        """Keep the records ``early`` decides out of the inline window ``child``.

        Their value is given at once, so the window need not wait for their witness: the
        step function then does no window work for them. Only for an inline window (a stream
        class is stepped every record) whose record is decided by the operand before it (its
        lines, computing ``early``, come first).
        """
        window = self._windows.pop(child, None)  # type: ignore[arg-type]
        if window is None or position != 1:
            return False
        first = self._lines[window.start]
        assert isinstance(first, Code)
        self._lines[window.start] = Code(f"if not ({early}): {first.text}")
        # the window may now be empty: the current record is not always in it
        self._lines[window.start + 1] = Code(
            f"while {window.pending} and tn - {window.pending}[0][2] > {_number(window.high)}:"
        )
        return True


def _within(last: str, b: int | float) -> str:
    if b == INF:
        return f"{last} is not None"
    return f"{last} is not None and tn - {last} <= {_number(b)}"


def _decider(op: str, position: int) -> Decider | None:
    """When the immediate operand ``w`` of ``op`` alone decides it, the stream's value at
    ``position``: (test on w, the value then, w's value otherwise)."""
    if op == "and":
        return "not {w}", "False", "True"
    if op == "or":
        return "{w}", "True", "False"
    if op == "->":
        return ("not {w}", "True", "True") if position == 1 else ("{w}", "True", "False")
    return None


def _kleene_binary(op: str, names: list[str], position: int) -> str:
    """Source of ``op`` over ``names`` where ``names[position]`` may be None (inconclusive).

    Python's ``and``/``or`` are Kleene's when their left operand is two-valued, so the
    immediate operand goes first.
    """
    v = names[position]
    if op in ("and", "or"):
        return f"({names[1 - position]} {op} {v})"
    if op == "->":
        if position == 1:
            return f"((not {names[0]}) or {v})"
        return f"({names[1]} or (None if {v} is None else not {v}))"
    return f"(None if {v} is None else {_binary(op, names[0], names[1])})"


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
