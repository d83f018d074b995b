"""Compiling a checked specification to Python source: one step function for all properties.

Each property's lines come from :class:`rasm.properties.formula_code.FormulaGenerator`; this
module puts them together with the record checks into one program. A property whose formula
looks into the future gets its verdicts off its top stream as they are decided, in any order:
``step`` gives each as a Verdict at once, ``run`` puts them back in record order
(:class:`rasm.properties.streams.InOrder`).

Windows compare times as exact integer nanoseconds: the generated code turns each record's time
``t`` (seconds, as given) into ``tn`` (:mod:`rasm.properties.times`); the bounds are
nanoseconds from the parser.

The same body is generated twice: in ``step(t, record)`` (verdict objects, one call per record)
and in ``run(records)`` (a loop over a whole trace, plain lists of values: ``rasm check``). Each
property's code runs in its own ``try``: if it raises, the monitor gives that property error
verdicts and resets its state (``rasm.properties.monitor``), and the other properties carry on.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from rasm.properties.ast import Specification
from rasm.properties.formula_code import FormulaGenerator, normalise, signal_variable
from rasm.properties.loader import signals_of
from rasm.properties.times import FAST

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
    # per property with a stream root: what holds the records owed a verdict online (a dict
    # index -> time, or a deque of (index, time) where verdicts come in record order), and
    # the InOrder that hands its values on in record order offline (None: they come so)
    owed: list[str | None] = field(default_factory=list)
    orders: list[str | None] = field(default_factory=list)


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
    gen = FormulaGenerator(spec)
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
        gen.owed = gen.order = None
        kind, value = gen.emit(gen.root)
        value = gen.property_value(gen.root, kind, value)
        if reads is None:
            needed = signals_of(prop.formula)
        else:
            needed = reads[number]
        warm = tuple(name for name in needed if name not in events and name not in defaults)
        program.reads.append(warm)
        body: list = list(gen.lines)
        finish: list = list(gen.finish_lines)
        order = None
        if kind == "imm":
            body.append(("EMIT", number, "i", "t", value, "", None))
        else:
            root = gen.constant("r", value.out)
            # verdicts that may come out of record order go back in order offline
            order = None if value.ordered else gen.in_order()
            if gen.owed is not None:  # the root gives early verdicts: it owes the others
                forget = f"    del {gen.owed}[_j]"
            elif value.ordered:  # owed in record order: a queue
                gen.owed = gen.constant("owed", deque())
                body.insert(0, ("ONLINE", f"{gen.owed}.append((i, t))", None))
                forget = f"    {gen.owed}.popleft()"
            else:
                gen.owed = gen.constant("owed", {})
                body.insert(0, ("ONLINE", f"{gen.owed}[i] = t", None))
                forget = f"    del {gen.owed}[_j]"
            # a verdict given, the record is no longer owed (in this order: a verdict that
            # fails to be made leaves its record owed)
            drain = [
                f"while {root}:",
                f"    _j, _tj, _tn, _v = {root}.popleft()",
                ("EMIT", number, "_j", "_tj", "_v", "    ", order),
                ("ONLINE", forget, None),
            ]
            body += drain
            finish += drain
        program.owed.append(gen.owed if kind == "stream" else None)
        program.orders.append(order)
        if hook:
            body.insert(0, f"FAULT_HOOK(NAME_{number}, i)")
        guarded = _guarded(body, number, finishing=False)
        if warm:
            started = gen.variable("started", False, owned=False)
            ready = " and ".join(f"{signal_variable(n)} is not UNSET" for n in warm)
            block: list = [f"if not {started} and {ready}:", f"    {started} = True"]
            block.append(f"    STARTS[{number}] = i")
            if order is not None:
                block.append(f"    {order}.next = i")
            block.append(f"if {started}:")
            block += [_indent(line) for line in guarded]
        else:
            started = "i >= 0"
            first = f"STARTS[{number}] = 0" + (f"; {order}.next = 0" if order is not None else "")
            block = [f"if i == 0: {first}", *guarded]
        blocks.append(block)
        if kind == "stream":
            finishes.append(
                [f"if {started}:", *(_indent(line) for line in _guarded(finish, number, True))]
            )
    program.source = _assemble(spec, gen, blocks, finishes, events, program.reads)
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
        kind, number, index, time, value, indent, order = line
        return (kind, number, index, time, value, pad + indent, order)
    kind, number, indent, finishing = line  # FAULT
    return (kind, number, pad + indent, finishing)


def _render(line, mode: str) -> str | None:
    """A generated line for ``mode`` (step or run); None where the line is online-only.

    Line kinds: a string (both modes); ``("ONLINE", step_text, run_text)`` (``run_text`` None:
    step only); ``("EMIT", property, index, time, value, indent, order)`` (a verdict: a
    Verdict object online, a plain value in ``run``, through ``order`` — an InOrder — where
    verdicts come in any order); ``("FAULT", property, indent, finishing)`` (the handler of a
    property's exception).
    """
    online = mode == "step"
    if isinstance(line, str):
        return line
    if line[0] == "ONLINE":
        return line[1] if online else line[2]
    if line[0] == "EMIT":
        _, number, index, time, value, pad, order = line
        if online:
            return f"{pad}out.append(Verdict(NAME_{number}, {index}, {time}, {value}))"
        if order is not None:
            if index == "i":
                return f"{pad}{order}.put(i, {value}, values_{number})"
            # values in record order go straight on (the common case: one call less)
            return (f"{pad}if {index} == {order}.next and not {order}.waiting: "
                    f"values_{number}({value}); {order}.next += 1\n"
                    f"{pad}else: {order}.put({index}, {value}, values_{number})")
        return f"{pad}values_{number}({value})"
    _, number, pad, finishing = line
    if online:
        if finishing:
            return f"{pad}FAULT({number}, None, None, None, _exc, out)"
        return f"{pad}FAULT({number}, i, t, tn, _exc, out)"
    return f"{pad}FAULT_RUN({number}, i, {'None' if finishing else 'tn'}, _exc)"


def _assemble(spec, gen: FormulaGenerator, blocks, finishes, events, reads) -> str:
    # an event holds no value from one record to the next (absent means false): its variable is
    # a local of each function, set by every record; only inputs are held in the closure.
    # A warm-up may wait for a signal no formula reads (``reads``): it is held all the same.
    used = checked_signals(spec)
    used += dict.fromkeys(name for warm in reads for name in warm if name not in used)
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
            lines += text.split("\n")  # (a verdict given in record order is two lines)
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
