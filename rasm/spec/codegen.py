"""Compiling a checked specification to Python source: one step function for all properties.

Sub-formulas that only look at the past are *immediate*: their value at record i is known at
record i, and they become straight-line code with their state in closure variables (a last
witness time, a deque of not-yet-old-enough witnesses). Anything above a future operator is a
*stream* (``rasm.spec.streams``) whose values come late; the generated code feeds the streams
their immediate inputs and reads the property's verdicts off the top stream.

The same body is generated several times: in ``step(t, record)`` (verdict objects, one call per
record), its variants ``tally`` and ``tally_into`` (plain values, for the Trustworthiness
Checker) and in ``run(records)`` (a loop over a whole trace, plain lists of values: ``rasm
check``). ``tally_into`` has a second, *quiet* copy for a record that carries none of the
file's events (most records of a loop): the events' values (false) folded in by
:mod:`rasm.spec.fold`.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from rasm.spec.ast import (
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
from rasm.spec.expr import _ARITH, _COMPARE, HELPERS, _max2, _min2
from rasm.spec.fold import fold
from rasm.spec.loader import signals_of
from rasm.spec.operators import EventuallyCore, OnceCore, SinceCore, UntilCore, WindowCore
from rasm.spec.streams import (
    AggregateStream,
    PointwiseStream,
    PrevStream,
    Source,
    TemporalStream,
    kleene_function,
)
from rasm.spec.types import TypeScope

__all__ = ["Program", "generate"]


@dataclass
class Program:
    """What :func:`generate` produces: the source and the objects it closes over."""

    source: str
    constants: dict[str, object]
    state: dict[str, object]
    roots: list[Source | None] = field(default_factory=list)  # per property, or None
    reads: list[tuple[str, ...]] = field(default_factory=list)  # warm-up signals per property


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


def _number(x: float) -> str:
    return "INF" if x == INF else repr(float(x))


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
        # inline future windows by their Source (kept alive here, so never confused with a
        # later one): (index of their first line, pending deque, upper bound), for the parent
        # that may keep the records it decides out of them (online_skip)
        self.windows: dict[Source, tuple[int, str, float]] = {}
        self.prevs: dict[tuple[int, str], str] = {}  # (property, operand) -> its prev's value

    def fresh(self, prefix: str) -> str:
        self.count += 1
        return f"{prefix}{self.count}"

    def constant(self, prefix: str, value: object) -> str:
        name = self.fresh(prefix)
        self.constants[name] = value
        return name

    def variable(self, prefix: str, initial: object) -> str:
        name = self.fresh(prefix)
        self.state[name] = initial
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
            if kind == "imm":
                return self.inline_future(node.bound.low, node.bound.high, None, value)
            core = EventuallyCore(node.bound.low, node.bound.high)
            return self.stream(TemporalStream, [(kind, value)], core)
        if isinstance(node, Until):
            left, right = self.emit(node.left), self.emit(node.right)
            if left[0] == right[0] == "imm":
                return self.inline_future(node.bound.low, node.bound.high, left[1], right[1])
            core = UntilCore(node.bound.low, node.bound.high)
            return self.stream(TemporalStream, [left, right], core)
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
            return "imm", _binary(node.op, values[0], values[1])
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
        if isinstance(node, Past):  # once, after normalise()
            return "imm", self.once(node.bound.low, node.bound.high, values[0])
        if isinstance(node, Since):
            return "imm", self.since(node.bound.low, node.bound.high, values[0], values[1])
        if isinstance(node, Aggregate):
            if node.op == "count" and node.bound.low == 0:
                return "imm", self.count_window(node.bound.high, values[0])
            core = self.constant("w", WindowCore(node.op, node.bound.low, node.bound.high))
            out = self.fresh("v")
            self.lines.append(f"{out} = {core}.push(t, {values[0]})")
            return "imm", out
        raise TypeError(f"cannot compile {node!r}")

    def undefined(self, node: Expr) -> object:
        # prev(φ) at a property's first record: a boolean is false, anything else undefined
        return False if self.types.check(node) == "bool" else math.nan

    def once(self, a: float, b: float, value: str) -> str:
        if a == 0 and b == INF:  # once, unbounded: a flag
            seen = self.variable("f", False)
            self.lines.append(f"if {value}: {seen} = True")
            return seen
        last = self.variable("l", None)
        out = self.fresh("v")
        if a == 0:
            self.lines.append(f"if {value}: {last} = t")
        else:
            pending = self.constant("q", deque())
            self.lines += [
                f"if {value}: {pending}.append(t)",
                f"while {pending} and t - {pending}[0] >= {_number(a)}: "
                f"{last} = {pending}.popleft()",
            ]
        self.lines.append(f"{out} = {self.within(last, b)}")
        return out

    def count_window(self, b: float, value: str) -> str:
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
            f"if {value}: {times}.append(t)",
            f"while {times} and t - {times}[0] > {_number(b)}: {times}.popleft()",
            f"{out} = len({times})",
        ]
        return out

    def since(self, a: float, b: float, left: str, right: str) -> str:
        last = self.variable("l", None)
        out = self.fresh("v")
        if a == 0:
            self.lines += [f"if not {left}: {last} = None", f"if {right}: {last} = t"]
        else:
            pending = self.constant("q", deque())
            self.lines += [
                f"if not {left}:",
                f"    {last} = None",
                f"    {pending}.clear()",
                f"if {right}: {pending}.append(t)",
                f"while {pending} and t - {pending}[0] >= {_number(a)}: "
                f"{last} = {pending}.popleft()",
            ]
        self.lines.append(f"{out} = {self.within(last, b)}")
        return out

    @staticmethod
    def within(last: str, b: float) -> str:
        if b == INF:
            return f"{last} is not None"
        return f"{last} is not None and t - {last} <= {_number(b)}"

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
        if isinstance(node, Past):
            return self.stream(TemporalStream, parts, OnceCore(node.bound.low, node.bound.high))
        if isinstance(node, Since):
            core = SinceCore(node.bound.low, node.bound.high)
            return self.stream(TemporalStream, parts, core)
        if isinstance(node, Aggregate):
            return self.stream(AggregateStream, parts, node.op, node.bound.low, node.bound.high)
        raise TypeError(f"cannot compile {node!r}")

    def stream(self, cls, parts, *args):
        inputs = [value if kind == "stream" else None for kind, value in parts]
        stream = cls(inputs, *args)
        name = self.constant("s", stream)
        immediate = [value for kind, value in parts if kind == "imm"]
        self.lines.append(f"{name}.step(i, t{''.join(', ' + v for v in immediate)})")
        self.finish_lines.append(f"{name}.finish()")
        return "stream", stream

    # ----------------------------------------------------------------- inline streams
    def inline_future(self, a: float, b: float, left: str | None, right: str):
        """``eventually[a,b] right`` (left None) or ``left until[a,b] right``, both immediate.

        Same algorithm as :class:`EventuallyCore`/:class:`UntilCore`, written into the step
        function: open records wait in ``pending``; decided ones go to the output queue.
        """
        source = Source()
        out = self.constant("o", source.out)
        pending = self.constant("w", deque())
        lines = [
            f"{pending}.append((i, t))",
            f"while t - {pending}[0][1] > {_number(b)}:",
            f"    _j, _tj = {pending}.popleft()",
            f"    {out}.append((_j, _tj, False))",
            f"if {right}:",
        ]
        if a == 0:
            lines += [f"    while {pending}:"]
        else:
            lines += [f"    while {pending} and t - {pending}[0][1] >= {_number(a)}:"]
        lines += [
            f"        _j, _tj = {pending}.popleft()",
            f"        {out}.append((_j, _tj, True))",
        ]
        if left is not None:
            lines += [
                f"if not {left}:",
                f"    while {pending}:",
                f"        _j, _tj = {pending}.popleft()",
                f"        {out}.append((_j, _tj, False))",
            ]
        self.windows[source] = (len(self.lines), pending, b)
        self.lines += lines
        # at the end of the trace the still-open windows are inconclusive
        self.finish_lines += [
            f"while {pending}:",
            f"    _j, _tj = {pending}.popleft()",
            f"    {out}.append((_j, _tj, None))",
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
        drain = [f"while {child}:", f"    _j, _tj, _v = {child}.popleft()"]
        if held is not None:
            drain.append(f"    _w = {held}.popleft()")
        if decides is not None and node is self.root:
            # online, the immediate side alone may decide the verdict (a false trigger of
            # "trigger -> eventually …"): say it now, and skip it when the stream catches up
            test, value = decides
            self.lines.append(("EARLY", f"if {test.format(w=immediate[0])}:"))
            self.lines.append(("EMIT", self.root_number, "i", "t", value, "    ", "EARLY"))
            drain.append(("EARLY", f"    if {test.format(w='_w')}: continue"))
        drain.append(f"    {out}.append((_j, _tj, {_kleene(node, names, position)}))")
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
        self.lines[start + 1] = f"while {pending} and t - {pending}[0][1] > {_number(b)}:"
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


def _binary(op: str, left: str, right: str) -> str:
    if op == "and":
        return f"({left} and {right})"
    if op == "or":
        return f"({left} or {right})"
    if op == "->":
        return f"((not {left}) or {right})"
    if op == "/":
        return f"_div({left}, {right})"
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
# the locals of tally_into whose values fold() may follow: verdicts, temporaries, the odd list
_FOLDED_LOCALS = r"_last\d+|v\d+|odd"


def generate(spec: Specification, reads: list[tuple[str, ...]] | None = None) -> Program:
    """Generate the step and run functions' source for every property of ``spec``.

    ``reads`` overrides, per property, the signals whose first values end its warm-up (by
    default: those it reads); explanations use it to evaluate sub-formulas in context.

    The source defines ``factory()`` returning ``(step, tally, tally_into, run, finish_step,
    finish_run)`` (``tally``: ``step`` giving ``(property, value)`` pairs, not verdicts;
    ``tally_into(t, rec, latest, unusual)``: ``tally`` keeping the pairs itself, see
    :meth:`rasm.spec.monitor.Monitor.tally_into`); it
    reads the names in ``Program.constants`` plus ``STATE`` (initial values),
    ``Verdict``, ``NAMES``, ``STARTS``, ``VALUES``, ``NUMERIC``, ``SCALAR``, ``UNSET``,
    ``REJECT_STEP``, ``REJECT_INTO`` and ``REJECT_RUN``, which the monitor provides.
    """
    gen = _Generator(spec)
    defaults = {item.name: item.default for item in spec.inputs if item.default is not None}
    events = {item.name for item in spec.events}
    blocks: list[list] = []
    finishes: list[list] = []
    every: list[bool] = []  # per property: a value on every record, never UNSET
    program = Program("", gen.constants, gen.state)
    for number, prop in enumerate(spec.properties):
        gen.lines, gen.finish_lines = [], []
        gen.root = normalise(prop.formula)
        gen.root_number = number
        kind, value = gen.emit(gen.root)
        if reads is None:
            needed = signals_of(prop.formula)
        else:
            needed = reads[number]
        warm = tuple(name for name in needed if name not in events and name not in defaults)
        program.reads.append(warm)
        # past-only, judged from the first record, and reading only signals that always have
        # a value (``reads`` may leave out some the formula reads)
        every.append(kind == "imm" and not warm and reads is None)
        program.roots.append(value if kind == "stream" else None)
        body: list = list(gen.lines)
        finish: list = list(gen.finish_lines)
        if kind == "imm":
            body.append(("EMIT", number, "i", "t", value))
        else:
            root = gen.constant("r", value.out)
            drain = [f"while {root}:", f"    _j, _tj, _v = {root}.popleft()"]
            drain.append(("EMIT", number, "_j", "_tj", "_v", "    "))
            body += drain
            finish += drain
        if warm:
            started = gen.variable("started", False)
            ready = " and ".join(f"{signal_variable(n)} is not UNSET" for n in warm)
            block: list = [f"if not {started} and {ready}:", f"    {started} = True"]
            block.append(f"    STARTS[{number}] = i")
            block.append(f"if {started}:")
            block += [_indent(line) for line in body]
        else:
            started = "i >= 0"
            block = [("FIRST", f"if i == 0: STARTS[{number}] = 0"), *body]
        blocks.append(block)
        if kind == "stream":
            finishes.append([f"if {started}:", *(_indent(line) for line in finish)])
    program.source = _assemble(spec, gen, blocks, finishes, defaults, events, every)
    return program


def _indent(line):
    if isinstance(line, tuple) and line[0] == "EARLY":
        return ("EARLY", "    " + line[1])
    if isinstance(line, tuple) and line[0] == "ONLINE":
        return ("ONLINE", "    " + line[1], "    " + line[2])
    if isinstance(line, tuple):
        return (*line[:5], (line[5] if len(line) > 5 else "") + "    ", *line[6:])
    return "    " + line


def _render(line, mode: str) -> str | None:
    """A generated line for ``mode`` (step, tally, into, quiet or run); None where the line is
    online-only (or, for ``quiet``, only for the first record).

    ``tally`` is ``step`` with each verdict as a plain ``(property, value)`` pair: what the
    Trustworthiness Checker keeps of a verdict when nobody asked for the verdicts themselves.
    ``into`` (``tally_into``; ``quiet``: its quiet path) holds each property's latest value of
    the record in ``_last<n>`` and the values that are not True, in order, in ``odd`` (a list
    made for the first such value): it hands them over once the whole record is decided, so a
    record that fails half way hands over nothing, as with ``tally``.
    """
    online = mode != "run"
    if isinstance(line, str):
        return line
    if line[0] == "FIRST":  # the quiet path of tally_into never sees the first record
        return None if mode == "quiet" else line[1]
    if line[0] == "EARLY":  # early verdicts exist online only: run() keeps record order
        return line[1] if online else None
    if line[0] == "ONLINE":  # the online functions' version of a line, and run()'s
        return line[1] if online else line[2]
    _, number, index, time, value, *rest = line
    if "EARLY" in rest and not online:
        return None
    pad = rest[0] if rest else ""
    if mode == "step":
        return f"{pad}out.append(Verdict(NAME_{number}, {index}, {time}, {value}))"
    if mode == "tally":
        return f"{pad}out.append((NAME_{number}, {value}))"
    if mode in ("into", "quiet"):
        last = f"_last{number}"
        if value == "True":  # an early verdict: nothing unusual to note
            return f"{pad}{last} = True"
        # the list is made for the first unusual value only: most records have none
        return (
            f"{pad}{last} = {value}\n"
            f"{pad}if {last} is not True:\n"
            f"{pad}    if odd is None: odd = []\n"
            f"{pad}    odd.append((NAME_{number}, {last}))"
        )
    return f"{pad}values_{number}({value})"


def _assemble(spec, gen: _Generator, blocks, finishes, defaults, events, every) -> str:
    # an event holds no value from one record to the next (absent means false): its variable is
    # a local of each function, set by every record; only inputs are held in the closure
    used = _used(spec)
    for name in used:
        if name not in events:
            gen.state[signal_variable(name)] = defaults.get(name, UNSET)
    absent = [name for name in used if name in events]  # from a quiet record
    if absent:
        gen.state["dict_after_first"] = None  # see into_function
    cells = sorted(gen.state) + ["i", "last_t"]
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
            lines += text.split("\n") if "\n" in text else [text]
        return lines

    def function(header: str, mode: str) -> list[str]:
        lines = [header, "    nonlocal " + ", ".join(cells)]
        if mode == "run":
            lines.append("    for t, rec in records:")
            indent = "        "
            reject = "REJECT_RUN"
        else:
            lines.append("    out = []")
            indent = "    "
            reject = "REJECT_STEP"
        # one past-only property: its verdict is the body's last statement, so the step
        # function can return a one-element list directly (cheaper than append + return)
        single = (
            mode in ("step", "tally")
            and len(blocks) == 1
            and isinstance(properties[-1], tuple)
            and properties[-1][0] == "EMIT"
            and properties[-1][2] == "i"
        )
        if single:
            lines.pop()  # no "out = []"
        body = rendered([*update, "i += 1", *properties[:-1]], mode, reject)
        last = rendered(properties[-1:], mode, reject)
        if single:
            last = [text.replace("out.append(", "return [", 1)[:-1] + "]" for text in last]
        lines += [indent + text for text in body + last]
        if mode == "run":
            lines.append("    return None")
        else:
            lines.append("    return []" if single else "    return out")
        return lines

    def into_function() -> list[str]:
        """``tally_into``; with a quiet path for records that carry none of the events."""
        kept = [f"_last{number}" for number in range(len(blocks))]

        def decide(mode: str) -> list[str]:
            # UNSET: no value for the property yet (one line each: fold() drops those a quiet
            # record surely sets)
            lines = [
                "odd = None",
                *(f"{kept[n]} = UNSET" for n in range(len(kept)) if not every[n]),
            ]
            lines += rendered(properties, mode)
            for number, last in enumerate(kept):
                handover = f"latest[NAME_{number}] = {last}"
                lines.append(handover if every[number] else f"if {last} is not UNSET: {handover}")
            return lines + [
                "if odd is not None:",
                "    for _name, _value in odd:",
                "        unusual(_name, _value)",
                "return None",
            ]

        lines = ["def tally_into(t, rec, latest, unusual):", "    nonlocal " + ", ".join(cells)]
        general = rendered([*update, "i += 1"], "into", "REJECT_INTO")
        if absent:
            # such a record reads each absent event as false: the same code with those values
            # folded in (rasm.spec.fold) decides the same, without reading or testing them
            if len(absent) > 5:
                gen.constants["QUIET"] = frozenset(absent)
                none = "QUIET.isdisjoint(rec)"  # one set lookup per key of the record
            else:  # a few dict lookups cost less than iterating over the record's keys
                none = " and ".join(f"{name!r} not in rec" for name in absent)
            known = tuple((signal_variable(name), False) for name in absent)
            quiet = [
                *rendered(_update_lines(spec, used, events, absent), "into", "REJECT_INTO"),
                "i += 1",
                *fold("\n".join(decide("quiet")), known, _FOLDED_LOCALS).splitlines(),
            ]
            # dict_after_first is None until the general code accepted a record: the quiet
            # path never sees the first record (and leaves out what only that one does)
            lines.append(f"    if rec.__class__ is dict_after_first and {none}:")
            lines += ["        " + text for text in quiet]
            general.append("dict_after_first = dict")
        return lines + ["    " + text for text in [*general, *decide("into")]]

    factory = ["def factory():"]
    for name in sorted(gen.state):
        factory.append(f"    {name} = STATE[{name!r}]")
    factory += ["    i = -1", "    last_t = -INF"]
    for number in range(len(blocks)):
        factory.append(f"    values_{number} = VALUES[{number}].append")
        factory.append(f"    NAME_{number} = NAMES[{number}]")
    factory += ["    " + line for line in function("def step(t, rec):", "step")]
    factory += ["    " + line for line in function("def tally(t, rec):", "tally")]
    factory += ["    " + line for line in into_function()]
    factory += ["    " + line for line in function("def run(records):", "run")]
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
    factory.append("    return step, tally, tally_into, run, finish_step, finish_run, held")
    return "\n".join(factory) + "\n"


def _used(spec: Specification) -> list[str]:
    # only the signals some property reads are held and checked: others cannot change a verdict
    used: dict[str, None] = {}
    for prop in spec.properties:
        for name in signals_of(prop.formula):
            used.setdefault(name, None)
    return list(used)


def _update_lines(spec: Specification, used: list[str], events: set[str], absent=()) -> list[str]:
    """Validate a record's time and the ``used`` signals' values, then update the held signals
    (all or nothing).

    The events in ``absent`` are left out: the caller knows the record does not carry them.

    The fast tests look at exact classes; anything else (a numpy float, an int subclass) takes
    the slow path through COERCE, which converts what it can and refuses the rest.
    """
    checks = [
        "if t.__class__ not in NUMERIC:",
        "    _t = COERCE(t, 'float')",
        "    if _t is BAD: return REJECT(i + 1, t, rec, None, 'time')",
        "    t = _t",
        # t is an int or a float now; one test for both a nan and a time going back: neither
        # is >= last_t
        "if not t >= last_t: return REJECT(i + 1, t, rec, None, 'time' if t != t else 'backwards')",
    ]
    assigns = []
    names = [name for name in used if name not in absent]
    for name in names:
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
        if name == names[-1]:  # the last check: nothing can refuse the record after it
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
    return guarded + assigns + ["last_t = t"]
