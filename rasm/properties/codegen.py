"""Compiling a checked specification to Python source: one step function for all properties.

Each property's lines (:mod:`rasm.properties.lines`) come from
:class:`rasm.properties.formula_code.FormulaGenerator`; this module puts them together with the
record checks into one program. What the program reads besides its own constants, the monitor
provides: the names of :class:`Runtime`. A property whose formula looks into the future gets
its verdicts off its top stream as they are decided, in any order: ``step`` gives each as a
Verdict at once, ``run`` puts them back in record order
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
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from rasm.properties.ast import Specification
from rasm.properties.emitter import Names, PropertyCode, signal_variable
from rasm.properties.formula_code import FormulaGenerator
from rasm.properties.lines import Block, Code, Fault, Line, Offline, Online, Reject, render
from rasm.properties.loader import signals_of
from rasm.properties.robust_code import RobustCode, RobustnessGenerator
from rasm.properties.times import FAST

__all__ = ["RUNTIME", "UNSET", "Program", "Runtime", "checked_signals", "generate"]


class Runtime(NamedTuple):
    """What the generated code reads besides :attr:`Program.constants`: the monitor provides
    one of each (:class:`rasm.properties.monitor.Monitor`), by these names, and the generated
    code reads no other (``tests/properties/test_passes.py`` checks both)."""

    STATE: Any  # the closure variables' initial values, by name (Program.state)
    Verdict: Any  # the class of the verdicts step gives
    VERDICT_NEW: Any  # tuple.__new__: a Verdict from the tuple of all its fields, in C
    NAMES: Any  # the property names, in file order
    STARTS: Any  # per property: the index of its first judged record (set by the code)
    VALUES: Any  # per property: the list run appends its values to, in record order
    UNSET: Any  # a held signal's value before its first (UNSET below)
    NUMERIC: Any  # the classes a float signal's value may have on the fast path
    SCALAR: Any  # the classes a signal of unknown type may have on the fast path
    COERCE: Any  # (value, kind) -> the plain value, or BAD: the slow path of the checks
    BAD: Any  # what COERCE gives for a value that does not fit
    NANOSECONDS: Any  # a time that is no plain number -> exact nanoseconds, or None
    SECONDS: Any  # such a time -> the int or float a verdict carries
    REJECT_STEP: Any  # (index, time, record, signal, kind): step refuses a record
    REJECT_RUN: Any  # the same for run (it raises)
    FAULT: Any  # (property, index, time, ns, exception, out): a property raised, online
    FAULT_RUN: Any  # (property, index, ns, exception): offline
    RECOVERING: Any  # the properties recovering from a fault (a dict: falsy when none)
    RECOVER: Any  # (index, ns, out) -> out: the verdicts of recovering properties, online
    RECOVER_RUN: Any  # (index, ns): offline
    FAULT_HOOK: Any  # (property name, index): a test's way to make a property raise
    ROBUST: Any  # per property: the list its final robustness values go to, in record order


RUNTIME: tuple[str, ...] = Runtime._fields


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
    # with robustness: per property, the constant naming the stream its robustness comes off
    # (None: known at each record), and online the deque of the records whose robustness is
    # not final yet, oldest first
    robust_tops: list[str | None] = field(default_factory=list)
    robust_records: list[str | None] = field(default_factory=list)


# --------------------------------------------------------------------------- whole programs

UNSET = type("Unset", (), {"__repr__": lambda self: "<unset>"})()


def generate(
    spec: Specification,
    reads: list[tuple[str, ...]] | None = None,
    *,
    hook: bool = False,
    robustness: bool = False,
) -> Program:
    """Generate the step and run functions' source for every property of ``spec``.

    ``reads`` overrides, per property, the signals whose first values end its warm-up (by
    default: those it reads); explanations use it to evaluate sub-formulas in context.
    ``hook``: each property's code starts with a call ``FAULT_HOOK(property, index)`` (a test's
    way to make a property raise; see :class:`rasm.properties.monitor.Monitor`).
    ``robustness``: each property's code also computes its robustness (SPEC §12,
    :mod:`rasm.properties.robust_code`), after its boolean lines, appending each record's final
    value to ``ROBUST[k]``; without it the program is the same as before.

    The source defines ``factory()`` returning ``(step, run, finish_step, finish_run, held,
    resets)``: ``held()`` tells which held signals have had a value, ``resets[k]()`` puts
    property k's closure variables back to their initial values (its constants are renewed by
    the caller, from a fresh :func:`generate`). It reads the names in ``Program.constants`` and
    those of :class:`Runtime`, which the monitor provides.
    """
    names = Names()
    gen = FormulaGenerator(spec, names)
    robust = RobustnessGenerator(spec, names) if robustness else None
    defaults = {item.name: item.default for item in spec.inputs if item.default is not None}
    events = {item.name for item in spec.events}
    blocks: list[list[Line]] = []
    finishes: list[list[Line]] = []
    program = Program("", names.constants, {}, owned=names.owned)
    for number, prop in enumerate(spec.properties):
        rcode = robust.compile(number, prop.formula) if robust is not None else None
        # online, each verdict goes out with its robustness: the variable holding it, or
        # where it comes late, a dict of the final values whose verdict is still to come
        known = None
        if rcode is not None:
            known = rcode.value or names.constant(number, "rk", {})
        code = gen.compile(number, prop.formula, robustness=known)
        needed = signals_of(prop.formula) if reads is None else reads[number]
        warm = tuple(name for name in needed if name not in events and name not in defaults)
        program.reads.append(warm)
        program.owed.append(code.owed)
        program.orders.append(code.order)
        body, finish = list(code.body), list(code.finish)
        if rcode is not None:
            body += rcode.body
            finish += rcode.finish
            program.robust_tops.append(rcode.top)
            if rcode.value is not None:
                body += _robust_now(number, rcode.value)
                program.robust_records.append(None)
            else:
                records = names.constant(number, "rj", deque())
                body += _robust_late(number, rcode, code, records, known)
                program.robust_records.append(records)
        # the verdicts go out after the robustness lines: with the robustness final by then
        body += code.verdicts
        if code.late:
            finish += code.verdicts
        if hook:
            body.insert(0, Code(f"FAULT_HOOK(NAME_{number}, i)"))
        guarded = _guarded(body, number, finishing=False)
        if warm:
            started = names.variable(None, "started", False)
            ready = " and ".join(f"{signal_variable(n)} is not UNSET" for n in warm)
            start = [Code(f"{started} = True"), Code(f"STARTS[{number}] = i")]
            if code.order is not None:
                start.append(Code(f"{code.order}.next = i"))
            block: list[Line] = [
                Block(f"if not {started} and {ready}:", tuple(start)),
                Block(f"if {started}:", tuple(guarded)),
            ]
        else:
            started = "i >= 0"
            first = f"STARTS[{number}] = 0"
            if code.order is not None:
                first += f"; {code.order}.next = 0"
            block = [Code(f"if i == 0: {first}"), *guarded]
        blocks.append(block)
        if code.late or finish:
            finishes.append([Block(f"if {started}:", tuple(_guarded(finish, number, True)))])
    # an event holds no value from one record to the next (absent means false): its variable is
    # a local of each function, set by every record; only inputs are held in the closure.
    # A warm-up may wait for a signal no formula reads (``reads``): it is held all the same.
    used = checked_signals(spec)
    used += dict.fromkeys(name for warm in program.reads for name in warm if name not in used)
    program.state = dict(names.state)
    for name in used:
        if name not in events:
            program.state[signal_variable(name)] = defaults.get(name, UNSET)
    program.source = _assemble(spec, program, used, blocks, finishes, events)
    return program


def _robust_now(number: int, value: str) -> list[Line]:
    """A robustness known at each record: offline appended to the property's list, online
    made a float for its verdict."""
    return [
        Offline((Code(f"ROBUST_{number}({value})"),)),
        Online(f"if {value}.__class__ is not float: {value} = AS_FLOAT({value})"),
    ]


def _robust_late(number: int, rcode: RobustCode, code: PropertyCode, records: str,
                 known: str) -> list[Line]:
    """Robustness values that come late, final and in record order (``rcode.out``): offline
    appended to the property's list; online each kept in ``known`` by record (``records``:
    the records whose value is not final yet, oldest first) for its verdict to take, unless
    that verdict went out before (decided early: it has no robustness, and the value is not
    kept)."""
    out, owed = rcode.out, code.owed
    if code.order is None:  # verdicts in record order, owed in a queue: the newest ones
        to_come = f"{owed} and {owed}[0][0] <= _k"
    else:
        to_come = f"_k in {owed}"
    return [
        Online(f"{records}.append(i)"),
        Online(f"while {out}:"),
        Online(f"    _r = {out}.popleft()"),
        Online(f"    _k = {records}.popleft()"),
        Online(f"    if {to_come}: {known}[_k] = _r if _r.__class__ is float else AS_FLOAT(_r)"),
        Offline((Code(f"if {out}: ROBUSTS_{number}({out}); {out}.clear()"),)),
    ]


def _guarded(body: Sequence[Line], number: int, finishing: bool) -> list[Line]:
    """``body`` in a ``try`` whose failure is property ``number``'s fault, not the file's."""
    return [Block("try:", tuple(body)),
            Block("except Exception as _exc:", (Fault(number, finishing),))]


def _assemble(
    spec: Specification,
    program: Program,
    used: list[str],
    blocks: list[list[Line]],
    finishes: list[list[Line]],
    events: set[str],
) -> str:
    state = program.state
    cells = sorted(state) + ["i", "last_tn"]
    body = [*_update_lines(spec, used, events), Code("i += 1")]
    body += [line for block in blocks for line in block]

    step = ["def step(t, rec):", "    nonlocal " + ", ".join(cells), "    out = []"]
    step += render(body, online=True, pad="    ")
    # a property recovering from a fault: its verdicts that depend on records from before
    # its reset are errors (rasm.properties.recovery)
    step += ["    if RECOVERING: return RECOVER(i, tn, out)", "    return out"]

    run = ["def run(records):", "    nonlocal " + ", ".join(cells), "    for t, rec in records:"]
    run += render(body, online=False, pad="        ")
    run += ["        if RECOVERING: RECOVER_RUN(i, tn)", "    return None"]

    factory = ["def factory():"]
    for name in sorted(state):
        factory.append(f"    {name} = STATE[{name!r}]")
    factory += ["    i = -1", "    last_tn = -INF"]
    for number in range(len(blocks)):
        factory.append(f"    values_{number} = VALUES[{number}].append")
        factory.append(f"    NAME_{number} = NAMES[{number}]")
        if program.robust_tops:
            factory.append(f"    ROBUST_{number} = ROBUST[{number}].append")
            factory.append(f"    ROBUSTS_{number} = ROBUST[{number}].extend")
    factory += ["    " + line for line in step + run]
    for online, mode in ((True, "step"), (False, "run")):
        factory += [
            f"    def finish_{mode}():",
            "        nonlocal " + ", ".join(cells),
            "        out = []",
        ]
        for block in finishes:
            factory += render(block, online, pad="        ")
        factory.append("        return out")
    # which held signals have had a value so far (a property not judged names the missing ones)
    held = [name for name in used if name not in events]
    factory.append("    def held():")
    pairs = ", ".join(f"{name!r}: {signal_variable(name)} is not UNSET" for name in held)
    factory.append("        return {" + pairs + "}")
    # each property's closure variables back to their initial values
    for number, owned in enumerate(program.owned):
        variables = [name for name in owned if name in state]
        factory.append(f"    def reset_{number}():")
        if variables:
            factory.append("        nonlocal " + ", ".join(variables))
        factory += [f"        {name} = STATE[{name!r}]" for name in variables]
        factory.append("        return None")
    resets = "".join(f"reset_{number}, " for number in range(len(program.owned)))
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


def _update_lines(spec: Specification, used: list[str], events: set[str]) -> list[Line]:
    """Validate a record's time and the ``used`` signals' values, then update the held signals
    (all or nothing).

    The time ``t`` (seconds, as given) becomes ``tn``, exact integer nanoseconds
    (:mod:`rasm.properties.times`): at once for an int and for a float below FAST, through
    NANOSECONDS for anything else (then ``t``, which the ``time`` expression reads and verdicts
    carry, becomes an int or a float through SECONDS). The values' fast tests look at exact
    classes; anything else (a numpy float, an int subclass) takes the slow path through COERCE,
    which converts what it can and refuses the rest.
    """
    checks: list[Line] = [
        # round(t * 1e9) without round()'s lookup of the method (a float's, known here): a
        # third of what converting each record's time costs
        Block(f"if t.__class__ is float and {-FAST!r} < t < {FAST!r}:", (
            Code("tn = (t * 1e9).__round__()"),
        )),
        Block("elif t.__class__ is int:", (Code("tn = t * 1000000000"),)),
        Block("else:", (
            Code("tn = NANOSECONDS(t)"),
            Reject("tn is None", None, "time"),
            Code("t = SECONDS(t)"),
        )),
        Reject("tn < last_tn", None, "backwards"),
    ]
    assigns: list[Line] = []
    for name in used:
        kind = spec.signals[name]
        var = signal_variable(name)
        tmp = f"n_{name}"
        if name in events:  # a local: a rejected record leaves no trace of it
            checks += [
                Code(f"{var} = rec.get({name!r}, False)"),
                Block(f"if {var} is not True and {var} is not False:", (
                    Code(f"{var} = COERCE({var}, 'bool')"),
                    Reject(f"{var} is BAD", name, "bool"),
                )),
            ]
            continue
        check = {
            "float": f"{tmp}.__class__ not in NUMERIC",
            "int": f"{tmp}.__class__ is not int",
            "bool": f"{tmp}.__class__ is not bool",
            "str": f"{tmp}.__class__ is not str",
            "any": f"{tmp}.__class__ not in SCALAR",
        }[kind]
        coerce = (Code(f"{tmp} = COERCE({tmp}, {kind!r})"), Reject(f"{tmp} is BAD", name, kind))
        checks.append(Code(f"{tmp} = rec.get({name!r}, UNSET)"))
        if name == used[-1]:  # the last check: nothing can refuse the record after it
            checks.append(Block(f"if {tmp} is not UNSET:", (
                Block(f"if {check}:", coerce),
                Code(f"{var} = {tmp}"),
            )))
        else:
            checks.append(Block(f"if {tmp} is not UNSET and {check}:", coerce))
            assigns.append(Code(f"if {tmp} is not UNSET: {var} = {tmp}"))
    # a record that is not a mapping (no .get), or a time that cannot be compared
    guarded = [
        Block("try:", tuple(checks)),
        Block("except (AttributeError, TypeError):", (Reject(None, None, "record"),)),
    ]
    return guarded + assigns + [Code("last_tn = tn")]
