"""Compiling a checked specification to Python source: one step function for all properties.

Sub-formulas that only look at the past are *immediate*: their value at record i is known at
record i, and they become straight-line code with their state in closure variables (a last
witness time, a deque of not-yet-old-enough witnesses). Anything above a future operator is a
*stream* (``rasm.properties.streams``) whose values come late; the generated code feeds the streams
their immediate inputs and reads the property's verdicts off the top stream.

Windows compare times as exact integer nanoseconds: the generated code turns each record's time
``t`` (seconds, as given) into ``tn`` (:mod:`rasm.properties.times`); the bounds are
nanoseconds from the parser.

The same body is generated twice: in ``step(t, record)`` (verdict objects, one call per record)
and in ``run(records)`` (a loop over a whole trace, plain lists of values: ``rasm check``). Each
property's code runs in its own ``try``: if it raises, the monitor gives that property error
verdicts and resets its state (``rasm.properties.monitor``), and the other properties carry on.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from rasm.properties.ast import (
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
)
from rasm.properties.expr import _ARITH, _ARITH_NAMES, _COMPARE, HELPERS, _max2, _min2
from rasm.properties.loader import signals_of
from rasm.properties.operators import EventuallyCore, OnceCore, SinceCore, UntilCore, WindowCore
from rasm.properties.streams import (
    AggregateStream,
    PointwiseStream,
    PrevStream,
    Source,
    TemporalStream,
    kleene_function,
)
from rasm.properties.times import FAST
from rasm.properties.types import TypeScope

__all__ = ["Program", "checked_signals", "generate"]


@dataclass
class Program:
    """What :func:`generate` produces: the source and the objects it closes over."""

    source: str
    constants: dict[str, object]
    state: dict[str, object]
    reads: list[tuple[str, ...]] = field(default_factory=list)  # warm-up signals per property
    # per property: the names of its constants and closure variables, which a reset renews
    owned: list[list[str]] = field(default_factory=list)
    # per property with a stream root: its deque of the (index, time) owed a verdict online
    owed: list[str | None] = field(default_factory=list)


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


class _Generator:
    def __init__(self, spec: Specification) -> None:
        self.spec = spec
        self.types = TypeScope({k: v for k, v in spec.signals.items() if v != "any"})
        self.constants: dict[str, object] = {"deque": deque, "INF": INF, "NAN": math.nan}
        self.constants.update(HELPERS)
        self.state: dict[str, object] = {}
        self.count = 0
        self.lines: list = []
        self.finish_lines: list = []
        self.root: Expr | None = None  # the property's formula being compiled
        self.root_number = 0
        self.owned: list[list[str]] = []  # per property: its constants and closure variables
        # the root's deque of the records it owes a verdict (online): made by the root when it
        # gives early verdicts (inline_pointwise), else by generate()
        self.owed: str | None = None
        # inline future windows by their Source (kept alive here, so never confused with a
        # later one): (index of their first line, pending deque, upper bound), for the parent
        # that may keep the records it decides out of them (online_skip)
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
            return "imm", "t"
        if isinstance(node, Future):  # only eventually, after normalise()
            (kind, value) = self.emit(node.operand)
            a, b = node.bound.low_ns, node.bound.high_ns
            if kind == "imm":
                return self.inline_future(a, b, None, value)
            return self.stream(TemporalStream, [(kind, value)], EventuallyCore(a, b))
        if isinstance(node, Until):
            left, right = self.emit(node.left), self.emit(node.right)
            a, b = node.bound.low_ns, node.bound.high_ns
            if left[0] == right[0] == "imm":
                return self.inline_future(a, b, left[1], right[1])
            return self.stream(TemporalStream, [left, right], UntilCore(a, b))
        parts = [self.emit(c) for c in _operands(node)]
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
        if isinstance(node, Not):
            return self.stream(PointwiseStream, parts, kleene_function("not", None))
        if isinstance(node, Unary):
            return self.stream(PointwiseStream, parts, kleene_function("-", lambda a: -a))
        if isinstance(node, Binary):
            plain = _ARITH.get(node.op) or _COMPARE.get(node.op)
            return self.stream(PointwiseStream, parts, kleene_function(node.op, plain))
        if isinstance(node, Call):
            plain = {"abs": abs, "min": _min2, "max": _max2}[node.func]
            return self.stream(PointwiseStream, parts, kleene_function(node.func, plain))
        if isinstance(node, Prev):
            return self.stream(PrevStream, parts, self.undefined(node.operand))
        a, b = node.bound.low_ns, node.bound.high_ns
        if isinstance(node, Past):
            return self.stream(TemporalStream, parts, OnceCore(a, b))
        if isinstance(node, Since):
            return self.stream(TemporalStream, parts, SinceCore(a, b))
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

        Same algorithm as :class:`EventuallyCore`/:class:`UntilCore`, written into the step
        function: open records wait in ``pending``; decided ones go to the output queue.
        """
        source = Source()
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
        """A non-temporal operator over one stream and immediate values, in Kleene logic."""
        source = Source()
        out = self.constant("o", source.out)
        child = self.constant("c", parts[position][1].out)
        names = []
        held = None
        immediate = [value for kind, value in parts if kind == "imm"]
        decides = _decider(node, position) if len(immediate) == 1 else None
        early = None
        if decides is not None and node is self.root:
            early = decides[0].format(w=immediate[0])
        if immediate:
            held = self.constant("b", deque())
            if len(immediate) == 1:
                append = f"{held}.append({immediate[0]})"
                if early is not None and self.online_skip(parts[position][1], position, early):
                    append = ("ONLINE", f"if not ({early}): {append}", append)
                self.lines.append(append)
            else:
                self.lines.append(f"{held}.append(({', '.join(immediate)},))")
        k = 0
        for kind, _ in parts:
            if kind == "stream":
                names.append("_v")
            elif len(immediate) == 1:
                names.append("_w")
            else:
                names.append(f"_w[{k}]")
                k += 1
        drain = [f"while {child}:", f"    _j, _tj, _tn, _v = {child}.popleft()"]
        if held is not None:
            drain.append(f"    _w = {held}.popleft()")
        if early is not None:
            # online, the immediate side alone may decide the verdict (a false trigger of
            # "trigger -> eventually …"): say it now, and skip it when the stream catches up;
            # any other record is owed a verdict by the stream
            test, value = decides
            self.owed = self.constant("owed", deque())
            self.lines += [
                ("ONLINE", f"if {early}:", None),
                ("EMIT", self.root_number, "i", "t", value, "    ", True),
                ("ONLINE", "else:", None),
                ("ONLINE", f"    {self.owed}.append((i, t))", None),
            ]
            drain.append(("ONLINE", f"    if {test.format(w='_w')}: continue", None))
        drain.append(f"    {out}.append((_j, _tj, _tn, {_kleene(node, names, position)}))")
        self.lines += drain
        self.finish_lines += drain
        return "stream", source

    def online_skip(self, child: Source, position: int, early: str) -> bool:
        """Online, keep the records ``early`` decides out of the inline window ``child``.

        Their verdict is given at once, so the window need not wait for their witness: the
        step function then does no window work for them (most records: a trigger is rare).
        Only for an inline window (a stream class is stepped every record) whose record is
        decided by the operand before it (its lines, computing ``early``, come first). The
        window and the held operand values skip the same records, so they stay aligned;
        ``run()`` keeps every record (it gives no early verdicts).
        """
        window = self.windows.pop(child, None)
        if window is None or position != 1:
            return False
        start, pending, b = window
        append = self.lines[start]
        self.lines[start] = ("ONLINE", f"if not ({early}): {append}", append)
        # the window may now be empty: the current record is not always in it
        self.lines[start + 1] = f"while {pending} and tn - {pending}[0][2] > {_number(b)}:"
        return True


def _decider(node: Expr, position: int) -> tuple[str, str] | None:
    """When the immediate operand ``w`` alone decides ``node``: (test on w, verdict)."""
    if not isinstance(node, Binary):
        return None
    if node.op == "and":
        return "not {w}", "False"
    if node.op == "or":
        return "{w}", "True"
    if node.op == "->":
        return ("not {w}", "True") if position == 1 else ("{w}", "True")
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


# --------------------------------------------------------------------------- whole programs

UNSET = type("Unset", (), {"__repr__": lambda self: "<unset>"})()


def generate(
    spec: Specification, reads: list[tuple[str, ...]] | None = None, *, hook: bool = False
) -> Program:
    """Generate the step and run functions' source for every property of ``spec``.

    ``reads`` overrides, per property, the signals whose first values end its warm-up (by
    default: those it reads); explanations use it to evaluate sub-formulas in context.
    ``hook``: each property's code starts with a call ``FAULT_HOOK(property, index)`` (a test's
    way to make a property raise; see :class:`rasm.properties.monitor.Monitor`).

    The source defines ``factory()`` returning ``(step, run, finish_step, finish_run, held,
    resets)``: ``held()`` tells which held signals have had a value, ``resets[k]()`` puts
    property k's closure variables back to their initial values (its constants are renewed by
    the caller, from a fresh :func:`generate`). It reads the names in ``Program.constants`` plus
    ``STATE`` (initial values), ``Verdict``, ``NAMES``, ``STARTS``, ``VALUES``, ``UNSET``,
    ``NUMERIC``, ``SCALAR``, ``COERCE``, ``BAD``, ``NANOSECONDS``, ``SECONDS``, ``REJECT_STEP``,
    ``REJECT_RUN``,
    ``FAULT``, ``FAULT_RUN``, ``RECOVERING``, ``RECOVER`` and ``RECOVER_RUN``, which the monitor
    provides.
    """
    gen = _Generator(spec)
    defaults = {item.name: item.default for item in spec.inputs if item.default is not None}
    events = {item.name for item in spec.events}
    blocks: list[list] = []
    finishes: list[list] = []
    program = Program("", gen.constants, gen.state, owned=gen.owned)
    for number, prop in enumerate(spec.properties):
        gen.lines, gen.finish_lines = [], []
        gen.root = normalise(prop.formula)
        gen.root_number = number
        gen.owned.append([])
        gen.owed = None
        kind, value = gen.emit(gen.root)
        if reads is None:
            needed = signals_of(prop.formula)
        else:
            needed = reads[number]
        warm = tuple(name for name in needed if name not in events and name not in defaults)
        program.reads.append(warm)
        body: list = list(gen.lines)
        finish: list = list(gen.finish_lines)
        if kind == "imm":
            body.append(("EMIT", number, "i", "t", value, "", False))
        else:
            root = gen.constant("r", value.out)
            if gen.owed is None:
                gen.owed = gen.constant("owed", deque())
                body.insert(0, ("ONLINE", f"{gen.owed}.append((i, t))", None))
            # a verdict given, the record is no longer owed (in this order: a verdict that
            # fails to be made leaves its record owed)
            drain = [
                f"while {root}:",
                f"    _j, _tj, _tn, _v = {root}.popleft()",
                ("EMIT", number, "_j", "_tj", "_v", "    ", False),
                ("ONLINE", f"    {gen.owed}.popleft()", None),
            ]
            body += drain
            finish += drain
        program.owed.append(gen.owed if kind == "stream" else None)
        if hook:
            body.insert(0, f"FAULT_HOOK(NAME_{number}, i)")
        guarded = _guarded(body, number, finishing=False)
        if warm:
            started = gen.variable("started", False, owned=False)
            ready = " and ".join(f"{signal_variable(n)} is not UNSET" for n in warm)
            block: list = [f"if not {started} and {ready}:", f"    {started} = True"]
            block.append(f"    STARTS[{number}] = i")
            block.append(f"if {started}:")
            block += [_indent(line) for line in guarded]
        else:
            started = "i >= 0"
            block = [f"if i == 0: STARTS[{number}] = 0", *guarded]
        blocks.append(block)
        if kind == "stream":
            finishes.append(
                [f"if {started}:", *(_indent(line) for line in _guarded(finish, number, True))]
            )
    program.source = _assemble(spec, gen, blocks, finishes, events)
    return program


def _guarded(body: list, number: int, finishing: bool) -> list:
    """``body`` in a ``try`` whose failure is property ``number``'s fault, not the file's."""
    return ["try:", *(_indent(line) for line in body), "except Exception as _exc:",
            ("FAULT", number, "    ", finishing)]


def _indent(line, pad: str = "    "):
    if isinstance(line, str):
        return pad + line
    if line[0] == "ONLINE":
        _, online, offline = line
        return ("ONLINE", pad + online, None if offline is None else pad + offline)
    if line[0] == "EMIT":
        kind, number, index, time, value, indent, online_only = line
        return (kind, number, index, time, value, pad + indent, online_only)
    kind, number, indent, finishing = line  # FAULT
    return (kind, number, pad + indent, finishing)


def _render(line, mode: str) -> str | None:
    """A generated line for ``mode`` (step or run); None where the line is online-only.

    Line kinds: a string (both modes); ``("ONLINE", step_text, run_text)`` (``run_text`` None:
    step only); ``("EMIT", property, index, time, value, indent, online_only)`` (a verdict:
    a Verdict object online, a plain value in ``run``); ``("FAULT", property, indent,
    finishing)`` (the handler of a property's exception).
    """
    online = mode == "step"
    if isinstance(line, str):
        return line
    if line[0] == "ONLINE":
        return line[1] if online else line[2]
    if line[0] == "EMIT":
        _, number, index, time, value, pad, online_only = line
        if online:
            return f"{pad}out.append(Verdict(NAME_{number}, {index}, {time}, {value}))"
        return None if online_only else f"{pad}values_{number}({value})"
    _, number, pad, finishing = line
    if online:
        if finishing:
            return f"{pad}FAULT({number}, None, None, None, _exc, out)"
        return f"{pad}FAULT({number}, i, t, tn, _exc, out)"
    return f"{pad}FAULT_RUN({number}, i, {'None' if finishing else 'tn'}, _exc)"


def _assemble(spec, gen: _Generator, blocks, finishes, events) -> str:
    # an event holds no value from one record to the next (absent means false): its variable is
    # a local of each function, set by every record; only inputs are held in the closure
    used = checked_signals(spec)
    defaults = {item.name: item.default for item in spec.inputs if item.default is not None}
    for name in used:
        if name not in events:
            gen.state[signal_variable(name)] = defaults.get(name, UNSET)
    cells = sorted(gen.state) + ["i", "last_tn"]
    update = _update_lines(spec, used, events)
    properties = [line for block in blocks for line in block]

    def rendered(body: list, mode: str, reject: str = "") -> list[str]:
        lines = []
        for line in body:
            text = _render(line, mode)
            if text is None:
                continue
            if reject:
                text = text.replace("REJECT(", reject + "(")
            lines.append(text)
        return lines

    step = ["def step(t, rec):", "    nonlocal " + ", ".join(cells), "    out = []"]
    step += ["    " + text for text in rendered([*update, "i += 1", *properties], "step",
                                                "REJECT_STEP")]
    # a property recovering from a fault: its verdicts that depend on records from before
    # its reset are errors (rasm.properties.recovery)
    step += ["    if RECOVERING: return RECOVER(i, tn, out)", "    return out"]

    run = ["def run(records):", "    nonlocal " + ", ".join(cells), "    for t, rec in records:"]
    run += ["        " + text for text in rendered([*update, "i += 1", *properties], "run",
                                                   "REJECT_RUN")]
    run += ["        if RECOVERING: RECOVER_RUN(i, tn)", "    return None"]

    factory = ["def factory():"]
    for name in sorted(gen.state):
        factory.append(f"    {name} = STATE[{name!r}]")
    factory += ["    i = -1", "    last_tn = -INF"]
    for number in range(len(blocks)):
        factory.append(f"    values_{number} = VALUES[{number}].append")
        factory.append(f"    NAME_{number} = NAMES[{number}]")
    factory += ["    " + line for line in step + run]
    for mode in ("step", "run"):
        factory += [
            f"    def finish_{mode}():",
            "        nonlocal " + ", ".join(cells),
            "        out = []",
        ]
        for block in finishes:
            factory += ["        " + text for text in rendered(block, mode)]
        factory.append("        return out")
    # which held signals have had a value so far (a property not judged names the missing ones)
    held = [name for name in used if name not in events]
    factory.append("    def held():")
    pairs = ", ".join(f"{name!r}: {signal_variable(name)} is not UNSET" for name in held)
    factory.append("        return {" + pairs + "}")
    # each property's closure variables back to their initial values
    for number, owned in enumerate(gen.owned):
        variables = [name for name in owned if name in gen.state]
        factory.append(f"    def reset_{number}():")
        if variables:
            factory.append("        nonlocal " + ", ".join(variables))
        factory += [f"        {name} = STATE[{name!r}]" for name in variables]
        factory.append("        return None")
    resets = "".join(f"reset_{number}, " for number in range(len(gen.owned)))
    factory.append(f"    return step, run, finish_step, finish_run, held, ({resets})")
    return "\n".join(factory) + "\n"


def checked_signals(spec: Specification) -> list[str]:
    """The signals the generated code reads, holds and checks the values of (with every
    record's time): those some property reads; others cannot change a verdict."""
    used: dict[str, None] = {}
    for prop in spec.properties:
        for name in signals_of(prop.formula):
            used.setdefault(name, None)
    return list(used)


def _update_lines(spec: Specification, used: list[str], events: set[str]) -> list[str]:
    """Validate a record's time and the ``used`` signals' values, then update the held signals
    (all or nothing).

    The time ``t`` (seconds, as given) becomes ``tn``, exact integer nanoseconds
    (:mod:`rasm.properties.times`): at once for an int and for a float below FAST, through
    NANOSECONDS for anything else (then ``t``, which the ``time`` expression reads and verdicts
    carry, becomes an int or a float through SECONDS). The values' fast tests look at exact
    classes; anything else (a numpy float, an int subclass) takes the slow path through COERCE,
    which converts what it can and refuses the rest.
    """
    checks = [
        f"if t.__class__ is float and {-FAST!r} < t < {FAST!r}:",
        "    tn = round(t * 1e9)",
        "elif t.__class__ is int:",
        "    tn = t * 1000000000",
        "else:",
        "    tn = NANOSECONDS(t)",
        "    if tn is None: return REJECT(i + 1, t, rec, None, 'time')",
        "    t = SECONDS(t)",
        "if tn < last_tn: return REJECT(i + 1, t, rec, None, 'backwards')",
    ]
    assigns = []
    for name in used:
        kind = spec.signals[name]
        var = signal_variable(name)
        tmp = f"n_{name}"
        if name in events:  # a local: a rejected record leaves no trace of it
            checks += [
                f"{var} = rec.get({name!r}, False)",
                f"if {var} is not True and {var} is not False:",
                f"    {var} = COERCE({var}, 'bool')",
                f"    if {var} is BAD: return REJECT(i + 1, t, rec, {name!r}, 'bool')",
            ]
            continue
        check = {
            "float": f"{tmp}.__class__ not in NUMERIC",
            "int": f"{tmp}.__class__ is not int",
            "bool": f"{tmp}.__class__ is not bool",
            "str": f"{tmp}.__class__ is not str",
            "any": f"{tmp}.__class__ not in SCALAR",
        }[kind]
        coerce = [
            f"{tmp} = COERCE({tmp}, {kind!r})",
            f"if {tmp} is BAD: return REJECT(i + 1, t, rec, {name!r}, {kind!r})",
        ]
        checks.append(f"{tmp} = rec.get({name!r}, UNSET)")
        if name == used[-1]:  # the last check: nothing can refuse the record after it
            checks += [f"if {tmp} is not UNSET:", f"    if {check}:"]
            checks += ["        " + line for line in coerce] + [f"    {var} = {tmp}"]
        else:
            checks += [f"if {tmp} is not UNSET and {check}:", *("    " + line for line in coerce)]
            assigns.append(f"if {tmp} is not UNSET: {var} = {tmp}")
    # a record that is not a mapping (no .get), or a time that cannot be compared
    guarded = [
        "try:",
        *("    " + line for line in checks),
        "except (AttributeError, TypeError):",
        "    return REJECT(i + 1, t, rec, None, 'record')",
    ]
    return guarded + assigns + ["last_tn = tn"]
