"""Offline checking (``rasm check``): a trace against a property file, and its reports.

Each property gets one of the five overall states of :mod:`rasm.properties.outcome` (satisfied,
violated, inconclusive, not judged, error). ``rasm check`` fails (exit 1) when some property is
violated, in error or not judged; satisfied and inconclusive alone exit 0.
"""

from __future__ import annotations

import gc
import json
import math
import shutil
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import islice
from typing import TextIO

from rasm.errors import SpecError
from rasm.losses import Damage
from rasm.properties.ast import Specification
from rasm.properties.codegen import checked_signals
from rasm.properties.explain import Explanation, explain
from rasm.properties.monitor import Monitor, PropertyRun
from rasm.properties.outcome import (
    ERROR,
    INCONCLUSIVE,
    NOT_JUDGED,
    SATISFIED,
    VIOLATED,
    PropertyOutcome,
)
from rasm.properties.printer import format_value
from rasm.properties.times import format_seconds, seconds_value
from rasm.properties.vacuity import Vacuity

__all__ = ["CheckReport", "PropertyReport", "check_file", "check_records", "check_stream",
           "format_json", "format_text", "format_verdicts", "json_object"]

# the order in which reports count the states: the failing ones first
STATE_ORDER = (VIOLATED, ERROR, NOT_JUDGED, INCONCLUSIVE, SATISFIED)
EXPLAINED = 5  # violations explained in full per property in the text report
SUMMARISED = 100  # further violations explained in one line each
NAMED = EXPLAINED + SUMMARISED + 20  # violations the text report names, explained or not
ERRORS_NAMED = 25  # records in error the text report names
CHUNK = 16_384  # records checked between two takes of the verdicts (check_stream)


@dataclass
class PropertyReport:
    """One property over one trace: its verdicts counted in ``outcome``, its violations and
    errors by record.

    ``violations`` lists every violation, or, from a streamed check of the text report, the
    ones it names (``outcome.violations`` counts them all); ``first_errors`` the first records
    in error, with their times and why. ``run`` holds every verdict (None when streamed).
    """

    name: str
    location: str
    outcome: PropertyOutcome
    violations: list[tuple[int, float]]  # (index, time) of each violation (errors apart)
    run: PropertyRun | None
    first_errors: list[tuple[int, float, str]] = field(default_factory=list)
    explanations: list[Explanation] = field(default_factory=list)
    # its verdict depended on records a damaged recording lost (CheckReport.note_damage)
    lost_data: bool = False
    # with robustness (SPEC §12): the minimum over the judged records whose robustness is
    # final (None: none is); ``robust`` says whether it was asked for
    robustness: float | None = None
    robust: bool = False

    @classmethod
    def of(cls, name: str, location: str, run: PropertyRun, times: Sequence[float]):
        """The report of one property's run over a trace whose record times are ``times``."""
        start = run.start or 0
        errors = run.errors
        violated = [
            start + k for k, v in enumerate(run.values) if v is False and start + k not in errors
        ]
        outcome = PropertyOutcome(
            name,
            judged=len(run.values),
            violations=len(violated),
            errors=len(errors),
            inconclusive=sum(1 for v in run.values if v is None),
            first_error=errors[min(errors)] if errors else None,
            missing=tuple(run.missing) if run.start is None else (),
        )
        first_errors = [(i, times[i], errors[i]) for i in sorted(errors)[:ERRORS_NAMED]]
        return cls(name, location, outcome, [(i, times[i]) for i in violated], run, first_errors)

    @property
    def verdict(self) -> str:
        """The overall state: satisfied, violated, inconclusive, not judged or error. Never
        false on what was read, but judged on a damaged recording: inconclusive."""
        state = self.outcome.state
        return INCONCLUSIVE if self.lost_data and state == SATISFIED else state

    @property
    def passed(self) -> bool:
        return self.outcome.passed

    @property
    def judged(self) -> int:
        return self.outcome.judged

    @property
    def inconclusive(self) -> int:
        return self.outcome.inconclusive

    @property
    def errors(self) -> dict[int, str]:
        """Record index -> why the property could not be evaluated there (the first ones only
        when the check was streamed)."""
        if self.run is not None:
            return self.run.errors
        return {index: why for index, _, why in self.first_errors}

    @property
    def missing(self) -> tuple[str, ...]:
        """The signals that never had a value (when the property was never judged)."""
        return self.outcome.missing

    def __repr__(self) -> str:
        # the run holds one verdict per record: thousands of them are no help in a REPL
        counts = f"{self.outcome.violations} violations, " if self.outcome.violations else ""
        return (f"<PropertyReport {self.name}: {self.verdict}, {counts}"
                f"{self.judged} records judged>")


@dataclass
class CheckReport:
    """Every property of a file over one trace."""

    source: str
    trace: str
    records: int
    properties: list[PropertyReport]
    times: Sequence[float] = ()
    damage: list[Damage] = field(default_factory=list)  # what the recording lost

    @property
    def violated(self) -> bool:
        return any(p.verdict == VIOLATED for p in self.properties)

    def note_damage(self, damage: Sequence[Damage]) -> None:
        """The recording lost ``damage``: every verdict that passed depended on what was lost
        (a property is judged at every record), so none of them is "satisfied"."""
        self.damage = list(damage)
        if self.damage:
            for p in self.properties:
                p.lost_data = p.passed

    @property
    def depends_on_damage(self) -> bool:
        """Some verdict that passed depended on what a damaged recording lost."""
        return any(p.lost_data for p in self.properties)

    @property
    def failed(self) -> list[PropertyReport]:
        """The properties that do not pass: violated, in error or not judged."""
        return [p for p in self.properties if not p.passed]

    def __repr__(self) -> str:
        verdicts = ", ".join(f"{p.name}: {p.verdict}" for p in self.properties)
        return (f"<CheckReport {self.source} over {self.records} records of {self.trace}: "
                f"{_tally_line(self)} ({verdicts})>")


def check_records(
    spec: Specification,
    records: Sequence[tuple[float, dict]],
    *,
    trace: str = "<trace>",
    explain_violations: bool = True,
) -> CheckReport:
    """Run every property of ``spec`` over ``records`` (already read and checked)."""
    runs = Monitor(spec).run(records)
    vacuity = Vacuity(spec)
    vacuity.feed(records)
    vacuity.settle()
    times = [t for t, _ in records]
    reports = []
    for prop, run in zip(spec.properties, runs, strict=True):
        report = PropertyReport.of(prop.name, str(prop.location), run, times)
        report.outcome.vacuous = vacuity.vacuous(prop.name)
        reports.append(report)
    if explain_violations:
        limit = EXPLAINED + SUMMARISED
        wanted = {r.name: [i for i, _ in r.violations[:limit]] for r in reports if r.violations}
        if wanted:
            explanations = explain(spec, records, wanted)
            for report in reports:
                report.explanations = [
                    explanations[(report.name, i)] for i in wanted.get(report.name, [])
                ]
    return CheckReport(spec.source, trace, len(records), reports, times)


class _Times:
    """The times of the records whose verdicts some property has still to give."""

    def __init__(self) -> None:
        self.held: list[float] = []
        self.first = 0  # the index of held[0]

    def __getitem__(self, index: int) -> float:
        return self.held[index - self.first]

    def forget_before(self, index: int) -> None:
        del self.held[: index - self.first]
        self.first = max(self.first, index)


class _Tally:
    """One property's verdicts counted as the monitor hands them out (see :meth:`add`)."""

    def __init__(self, name: str, named: int | None, verdicts: TextIO | None) -> None:
        self.outcome = PropertyOutcome(name)
        self.named = named  # violations kept: None all, else the first ones
        self.violations: list[tuple[int, float]] = []
        self.first_errors: list[tuple[int, float, str]] = []
        self.verdicts = verdicts
        self.json_name = json.dumps(name)
        self.robustness: float | None = None  # the minimum so far (robustness asked for)

    def add(self, first: int, values: list, errors: dict[int, str], times: _Times,
            robustness: list | None = None) -> None:
        """Count the verdicts of records ``first``, ``first + 1``, … (errors by index), and
        their ``robustness`` where asked for."""
        if robustness:
            known = [r for r in robustness if r is not None]
            if known:
                low = min(known)
                self.robustness = low if self.robustness is None else min(self.robustness, low)
        outcome = self.outcome
        outcome.judged += len(values)
        outcome.inconclusive += values.count(None)
        violated = values.count(False) - len(errors)  # an error's value is False too
        outcome.violations += violated
        if violated and (self.named is None or len(self.violations) < self.named):
            found = (first + k for k, v in enumerate(values) if v is False)
            found = (j for j in found if j not in errors)
            room = None if self.named is None else self.named - len(self.violations)
            self.violations.extend((j, times[j]) for j in islice(found, room))
        if errors:
            outcome.errors += len(errors)
            if outcome.first_error is None:
                outcome.first_error = errors[min(errors)]
            room = ERRORS_NAMED - len(self.first_errors)
            self.first_errors.extend((j, times[j], errors[j]) for j in sorted(errors)[:room])
        if self.verdicts is not None:
            name, write = self.json_name, self.verdicts.write
            if robustness is None:
                for k, value in enumerate(values):
                    j = first + k
                    write(_verdict_line(name, j, times[j], value, errors.get(j)))
            else:
                for k, value in enumerate(values):
                    j = first + k
                    write(_verdict_line(name, j, times[j], value, errors.get(j),
                                        robustness[k], True))


def check_stream(
    spec: Specification,
    records: Iterable[tuple[float, Mapping[str, object]]],
    *,
    trace: str = "<trace>",
    again: Callable[[], Iterable[tuple[float, Mapping[str, object]]]] | None = None,
    named: bool = False,
    verdicts: TextIO | None = None,
    chunk: int = CHUNK,
    robustness: bool = False,
) -> CheckReport:
    """Check every property of ``spec`` on ``records`` read one by one, as :func:`check_records`
    does on a list, holding no more of the trace than the properties' windows need.

    ``again`` gives the records once more, to explain the first violations (from the start of
    the trace to a little past the last one explained); without it nothing is explained.
    ``named``: keep only the violations the text report names (``outcome`` counts them all).
    ``verdicts``: write every verdict there, as :func:`format_verdicts` would. ``chunk``: how
    many records are checked between two counts of the verdicts. ``robustness``: each
    property's report and verdict lines carry its robustness too (SPEC §12).
    """
    monitor = Monitor(spec, robustness=robustness)
    vacuity = Vacuity(spec)
    spools: list = []
    if verdicts is not None:
        # the lines go out property by property, and only for a trace read to its end without
        # a malformed record: until then they wait in temporary files
        import tempfile

        spools = [tempfile.TemporaryFile("w+", encoding="utf-8") for _ in spec.properties]
    outputs = spools or [None] * len(spec.properties)
    limit = NAMED if named else None
    tallies = [_Tally(p.name, limit, out) for p, out in zip(spec.properties, outputs, strict=True)]
    times = _Times()
    count = 0

    def take() -> None:
        for k, tally in enumerate(tallies):
            if robustness:
                first, values, errors, robust = monitor.take_with_robustness(k)
                tally.add(first, values, errors, times, robust)
            else:
                first, values, errors = monitor.take(k)
                tally.add(first, values, errors, times)
        # a property not started yet gives its first verdict at a record still to come
        owed = [s + monitor.verdicts_taken(k) for k, s in enumerate(monitor.starts)
                if s is not None]
        times.forget_before(min(owed, default=count))

    # The records come and go by the million, and each one's tuple wakes the garbage
    # collector now and then: its full passes need not rescan every object that was there
    # before the check (the program, its libraries), so those are set aside meanwhile (unless
    # the caller set some aside itself: then its choice stands).
    ours = gc.get_freeze_count() == 0
    if ours:
        gc.freeze()
    try:
        records = iter(records)
        while part := list(islice(records, chunk)):
            monitor.feed(part)
            vacuity.feed(part)
            times.held.extend([t for t, _ in part])
            count += len(part)
            take()
        monitor.settle()
        vacuity.settle()
        take()
        for spool in spools:
            spool.seek(0)
            shutil.copyfileobj(spool, verdicts)
    finally:
        if ours:
            gc.unfreeze()
        for spool in spools:
            spool.close()
    reports = []
    for k, (prop, tally) in enumerate(zip(spec.properties, tallies, strict=True)):
        if monitor.starts[k] is None:
            tally.outcome.missing = monitor.missing(prop.name)
        tally.outcome.vacuous = vacuity.vacuous(prop.name)
        reports.append(PropertyReport(prop.name, str(prop.location), tally.outcome,
                                      tally.violations, None, tally.first_errors,
                                      robustness=tally.robustness, robust=robustness))
    if again is not None:
        _explain_first(spec, reports, again)
    return CheckReport(spec.source, trace, count, reports)


def check_file(
    spec: Specification,
    path: str,
    *,
    explain_violations: bool = True,
    named: bool = False,
    verdicts: TextIO | None = None,
    chunk: int = CHUNK,
    robustness: bool = False,
) -> CheckReport:
    """``rasm check``: :func:`check_stream` of the JSONL trace ``path``, read line by line.

    The lines are read by :func:`rasm.trace.scan_records`, whose records the monitor checks
    as it goes (no value is checked twice). At a malformed record the check stops and the
    trace is read again by :func:`rasm.trace.read_records`, whose :class:`SourceErrors` name
    every malformed record, each at its line.
    """
    from rasm.trace import MalformedTrace, read_records, scan_records

    checked = set(checked_signals(spec))
    unchecked = {name: kind for name, kind in spec.signals.items() if name not in checked}
    try:
        with open(path, encoding="utf-8") as handle:
            return check_stream(
                spec,
                scan_records(handle, unchecked, source=path),
                trace=path,
                again=(lambda: read_records(path, spec.signals)) if explain_violations else None,
                named=named,
                verdicts=verdicts,
                chunk=chunk,
                robustness=robustness,
            )
    except (MalformedTrace, SpecError, UnicodeDecodeError) as problem:
        for _ in read_records(path, spec.signals):  # raises SourceErrors: every bad record
            pass
        # the full reader found nothing wrong: the fast one must not pass for it (fail closed)
        raise SpecError(f"{path}: {problem}") from problem


def _explain_first(spec: Specification, reports: list[PropertyReport],
                   again: Callable[[], Iterable[tuple[float, Mapping[str, object]]]]) -> None:
    """Explain each property's first violations from the trace read again, as far as the
    explanations need it, holding only the records they may still look at
    (:class:`~rasm.properties.explain.Explainer`)."""
    limit = EXPLAINED + SUMMARISED
    wanted = {r.name: [i for i, _ in r.violations[:limit]] for r in reports if r.violations}
    if not wanted:
        return
    explanations = explain(spec, again(), wanted)
    for report in reports:
        report.explanations = [explanations[(report.name, i)] for i in wanted.get(report.name, [])]


def format_json(report: CheckReport) -> str:
    """``--format json``: one JSON object; ``verdict`` is one of the five states, ``errors``
    counts the records where the property could not be evaluated (``first_error`` says why),
    ``missing`` names the signals a property that was never judged waits for, ``vacuous`` the
    left sides of its ``->`` that never held on a judged record."""
    return json.dumps(json_object(report)) + "\n"


def json_object(report: CheckReport) -> dict:
    """The object :func:`format_json` prints."""
    out: dict = {"records": report.records}
    if report.damage:
        out["damage"] = [_damage_json(d) for d in report.damage]
    return {
        **out,
        "properties": [
            {
                "name": p.name,
                "verdict": p.verdict,
                "violations": [
                    {"index": i, "time": seconds_value(t)} for i, t in p.violations
                ],
                "judged": p.judged,
                "inconclusive": p.inconclusive,
                "errors": p.outcome.errors,
                "first_error": p.outcome.first_error,
                "missing": list(p.missing),
                "vacuous": [u.text for u in p.outcome.vacuous],
                **({"lost_data": True} if p.lost_data else {}),
                **({"robustness": _json_number(p.robustness)} if p.robust else {}),
            }
            for p in report.properties
        ],
    }


def _damage_json(d: Damage) -> dict:
    """One damaged part, for ``--format json``: times in seconds (None where not known)."""
    return {
        "file": d.file, "where": d.where, "reason": d.reason, "bytes": d.lost_bytes,
        "messages": d.messages,
        "from": d.start_ns / 1e9 if d.start_ns is not None else None,
        "to": d.end_ns / 1e9 if d.end_ns is not None else None,
        "topics": list(d.topics) if d.topics is not None else None,
    }


def format_verdicts(report: CheckReport) -> str:
    """``--verdicts``: JSONL, one line per judged record and property (``error`` on a record where
    the property could not be evaluated)."""
    lines = []
    for p in report.properties:
        name = json.dumps(p.name)
        start = p.run.start or 0
        errors = p.run.errors
        for k, value in enumerate(p.run.values):
            index = start + k
            lines.append(_verdict_line(name, index, report.times[index], value, errors.get(index)))
    return "".join(lines)


_VALUES = {True: "true", False: "false", None: "null"}


def _verdict_line(name: str, index: int, time: float, value: bool | None,
                  error: str | None, robustness: float | None = None,
                  robust: bool = False) -> str:
    """One line of ``--verdicts``, as ``json.dumps`` writes the record; ``name`` is JSON
    already. A time is written as a plain int or float (:func:`seconds_value`), whose JSON is
    its ``repr``; ``robust``: the line carries the ``robustness`` (null: not final)."""
    tail = "}\n" if error is None else f", \"error\": {json.dumps(error)}}}\n"
    if robust:
        tail = f', "robustness": {json.dumps(_json_number(robustness))}' + tail
    return (f'{{"property": {name}, "index": {index}, "time": {seconds_value(time)!r}, '
            f'"value": {_VALUES[value]}{tail}')


def _json_number(value: float | None) -> float | str | None:
    """A robustness in JSON: a number, or "inf" / "-inf" (JSON has no infinities)."""
    if value is None or math.isfinite(value):
        return value
    return "inf" if value > 0 else "-inf"


def _one_line(e: Explanation) -> str:
    # the innermost reasons (the most indented lines, with the line they hang from) say the
    # most in the least space: "velocity <= 0.5 failed: velocity = 0.7"
    def depth(line: str) -> int:
        return len(line) - len(line.lstrip())

    deepest = max((depth(line) for line in e.lines), default=0)
    groups: list[list[str]] = []
    parent = None
    for line in e.lines:
        if depth(line) < deepest:
            parent = line.strip()
        elif groups and groups[-1][0] == parent:
            groups[-1].append(line.strip())
        else:
            groups.append([parent, line.strip()])
    parts = [
        (f"{g[0].rstrip(':')}: " if g[0] else "") + ", ".join(g[1:]) for g in groups
    ]
    text = "; ".join(parts)
    return text if len(text) <= 160 else text[:157] + "…"


def format_text(report: CheckReport) -> str:
    """A human report: each property's state; each violation explained (the first few), each
    error and each signal a property never saw named."""
    out = [f"{report.source}: {len(report.properties)} properties over {report.records} "
           f"records of {report.trace}"]
    for p in report.properties:
        state = p.verdict
        if state == VIOLATED:
            first_index, first_time = p.violations[0]
            out.append(
                f"  {p.name}: VIOLATED at {p.outcome.violations} of {p.judged} judged records "
                f"(first: record {first_index}, time {format_seconds(first_time)})  "
                f"[{p.location}]"
            )
            for e in p.explanations[:EXPLAINED]:
                out.append(f"    at record {e.index} (time {format_seconds(e.time)}):")
                out.extend("      " + line for line in e.lines)
                values = ", ".join(f"{k} = {format_value(v)}" for k, v in e.signals.items())
                if values:
                    out.append(f"      signals: {values}")
            for e in p.explanations[EXPLAINED:]:
                out.append(
                    f"    at record {e.index} (time {format_seconds(e.time)}): {_one_line(e)}"
                )
            hidden = p.outcome.violations - len(p.explanations)
            if hidden > 0:
                more = ", ".join(f"{i}" for i, _ in p.violations[len(p.explanations):][:20])
                tail = ", …" if hidden > 20 else ""
                out.append(f"    … and {hidden} more violations (records {more}{tail})")
            if p.outcome.errors:
                out.extend(_errors(p))
        elif state == ERROR:
            out.append(f"  {p.name}: ERROR at {p.outcome.errors} of {p.judged} judged records: the "
                       f"checker could not evaluate it there  [{p.location}]")
            out.extend(_errors(p))
        elif state == NOT_JUDGED:
            why = (f"no value for {', '.join(p.missing)} in any record" if p.missing
                   else "no record reached it")
            out.append(f"  {p.name}: NOT JUDGED: {why}  [{p.location}]")
        elif state == INCONCLUSIVE and p.lost_data and not p.inconclusive:
            out.append(f"  {p.name}: inconclusive: never false on the {p.judged} records judged, "
                       f"but the recording lost data it depends on  [{p.location}]")
        elif state == INCONCLUSIVE:
            out.append(f"  {p.name}: inconclusive ({p.inconclusive} of {p.judged} records "
                       f"depend on records after the end of the trace)  [{p.location}]")
        else:
            if p.outcome.vacuous:
                out.append(f"  {p.name}: {p.outcome.word}, {p.judged} records judged  "
                           f"[{p.location}]")
            else:
                out.append(f"  {p.name}: satisfied ({p.judged} records judged)")
        if p.robust:
            shown = "none final" if p.robustness is None else f"{p.robustness:.6g}"
            out.append(f"    robustness (minimum over the judged records): {shown}")
    if report.damage:
        out.append(f"damaged: {report.trace} lost data:")
        out.extend(f"  {d.describe()}" for d in report.damage)
    out.append(_tally_line(report))
    return "\n".join(out) + "\n"


def _errors(p: PropertyReport) -> list[str]:
    """The first records where ``p`` could not be evaluated, and why."""
    first = p.first_errors
    out = [f"    in error at record {i} (time {format_seconds(t)}): {why}"
           for i, t, why in first[:5]]
    count = p.outcome.errors
    if count > 5:
        more = ", ".join(str(i) for i, _, _ in first[5:ERRORS_NAMED])
        tail = ", …" if count > ERRORS_NAMED else ""
        out.append(f"    … and in error at {count - 5} more records ({more}{tail})")
    return out


def _tally_line(report: CheckReport) -> str:
    """``1 of 3 properties fail: 1 not judged, 2 satisfied``."""
    counts = {state: 0 for state in STATE_ORDER}
    for p in report.properties:
        counts[p.verdict] += 1
    vacuous = sum(1 for p in report.properties if p.verdict == SATISFIED and p.outcome.vacuous)
    states = ", ".join(
        f"{n} {state}" + (f" ({vacuous} vacuously)" if state == SATISFIED and vacuous else "")
        for state, n in counts.items() if n
    )
    lost = sum(1 for p in report.properties if p.lost_data)
    damaged = (f"; the recording is damaged: {lost} verdict"
               f"{'s depend' if lost != 1 else ' depends'} on what it lost" if lost else "")
    return f"{len(report.failed)} of {len(report.properties)} properties fail" + (
        f": {states}" if states else ""
    ) + damaged
