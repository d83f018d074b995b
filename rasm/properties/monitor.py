"""The online monitor: ``compile_properties(text)``, ``Monitor.step``, ``.finish``, ``.run``."""

from __future__ import annotations

import copy
import functools
import math
import numbers
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from types import CodeType
from typing import NamedTuple

from rasm.errors import Misfit, SpecError
from rasm.properties.ast import Specification
from rasm.properties.codegen import UNSET, Runtime, generate
from rasm.properties.loader import load_specification
from rasm.properties.recovery import Recovery
from rasm.properties.robust_ops import as_float, pending_at
from rasm.properties.times import format_seconds, nanoseconds, seconds_value
from rasm.values import fit, wanted

__all__ = ["Monitor", "PropertyRun", "Rejection", "Verdict", "compile_properties"]

INF = math.inf
NUMERIC = frozenset((int, float))
SCALAR = frozenset((int, float, str, bool))


class Verdict(NamedTuple):
    """A property's value at one record: True, False, or None (inconclusive, at the end).

    ``error`` is set (and ``value`` is False) when the property could not be evaluated at this
    record: the checker cannot vouch for it, so it counts as not satisfied everywhere.
    """

    property: str
    index: int
    time: float
    value: bool | None
    error: str | None = None
    # with Monitor(robustness=True) (SPEC §12): the final robustness, or None where it is not
    # final yet (a verdict decided early, or inconclusive at the end); an interval that
    # contains the final value (lo == hi once final; for a verdict decided early only with
    # Monitor(intervals=True), or with intervals="newest" for the newest verdict of its
    # property in the step; else None). An error's is -inf.
    robustness: float | None = None
    robustness_interval: tuple[float, float] | None = None


@dataclass(frozen=True)
class Rejection:
    """A record the monitor refused (it changed nothing): which one and why."""

    index: int
    time: object
    reason: str


@dataclass
class PropertyRun:
    """A property's verdicts over a whole trace: ``values[k]`` is the verdict at ``start + k``.

    ``errors`` maps a record index to why the property could not be evaluated there (its value
    there is False); ``missing`` names the signals that never had a value when ``start`` is None
    (the property was never judged).
    """

    name: str
    start: int | None
    values: list
    errors: dict[int, str] = field(default_factory=dict)
    missing: tuple[str, ...] = ()
    # with robustness: ``robustness[k]`` is the robustness at ``start + k`` (None: not final)
    robustness: list | None = None


BAD = type("Bad", (), {"__repr__": lambda self: "<bad value>"})()


def coerce(value, kind: str):
    """The slow path of the generated checks: :func:`rasm.values.fit` of a value whose class
    is not the one the fast test looks for (a numpy number, an int subclass), an int given for
    a float kept exact.

    Returns the plain Python value, or :data:`BAD`.
    """
    try:
        return fit(value, kind, int_as_float=False)
    except Misfit:
        return BAD


def describe_rejection(time, record, signal: str | None, kind: str) -> str:
    """Why a record was rejected, in words (shared with the trace reader)."""
    if kind == "record":
        return f"a record must map signal names to values, not {type(record).__name__}"
    if kind == "time":
        if isinstance(time, numbers.Real) and not isinstance(time, bool):
            return f"'time' must be finite, not {time!r}"
        return f"'time' must be a number, not {time!r}"
    if kind == "backwards":
        return f"time {format_seconds(time)} goes back in time"
    value = record.get(signal)
    return f"{signal!r} must be {wanted(kind)}, not {json_repr(value)}"


def json_repr(value) -> str:
    import json

    try:
        return json.dumps(value)
    except (TypeError, ValueError):
        return repr(value)


class Monitor:
    """Incremental monitor of every property of one file.

    ``step(time, values)`` takes one record (the signals it updates) and returns the verdicts it
    decided (past-only properties: the one for this record; bounded-future ones: each verdict no
    later than the first record beyond its window). ``finish()`` returns the remaining verdicts,
    ``None`` where the trace ended too early to decide. A bad record (a time going back, a value
    of the wrong type) is refused, counted in ``rejected`` and changes nothing; ``step`` then
    returns no verdicts.

    Each property is evaluated on its own: if evaluating one raises (a safety net: arithmetic
    and aggregates never raise, :mod:`rasm.properties.expr`), its verdict for that record, and for
    every earlier record still waiting in its future windows, is an error (``value`` False,
    ``error`` saying why), its state is reset, and the other properties carry on untouched. Its
    verdicts that depend on records from before the reset are errors too, until they no longer
    do (:mod:`rasm.properties.recovery`); after that they are exact again. Every record gets exactly
    one verdict per started property either way.

    ``fault_hook(property, index)``, if given, is called before each property is evaluated at
    each record; whatever it raises is that property's fault there. It is for tests of the
    isolation above (the monitor is generated with the extra call; none otherwise).
    """

    def __init__(
        self,
        spec: Specification,
        *,
        reads: list[tuple[str, ...]] | None = None,
        fault_hook: Callable[[str, int], object] | None = None,
        robustness: bool = False,
        intervals: bool | str = False,
    ) -> None:
        if intervals not in (False, True, "newest"):
            raise ValueError(f"intervals must be False, True or 'newest', not {intervals!r}")
        self.spec = spec
        # an early verdict's robustness interval: True, each one's (in proportion to the
        # records in the property's windows); "newest", that of the newest verdict of each
        # property in a step (Monitor.interval: at a cost independent of the bounds)
        self._intervals = intervals
        self.names = [p.name for p in spec.properties]
        self._reads = reads
        self._hook = fault_hook is not None
        self.robustness = robustness
        self.program = generate(spec, reads, hook=self._hook, robustness=robustness)
        self.starts: list[int | None] = [None] * len(self.names)
        self.rejected: list[Rejection] = []
        self._values: list[list] = [[] for _ in self.names]
        self._taken = [0] * len(self.names)  # offline: values handed out by take(), per property
        self._errors: list[dict[int, str]] = [{} for _ in self.names]
        # properties recovering from a fault, by number; offline, every reset of each
        self._recovering: dict[int, Recovery] = {}
        self._resets_run: list[list[Recovery]] = [[] for _ in self.names]
        self._pristine: dict[int, dict[str, object]] = {}
        self._finished = False
        runtime = Runtime(
            STATE=self.program.state,
            Verdict=Verdict,
            VERDICT_NEW=tuple.__new__,
            NAMES=self.names,
            STARTS=self.starts,
            VALUES=self._values,
            UNSET=UNSET,
            NUMERIC=NUMERIC,
            SCALAR=SCALAR,
            COERCE=coerce,
            BAD=BAD,
            NANOSECONDS=nanoseconds,
            SECONDS=seconds_value,
            REJECT_STEP=self._reject_step,
            REJECT_RUN=self._reject_run,
            FAULT=self._fault,
            FAULT_RUN=self._fault_run,
            RECOVERING=self._recovering,
            RECOVER=self._recover,
            RECOVER_RUN=self._recover_run,
            FAULT_HOOK=fault_hook,
            ROBUST=[[] for _ in self.names],
        )
        self._robust: list[list] = runtime.ROBUST  # offline: the values in record order
        self._number = {name: k for k, name in enumerate(self.names)}
        namespace = {**self.program.constants, **runtime._asdict()}
        self._namespace = namespace
        code = compile_source(self.program.source, spec.source)
        exec(code, namespace)
        (
            self._step,
            self._run,
            self._finish,
            self._finish_run,
            self._held,
            self._resets,
        ) = namespace["factory"]()
        # the generated function itself, not a method around it: one call less per record
        # (online, each verdict comes out of it with its robustness where that is final)
        self._add_intervals: Callable[[list[Verdict]], list[Verdict]] | None = None
        if robustness and intervals:
            self._add_intervals = (self._with_newest_interval if intervals == "newest"
                                   else self._with_intervals)
        self.step = self._step if self._add_intervals is None else self._step_with_intervals

    # ----------------------------------------------------------------- online
    @property
    def properties(self) -> list[str]:
        """The property names, in file order."""
        return list(self.names)

    def step(self, time: float, values: Mapping[str, object]) -> list[Verdict]:
        """Feed one record; return the verdicts it decided.

        (Each monitor replaces this method by its generated step function.)
        """
        return self._step(time, values)

    def _step_with_intervals(self, time: float, values: Mapping[str, object]) -> list[Verdict]:
        out = self._step(time, values)
        return self._add_intervals(out) if out else out

    def _with_intervals(self, out: list[Verdict]) -> list[Verdict]:
        """The verdicts ``out``, each decided before its robustness is final with the interval
        known now (``Monitor(intervals=True)``)."""
        intervals: dict[int, dict[int, tuple[float, float]]] = {}  # by property, this step
        for position, verdict in enumerate(out):
            if verdict.robustness is None and verdict.error is None:
                k = self._number[verdict.property]
                if k not in intervals:  # computed once per property and step
                    intervals[k] = self.intervals(self.names[k])
                interval = intervals[k].get(verdict.index, (-INF, INF))
                out[position] = verdict._replace(robustness_interval=interval)
        return out

    def _with_newest_interval(self, out: list[Verdict]) -> list[Verdict]:
        """The verdicts ``out``, the newest of each property with the interval known now if it
        was decided before its robustness is final (``Monitor(intervals="newest")``)."""
        newest: dict[str, int] = {}  # property -> the position of its newest verdict
        for position, verdict in enumerate(out):
            known = newest.get(verdict.property)
            if known is None or verdict.index >= out[known].index:
                newest[verdict.property] = position
        for position in newest.values():
            verdict = out[position]
            if verdict.robustness is None and verdict.error is None:
                interval = self.interval(verdict.property, verdict.index)
                out[position] = verdict._replace(robustness_interval=interval)
        return out

    def interval(self, name: str, index: int) -> tuple[float, float]:
        """With robustness: an interval known to contain the robustness of property ``name``
        at record ``index`` while it is not final, at a cost independent of the bounds:
        the one :meth:`intervals` gives where the operators can answer for one record as
        cheaply (docs/properties.md §10), else wider, down to (-inf, inf): nothing known.
        (-inf, inf) too for a record whose robustness is final or was never open."""
        k = self._number[name]
        top = self.program.robust_tops[k] if self.robustness else None
        if top is None or self.starts[k] is None:
            return (-INF, INF)
        records = self._namespace[self.program.robust_records[k]]
        if not records or not records[0] <= index <= records[-1]:
            return (-INF, INF)
        lo, hi = pending_at(self._namespace[top], index - records[0])
        return (as_float(lo), as_float(hi))

    def intervals(self, name: str) -> dict[int, tuple[float, float]]:
        """With robustness: for each record whose robustness is not final yet (its window
        reaches records still to come), the interval known to contain it, by record index.
        It costs in proportion to the records in the property's windows."""
        k = self.names.index(name)
        top = self.program.robust_tops[k] if self.robustness else None
        if top is None or self.starts[k] is None:
            return {}
        records = self._namespace[self.program.robust_records[k]]
        pending = self._namespace[top].intervals()
        return {j: (as_float(lo), as_float(hi))
                for j, (lo, hi) in zip(records, pending, strict=True)}

    def reads(self, name: str) -> tuple[str, ...]:
        """The signals property ``name`` reads (those of the lets it uses too)."""
        return tuple(self.program.reads[self.names.index(name)])

    def missing(self, name: str) -> tuple[str, ...]:
        """The signals property ``name`` waits for: those it reads that have had no value yet
        (empty once it has started)."""
        k = self.names.index(name)
        if self.starts[k] is not None:
            return ()
        held = self._held()
        return tuple(s for s in self.program.reads[k] if not held.get(s, False))

    def _refuse(self, time, values, *rest):
        raise SpecError("this monitor has finished; compile a new one for a new trace")

    def _reject_step(self, index, time, record, signal, kind) -> list:
        self.rejected.append(Rejection(index, time, describe_rejection(time, record, signal, kind)))
        return []

    def _reject_run(self, index, time, record, signal, kind):
        raise SpecError(f"record {index}: {describe_rejection(time, record, signal, kind)}")

    def finish(self) -> list[Verdict]:
        """End of the trace: settle what is still open (``None``: inconclusive)."""
        if self._finished:
            return []
        self._finished = True
        self.step = self._refuse
        out = self._finish()
        for k, recovery in self._recovering.items():
            self._taint(k, recovery, out)
        return out if self._add_intervals is None else self._add_intervals(out)

    # ----------------------------------------------------------------- faults
    def _fault(self, k: int, index: int | None, time, ns: int | None, exc: Exception,
               out: list[Verdict]) -> None:
        """Property ``k`` raised at record ``index`` (None: while finishing): an error verdict
        for every record it owes one, then (at a record) a fresh state for it."""
        name = self.names[k]
        why = _why(exc, index)
        recovery = self._recovering.pop(k, None)
        if recovery is not None:  # what it decided at this record before it raised
            self._taint(k, recovery, out)
        owed_name = self.program.owed[k]
        owed = []
        if owed_name is not None:
            held = self._namespace[owed_name]
            owed = list(held.items()) if isinstance(held, dict) else list(held)
        if index is not None and all(j != index for j, _ in owed) and not any(
            v.property == name and v.index == index for v in out
        ):
            owed.append((index, time))
        # an error's robustness is -inf (the fresh state's values start at the next record)
        robust = (-INF, (-INF, -INF)) if self.robustness else ()
        out.extend(Verdict(name, j, tj, False, why, *robust) for j, tj in owed)
        if index is not None:
            self._reset(k)
            self._recovering[k] = Recovery(self.spec.properties[k].formula, index, ns, why)

    def _recover(self, index: int, ns: int, out: list[Verdict]) -> list[Verdict]:
        """After each record while a property recovers (online): its verdicts that depend on
        records from before its reset become errors."""
        for k, recovery in list(self._recovering.items()):
            recovery.note(index, ns)
            self._taint(k, recovery, out)
            if recovery.over:
                del self._recovering[k]
        return out

    def _taint(self, k: int, recovery: Recovery, out: list[Verdict]) -> None:
        name = self.names[k]
        for position, verdict in enumerate(out):
            if verdict.property == name and verdict.error is None and recovery.tainted(
                verdict.index
            ):
                # an error's robustness is -inf
                robust = {"robustness": -INF, "robustness_interval": (-INF, -INF)}
                out[position] = verdict._replace(value=False, error=recovery.why,
                                                 **(robust if self.robustness else {}))
                recovery.given += 1

    def _fault_run(self, k: int, index: int, ns: int | None, exc: Exception) -> None:
        """:meth:`_fault` offline: values go out in record order, so every record from the
        property's last value given to ``index`` gets its value now: the one decided before
        the fault where there is one (as online), else an error; ``ns`` None: while
        finishing."""
        values, errors = self._values[k], self._errors[k]
        why = _why(exc, index if ns is not None else None)
        recovery = self._recovering.pop(k, None)
        if recovery is not None:
            recovery.until = index
        order = self.program.orders[k]
        decided = self._namespace[order].waiting if order is not None else {}
        for j in range(self.starts[k] + self._taken[k] + len(values), index + 1):
            if j in decided:
                values.append(decided.pop(j))
            else:
                values.append(False)
                errors[j] = why
        if self.robustness:  # the records up to this one have theirs (an error's: -inf)
            robust = self._robust[k]
            robust += [-INF] * (index + 1 - self.starts[k] - self._taken[k] - len(robust))
        if ns is not None:
            self._reset(k)
            if order is not None:  # the values decided from now on follow this record's
                self._namespace[order].next = index + 1
            recovery = Recovery(self.spec.properties[k].formula, index, ns, why)
            self._recovering[k] = recovery
            self._resets_run[k].append(recovery)

    def _recover_run(self, index: int, ns: int) -> None:
        for k, recovery in list(self._recovering.items()):
            recovery.note(index, ns)
            if recovery.exact_from is not None:  # its tainted records are known
                del self._recovering[k]

    def _reset(self, k: int) -> None:
        """Property ``k``'s state as before the first record: fresh constants (deques, streams),
        closure variables back to their initial values. Whether it has started stays."""
        if k not in self._pristine:
            fresh = generate(self.spec, self._reads, hook=self._hook,
                             robustness=self.robustness)
            owned = self.program.owned[k]
            self._pristine[k] = {n: fresh.constants[n] for n in owned if n in fresh.constants}
        # copied together, the objects keep their links to one another (a stream's inputs)
        renewed = copy.deepcopy(self._pristine[k])
        self._namespace.update(renewed)
        self.program.constants.update(renewed)
        self._resets[k]()

    # ----------------------------------------------------------------- offline
    def run(self, records: Iterable[tuple[float, Mapping[str, object]]]) -> list[PropertyRun]:
        """Check a whole trace of ``(time, values)`` pairs; faster than ``step`` per record.

        A bad record raises :class:`SpecError` (read traces with :mod:`rasm.trace` to get
        line numbers). Returns each property's verdicts, in record order; where a property
        could not be evaluated, its value is False and ``errors`` says why.
        """
        self.feed(records)
        self.settle()
        runs = []
        for k, name in enumerate(self.names):
            _, values, errors, robustness = self.take_with_robustness(k)
            runs.append(PropertyRun(name, self.starts[k], values, errors,
                                    missing=self.missing(name),
                                    robustness=robustness if self.robustness else None))
        return runs

    def feed(self, records: Iterable[tuple[float, Mapping[str, object]]]) -> None:
        """Check the next records of a trace offline, as :meth:`run` does; call it again with
        the records that follow, then :meth:`settle`. :meth:`take` hands out the verdicts
        decided so far, so a trace can be checked part by part without holding it."""
        if self._finished:
            raise SpecError("this monitor has finished; compile a new one for a new trace")
        self.step = self._refuse  # a trace is checked offline or online, not both
        self._run(records)

    def settle(self) -> None:
        """The end of a trace fed offline: decide what is still open (``None``: inconclusive)."""
        if self._finished:
            raise SpecError("this monitor has finished; compile a new one for a new trace")
        self._finished = True
        self.step = self._refuse
        self._finish_run()
        if self.robustness:  # what is not final at the end is not known: None
            for k in range(len(self.names)):
                top = self.program.robust_tops[k]
                if top is not None and self.starts[k] is not None:
                    self._robust[k] += [None] * self._namespace[top].waiting()

    def verdicts_taken(self, k: int) -> int:
        """How many of property ``k``'s verdicts :meth:`take` has handed out."""
        return self._taken[k]

    def take(self, k: int) -> tuple[int, list, dict[int, str]]:
        """Property ``k``'s verdicts decided since the last take (offline): the index of the
        first, the values in record order, and why, by index, where it could not be evaluated.
        The monitor keeps none of them afterwards. (With robustness: only those whose
        robustness is known too, see :meth:`take_with_robustness`.)"""
        return self.take_with_robustness(k)[:3]

    def take_with_robustness(self, k: int) -> tuple[int, list, dict[int, str], list]:
        """:meth:`take`, and the robustness of each verdict taken (None where it is not final
        at the end of the trace; -inf where the property could not be evaluated). With
        robustness, a verdict waits for its robustness to be final (or the end)."""
        values, errors = self._values[k], self._errors[k]
        first = (self.starts[k] or 0) + self._taken[k]
        count = len(values)
        if self.robustness:
            count = min(count, len(self._robust[k]))
        end = first + count
        # a verdict that depends on records before a reset is an error; every record up to
        # the last one fed has been noted by its recovery, so that is known for these
        for recovery in self._resets_run[k]:
            for j in range(max(recovery.reset + 1, first), end):
                if recovery.tainted(j) and j not in errors:
                    values[j - first] = False
                    errors[j] = recovery.why
        taken = {j: errors.pop(j) for j in sorted(errors) if j < end}
        out = values[:count]
        del values[:count]  # in place: the generated code appends to this very list
        robust: list = []
        if self.robustness:
            given = self._robust[k]
            # (most are floats already: the call only for the others)
            robust = [v if v.__class__ is float or v is None else as_float(v)
                      for v in given[:count]]
            del given[:count]
            for j in taken:
                robust[j - first] = -INF
        self._taken[k] += len(out)
        return first, out, taken, robust

def _why(exc: Exception, index: int | None) -> str:
    where = f"at record {index}" if index is not None else "at the end of the trace"
    return f"evaluating the property raised {type(exc).__name__} {where}: {exc}"


@functools.lru_cache(maxsize=128)
def compile_source(source: str, origin: str) -> CodeType:
    """The code object of a generated monitor (cached: a code object is immutable, and every
    run of an application compiles the same property files again)."""
    return compile(source, f"<rasm monitor for {origin}>", "exec")


@functools.lru_cache(maxsize=128)
def _specification(text: str, source: str) -> Specification:
    # a Specification is immutable and a pure function of the text and its name; a file that
    # does not load raises each time (exceptions are not cached)
    return load_specification(text, source=source)


def compile_properties(text: str, *, source: str = "<text>", robustness: bool = False,
                       intervals: bool | str = False) -> Monitor:
    """Parse, check and compile a property file into a fresh :class:`Monitor`; ``robustness``:
    its verdicts carry their robustness too (SPEC §12); ``intervals``: a verdict decided
    before its robustness is final carries the interval known then (``"newest"``: only the
    newest verdict of each property in a step, at a cost independent of the bounds)."""
    if type(text) is str and type(source) is str:
        return Monitor(_specification(text, source), robustness=robustness, intervals=intervals)
    # says what is wrong with them
    return Monitor(load_specification(text, source=source), robustness=robustness,
                   intervals=intervals)
