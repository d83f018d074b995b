"""The tasks a worker runs, each on one recording or one part of it, found by its path.

A task returns its result, or :class:`Failed` with the messages ``rasm`` prints when the
recording cannot be checked (a malformed record, a file that cannot be read): such a failure
is the recording's, and trying again elsewhere would not change it. Every other exception is
raised (a lost worker is the engine's to retry).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass

from rasm.errors import RasmError, SourceErrors, printable
from rasm.extras import missing_extra
from rasm.properties.codegen import checked_signals
from rasm.properties.explain import Explanation
from rasm.properties.shards import PartResult, check_part, explain_part, subspec
from rasm.scale.recordings import Checked, Job, check_recording, spec_of

__all__ = ["Failed", "explain_task", "part_task", "whole_task"]


@dataclass(frozen=True)
class Failed:
    """Why a recording could not be checked: one line per problem, as ``rasm`` prints them."""

    messages: tuple[str, ...]


def failure(exc: BaseException) -> Failed:
    if isinstance(exc, ModuleNotFoundError):  # a package of an extra (rasm[ros2]) not installed
        missing = missing_extra(exc, "rasm check")
        if missing is not None:
            return Failed((printable(str(missing)),))
    if isinstance(exc, SourceErrors):
        return Failed(tuple(printable(str(error)) for error in exc.errors))
    return Failed((printable(str(exc)),))


def whole_task(job: Job, path: str, names: Collection[str] | None = None) -> Checked | Failed:
    """The recording checked in one pass (only the properties ``names``, if given)."""
    try:
        return check_recording(job, path, names=names)
    except (SourceErrors, RasmError, OSError, ModuleNotFoundError) as exc:
        return failure(exc)


def _part(job: Job, path: str, start: int, end: int, names: Collection[str]):
    from rasm.trace_parts import JsonlPart

    spec = subspec(spec_of(job), names)
    checked = set(checked_signals(spec))
    unchecked = {n: k for n, k in spec.signals.items() if n not in checked}
    return spec, JsonlPart(path, start, end, unchecked=unchecked)


def part_task(job: Job, path: str, start: int, end: int,
              names: Collection[str]) -> PartResult | Failed:
    """The properties ``names`` (bounded) on the lines of a JSONL trace starting in bytes
    ``[start, end)``. A failure here sends the whole recording to be checked in one pass,
    which says what is wrong with it."""
    try:
        spec, part = _part(job, path, start, end, names)
        with part:
            return check_part(spec, part, named=job.named)
    except (SourceErrors, RasmError, OSError, ValueError, ModuleNotFoundError) as exc:
        return failure(exc)


def explain_task(job: Job, path: str, start: int, end: int, names: Collection[str],
                 wanted: Mapping[str, list[int]],
                 offset: int) -> dict[tuple[str, int], Explanation] | Failed:
    """The explanations of the violations ``wanted`` (record indices of the whole trace) in the
    part of a JSONL trace in bytes ``[start, end)``, whose first record is ``offset``."""
    try:
        spec, part = _part(job, path, start, end, names)
        with part:
            return explain_part(spec, part, wanted, offset)
    except (SourceErrors, RasmError, OSError, ValueError) as exc:
        return failure(exc)
