"""The online monitor of SPEC §6: ``compile(text)``, ``Monitor.step``, ``Monitor.finish``."""

from __future__ import annotations

import builtins
import functools
import numbers
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from types import CodeType
from typing import NamedTuple

from rasm.errors import SpecError
from rasm.spec.ast import Specification
from rasm.spec.codegen import UNSET, generate
from rasm.spec.loader import load_specification

__all__ = ["Monitor", "PropertyRun", "Rejection", "Verdict", "compile"]

NUMERIC = frozenset((int, float))
SCALAR = frozenset((int, float, str, bool))
_WANT = {
    "float": "a number",
    "int": "an integer",
    "bool": "true or false",
    "str": "a string",
    "any": "a number, string or boolean",
}


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


BAD = type("Bad", (), {"__repr__": lambda self: "<bad value>"})()


def coerce(value, kind: str):
    """The slow path of the generated checks: convert numpy-like scalars, refuse the rest.

    Returns the plain Python value, or :data:`BAD`.
    """
    if isinstance(value, bool) or type(value).__name__ in ("bool_", "bool8"):
        return bool(value) if kind in ("bool", "any") else BAD
    if kind == "bool":
        return BAD
    if isinstance(value, numbers.Integral):
        return int(value) if kind in ("int", "float", "any") else BAD
    if isinstance(value, numbers.Real):
        return float(value) if kind in ("float", "any") else BAD
    if isinstance(value, str):
        return str(value) if kind in ("str", "any") else BAD
    return BAD


def describe_rejection(time, record, signal: str | None, kind: str) -> str:
    """Why a record was rejected, in words (shared with the trace reader)."""
    if kind == "record":
        return f"a record must map signal names to values, not {type(record).__name__}"
    if kind == "time":
        return f"'time' must be a number, not {time!r}"
    if kind == "backwards":
        return f"time {time!r} goes back in time"
    value = record.get(signal)
    return f"{signal!r} must be {_WANT[kind]}, not {json_repr(value)}"


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
    """

    def __init__(self, spec: Specification, *, reads: list[tuple[str, ...]] | None = None) -> None:
        self.spec = spec
        self.names = [p.name for p in spec.properties]
        self.program = generate(spec, reads)
        self.starts: list[int | None] = [None] * len(self.names)
        self.rejected: list[Rejection] = []
        self._values: list[list] = [[] for _ in self.names]
        self._finished = False
        namespace = dict(self.program.constants)
        namespace.update(
            STATE=self.program.state,
            Verdict=Verdict,
            NAMES=self.names,
            STARTS=self.starts,
            VALUES=self._values,
            REJECT_STEP=self._reject_step,
            REJECT_INTO=self._reject_into,
            REJECT_RUN=self._reject_run,
            NUMERIC=NUMERIC,
            SCALAR=SCALAR,
            UNSET=UNSET,
            COERCE=coerce,
            BAD=BAD,
        )
        code = compile_source(self.program.source, spec.source)
        exec(code, namespace)
        functions = namespace["factory"]()
        (
            self._step,
            self._tally,
            self._tally_into,
            self._run,
            self._finish,
            self._finish_run,
            self._held,
        ) = functions
        # the generated functions themselves, not methods around them: one call less per record
        self.step = self._step
        self.tally = self._tally
        self.tally_into = self._tally_into

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

    def tally(self, time: float, values: Mapping[str, object]) -> list[tuple[str, bool | None]]:
        """:meth:`step` giving each verdict as a ``(property, value)`` pair: for a caller that
        keeps only those (cheaper than verdicts). Feeds the same monitor: use one or the other
        per record. (Each monitor replaces this method by its generated tally function.)
        """
        return self._tally(time, values)

    def tally_into(
        self,
        time: float,
        values: Mapping[str, object],
        latest: dict[str, bool | None],
        unusual: Callable[[str, bool | None], object],
    ) -> None:
        """:meth:`tally` keeping the pairs itself: ``latest[property] = value`` for each, then
        ``unusual(property, value)`` for each value that is not True, in :meth:`tally`'s order.
        Nothing is handed over for a refused record, nor for one whose evaluation raised (the
        exception propagates, as from :meth:`tally`). For a caller that keeps only the latest
        value of each property and looks closer at the rest (the Trustworthiness Checker):
        no pair is made for the common True verdict. (Each monitor replaces this method by its
        generated function.)
        """
        return self._tally_into(time, values, latest, unusual)

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

    def _reject_into(self, index, time, record, signal, kind) -> None:
        self._reject_step(index, time, record, signal, kind)

    def _reject_run(self, index, time, record, signal, kind):
        raise SpecError(f"record {index}: {describe_rejection(time, record, signal, kind)}")

    def finish(self) -> list[Verdict]:
        """End of the trace: settle what is still open (``None``: inconclusive)."""
        if self._finished:
            return []
        self._finished = True
        self.step = self.tally = self.tally_into = self._refuse
        return self._finish()

    # ----------------------------------------------------------------- offline
    def run(self, records: Iterable[tuple[float, Mapping[str, object]]]) -> list[PropertyRun]:
        """Check a whole trace of ``(time, values)`` pairs; faster than ``step`` per record.

        A bad record raises :class:`SpecError` (read traces with :mod:`rasm.spec.trace` to get
        line numbers). Returns each property's verdicts, in record order.
        """
        if self._finished:
            raise SpecError("this monitor has finished; compile a new one for a new trace")
        self._run(records)
        self._finished = True
        self.step = self.tally = self.tally_into = self._refuse
        self._finish_run()
        return [
            PropertyRun(name, self.starts[k], self._values[k], missing=self.missing(name))
            for k, name in enumerate(self.names)
        ]


@functools.lru_cache(maxsize=128)
def compile_source(source: str, origin: str) -> CodeType:
    """The code object of a generated monitor (cached: a code object is immutable, and every
    run of an application compiles the same property files again)."""
    return builtins.compile(source, f"<rasm monitor for {origin}>", "exec")


@functools.lru_cache(maxsize=128)
def _specification(text: str, source: str) -> Specification:
    # a Specification is immutable and a pure function of the text and its name; a file that
    # does not load raises each time (exceptions are not cached)
    return load_specification(text, source=source)


def compile(text: str, *, source: str = "<text>") -> Monitor:  # noqa: A001 - SPEC §6 name
    """Parse, check and compile a property file into a fresh :class:`Monitor`."""
    if type(text) is str and type(source) is str:
        return Monitor(_specification(text, source))
    return Monitor(load_specification(text, source=source))  # says what is wrong with them
