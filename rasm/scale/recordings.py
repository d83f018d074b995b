"""One recording checked in one pass: a JSONL or MCAP trace, or a rosbag2 recording read with
an app's probes or a topic map (what ``rasm check`` does with each recording it is given)."""

from __future__ import annotations

import functools
from collections.abc import Callable, Collection, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from rasm.errors import RasmError
from rasm.properties.ast import Specification
from rasm.properties.check import CheckReport, check_file, check_stream
from rasm.properties.loader import cached_specification

__all__ = ["Job", "RecordingError", "check_recording", "is_recording", "is_trace", "spec_of"]


class RecordingError(RasmError):
    """A recording that cannot be checked as asked (its topics not mapped, a mapping for a
    trace that names its own signals)."""


@dataclass(frozen=True)
class Job:
    """What every recording of one ``rasm check`` is checked against, and how: small, so it
    travels to worker processes and cluster workers with each task."""

    props: str  # the property file's path (names it in reports)
    text: str  # its text (a worker need not see the file)
    app: str | None = None  # read rosbag2 recordings with this app's probes
    topics: str | None = None  # or with this topic map
    explain: bool = True  # explain the first violations (the text report shows them)
    named: bool = False  # keep only the violations a text report names
    robustness: bool = False  # each property's robustness too (one pass over each recording)


@functools.lru_cache(maxsize=16)
def _specification(text: str, source: str) -> Specification:
    return cached_specification(text, source)


def spec_of(job: Job) -> Specification:
    """The job's property file, loaded once per process (and read back from the user's cache
    folder while the file is unchanged)."""
    return _specification(job.text, job.props)


def is_recording(path: str) -> bool:
    """A rosbag2 recording (a bag folder, a .db3 file, an MCAP file that is no rasm trace)."""
    target = Path(path)
    if target.is_dir() or target.suffix == ".db3":
        return True
    if target.suffix != ".mcap":
        return False
    from rasm.trace_mcap import is_mcap_trace

    return not is_mcap_trace(target)


def is_trace(path: str) -> bool:
    """A JSONL trace (read line by line, and in parts by byte range)."""
    return not (Path(path).is_dir() or path.endswith((".mcap", ".db3")))


@dataclass
class Checked:
    """One recording's report, and what reading it left out (notes for standard error)."""

    recording: str
    report: CheckReport
    notes: list[str] = field(default_factory=list)


def _records(job: Job, path: str, signals: dict[str, str]) -> tuple[
    Callable[[], Iterable[tuple[float, dict]]], Callable[[], list[str]], Callable[[], list]
]:
    """How to read the records of a rasm MCAP trace, or of a rosbag2 recording with the probes
    of the job's app or topic map, each call reading them anew one by one; what the first whole
    reading left out (notes); and what could not be read (damage)."""
    if not is_recording(path):
        if job.app is not None or job.topics is not None:
            raise RecordingError(
                f"{path}: --app and --topics map a rosbag2 recording's topics to "
                "signals; a rasm trace names its signals itself"
            )
        from rasm.trace import parse_records
        from rasm.trace_mcap import McapTrace

        trace = McapTrace(path)

        def trace_records() -> Iterable[tuple[float, dict]]:
            return parse_records(trace, signals, source=path)

        return trace_records, list, lambda: trace.damage
    from rasm.platform.replay import recorded_trace

    if job.app is not None:
        from rasm.platform.manifest import load_manifest

        manifest = load_manifest(job.app)
        probes, store = manifest.probes, manifest.types
    elif job.topics is not None:
        from rasm.platform.manifest import load_topic_map
        from rasm.ros2 import TypeStore, recorded_types

        # a topic map may name the types the recording itself defines
        known = TypeStore()
        recorded_types(path, known)
        probes, store = load_topic_map(job.topics, known)
    else:
        raise RecordingError(
            f"{path} is a rosbag2 recording: say which topics give which signals, with "
            "--app APP (its probes) or --topics MAP.yaml (a 'probes:' list as in app.yaml)"
        )
    recorded = recorded_trace(path, probes, store, signals)
    return lambda: recorded, recorded.notes, lambda: recorded.damage


def check_recording(job: Job, path: str, *, names: Collection[str] | None = None,
                    verdicts: TextIO | None = None) -> Checked:
    """Check one recording in one pass (streamed: never held whole; explaining the first
    violations reads it once more). ``names``: only these properties."""
    spec = spec_of(job)
    if names is not None:
        from rasm.properties.shards import subspec

        spec = subspec(spec, names)
    if is_recording(path) or path.endswith(".mcap"):
        records, notes, damage = _records(job, path, spec.signals)
        report = check_stream(spec, records(), trace=path,
                              again=records if job.explain else None,
                              named=job.named, verdicts=verdicts,
                              robustness=job.robustness)
        report.note_damage(damage())
        return Checked(path, report, [f"{path}: {note}" for note in notes()])
    if job.app is not None or job.topics is not None:
        raise RecordingError(
            f"{path}: --app and --topics map a rosbag2 recording's topics to signals; a "
            "JSONL trace names its signals itself"
        )
    report = check_file(spec, path, explain_violations=job.explain, named=job.named,
                        verdicts=verdicts, robustness=job.robustness)
    return Checked(path, report)
