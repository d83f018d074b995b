"""``assert_properties(props, trace)``: a property file must hold on a trace, or the test fails
with each violation explained as ``rasm check`` explains it, and the trace saved to replay it."""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from rasm.errors import RasmError
from rasm.properties.ast import Specification
from rasm.properties.check import CheckReport, PropertyReport, check_records, format_text
from rasm.properties.outcome import ERROR, NOT_JUDGED, VIOLATED
from rasm.testing._props import property_file
from rasm.testing.failures import is_final_example, save_jsonl
from rasm.trace import parse_trace

__all__ = ["PropertyViolation", "assert_properties", "check_trace"]


class PropertyViolation(RasmError, AssertionError):
    """A property was violated, in error or not judged on a trace; ``report`` is the full
    check report."""

    def __init__(self, message: str, report: CheckReport, saved: Path | None) -> None:
        super().__init__(message)
        self.report = report
        self.saved = saved


def _records(trace: Iterable[Mapping[str, Any]] | str | Path) -> tuple[list[Any], str]:
    """The trace's records and its name; a record that is not a JSON object is left for
    :func:`parse_trace` to report at its place."""
    if isinstance(trace, str | Path):
        path = Path(trace)
        if not path.is_file():
            raise FileNotFoundError(
                f"no trace file {path} (pass a JSONL path, a rasm.testing.Trace or a list of "
                "records like {'time': 0.0, 'velocity': 0.3})"
            )
        text = path.read_text(encoding="utf-8")
        parse_trace(text.splitlines(), source=str(path))  # bad JSON: file:line:col, not a crash
        return [json.loads(line) for line in text.splitlines() if line.strip()], str(path)
    if isinstance(trace, Mapping) or not isinstance(trace, Iterable):
        raise TypeError(
            f"a trace is a list of records like {{'time': 0.0, 'velocity': 0.3}}, a "
            f"rasm.testing.Trace or a JSONL path, not {type(trace).__name__}"
        )
    return [dict(r) if isinstance(r, Mapping) else r for r in trace], "<trace>"


def check_trace(
    props: str | Path | Specification,
    trace: Iterable[Mapping[str, Any]] | str | Path,
    *,
    explain: bool = True,
) -> CheckReport:
    """Check ``props`` on ``trace`` (records, a :class:`~rasm.testing.Trace`, or a JSONL path),
    exactly as ``rasm check`` does; malformed records raise :class:`rasm.errors.SourceErrors`."""
    file = property_file(props)
    records, name = _records(trace)
    lines = [json.dumps(r) for r in records]
    parsed = parse_trace(lines, file.spec.signals, source=name)
    return check_records(file.spec, parsed, trace=name, explain_violations=explain)


def assert_properties(
    props: str | Path | Specification,
    trace: Iterable[Mapping[str, Any]] | str | Path,
    *,
    only: Iterable[str] | None = None,
) -> CheckReport:
    """Fail (``PropertyViolation``, an ``AssertionError``) if a property of ``props`` is violated,
    in error or not judged on ``trace``; ``only`` restricts the verdict to the named properties.

    The message is ``rasm check``'s report, each violation explained. The trace is saved under
    ``.rasm/failures/`` (inside hypothesis: for the reported example only) and the message gives
    the ``rasm check`` command that reproduces the report. Returns the report when all hold.
    """
    file = property_file(props)
    records, _ = _records(trace)
    report = check_trace(file, records)
    names = {p.name for p in report.properties}
    if isinstance(only, str):  # one name, not its letters
        only = [only]
    wanted = set(only) if only is not None else names
    unknown = sorted(wanted - names)
    if unknown:
        raise ValueError(
            f"{file.source} has no property {unknown[0]!r}; its properties: "
            f"{', '.join(sorted(names))}"
        )
    failed = [p for p in report.properties if not p.passed and p.name in wanted]
    if not failed:
        return report
    text = format_text(report)
    saved = None
    if is_final_example():
        saved = save_jsonl(file.stem, records)
        props_arg = file.source if file.source != "<text>" else "PROPS.rv"
        text += f"trace saved: {saved}\nreproduce: rasm check {props_arg} {saved}\n"
    raise PropertyViolation(f"{_headline(failed)}\n{text}", report, saved)


def _headline(failed: list[PropertyReport]) -> str:
    """``violated: a, b; not judged: c (no value for x)``: the failing properties by state."""
    parts = []
    for state in (VIOLATED, ERROR, NOT_JUDGED):
        names = []
        for p in failed:
            if p.verdict != state:
                continue
            if state == NOT_JUDGED:
                why = f"no value for {', '.join(p.missing)}" if p.missing else "no record"
                names.append(f"{p.name} ({why})")
            elif state == ERROR:
                names.append(f"{p.name} ({p.outcome.first_error})")
            else:
                names.append(p.name)
        if names:
            parts.append(f"{state}: {', '.join(names)}")
    return "; ".join(parts)
