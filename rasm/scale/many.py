"""Many recordings, and large ones, checked in parallel: ``rasm check PROPS RECORDING...``.

Each recording is a task, checked in one pass — except a large JSONL trace, which is cut into
parts by byte range (:mod:`rasm.trace_parts`), each part checked with the records its properties
reach around it (:mod:`rasm.properties.shards`); its properties with an unbounded past are
checked in one pass beside them. When every part of a trace is in, their results are merged
into the report of one pass, and the violations a text report explains are explained by the
parts that hold them (a second task each, once the records before each part are counted).

The tasks run on an :class:`~rasm.scale.engines.Engine`; a task whose worker died is sent again
(:data:`ATTEMPTS` times in all). A recording that cannot be checked (a malformed record, a file
that cannot be read, a worker that died every time) is reported with why, by name; the others
are checked all the same.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rasm.properties.check import CheckReport
from rasm.properties.shards import (
    PartResult,
    merge_parts,
    splittable,
    subspec,
    wanted_explanations,
)
from rasm.scale.engines import Engine, InProcess, WorkerLost
from rasm.scale.recordings import Checked, Job, is_trace, spec_of
from rasm.scale.tasks import Failed, explain_task, part_task, whole_task

__all__ = ["ATTEMPTS", "MIN_PART", "Outcome", "check_many", "cores", "plan_parts"]

ATTEMPTS = 3  # tries of a task whose worker died
MIN_PART = 8 << 20  # bytes: a smaller trace is checked in one pass


@dataclass
class Outcome:
    """One recording: its report (and notes), or why it could not be checked."""

    recording: str
    checked: Checked | None = None
    failed: tuple[str, ...] = ()

    @property
    def report(self) -> CheckReport | None:
        return self.checked.report if self.checked is not None else None


def cores() -> int:
    """The cores this process may run on (``--jobs``' default)."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _size(path: str) -> int:
    """The bytes of a recording (a folder's files added up; 0 when it cannot be read)."""
    try:
        target = Path(path)
        if target.is_dir():
            return sum(p.stat().st_size for p in target.iterdir() if p.is_file())
        return target.stat().st_size
    except OSError:
        return 0


def plan_parts(sizes: Sequence[int], jobs: int, part_size: int | None) -> list[int]:
    """How many parts each recording is cut into: with ``part_size`` (bytes), one per that
    many bytes; without, for ``jobs`` > 1, about two per job in all, so that the jobs finish
    together (a recording no larger than the rest is not cut), none smaller than
    :data:`MIN_PART`."""
    if part_size is None:
        if jobs <= 1:
            return [1] * len(sizes)
        part_size = max(MIN_PART, sum(sizes) // (2 * jobs))
    return [max(1, math.ceil(size / part_size)) for size in sizes]


@dataclass
class _Task:
    fn: Callable[..., Any]
    args: tuple
    recording: int
    kind: str  # whole | part | explain
    weight: int = 0  # bytes, for the progress
    number: int = 0  # the part's number
    attempts: int = 0


@dataclass
class _Recording:
    path: str
    cuts: list[int] = field(default_factory=list)
    parts: dict[int, PartResult] = field(default_factory=dict)
    whole: Checked | None = None  # the one-pass check (of the unbounded properties, if cut)
    merged: CheckReport | None = None
    explaining: int = 0  # explanation tasks still out
    outcome: Outcome | None = None
    wanted: dict[str, list[int]] = field(default_factory=dict)


class _Run:
    def __init__(self, job: Job, paths: Sequence[str], engine: Engine,
                 progress: Callable[[int, int], None] | None) -> None:
        self.job = job
        self.engine = engine
        self.progress = progress
        self.recordings = [_Recording(p) for p in paths]
        spec = spec_of(job)
        self.bounded = [p.name for p in spec.properties if splittable(p.formula)]
        self.unbounded = [p.name for p in spec.properties if not splittable(p.formula)]
        self.names = [p.name for p in spec.properties]
        self.out: dict[Any, _Task] = {}
        self.done = 0
        self.total = 0

    # ------------------------------------------------------------------ tasks

    def send(self, task: _Task) -> None:
        task.attempts += 1
        self.out[self.engine.submit(task.fn, *task.args)] = task

    def start(self, jobs: int, part_size: int | None) -> None:
        sizes = [_size(r.path) for r in self.recordings]
        counts = plan_parts(sizes, jobs, part_size)
        tasks = []
        for k, (rec, size, n) in enumerate(zip(self.recordings, sizes, counts, strict=True)):
            if n > 1 and self.bounded and is_trace(rec.path):
                from rasm.trace_parts import cut_points  # here: a trace checked whole needs none

                try:
                    rec.cuts = cut_points(rec.path, n)
                except OSError:
                    rec.cuts = []
            if len(rec.cuts) > 2:
                for number, (a, b) in enumerate(zip(rec.cuts, rec.cuts[1:], strict=False)):
                    tasks.append(_Task(part_task, (self.job, rec.path, a, b, self.bounded), k,
                                       "part", b - a, number))
                if self.unbounded:
                    tasks.append(_Task(whole_task, (self.job, rec.path, self.unbounded), k,
                                       "whole", size))
            else:
                rec.cuts = []
                tasks.append(_Task(whole_task, (self.job, rec.path, None), k, "whole", size))
        self.total = sum(t.weight for t in tasks)
        self.report_progress()
        # the largest first: the last to finish is a small one
        for task in sorted(tasks, key=lambda t: -t.weight):
            self.send(task)

    def report_progress(self) -> None:
        if self.progress is not None:
            self.progress(self.done, self.total)

    def run(self) -> list[Outcome]:
        while self.out:
            for future in self.engine.wait(list(self.out)):
                task = self.out.pop(future, None)
                if task is None:  # given up (its recording is checked in one pass instead)
                    continue
                try:
                    result = self.engine.result(future)
                except WorkerLost as lost:
                    if task.attempts < ATTEMPTS:
                        self.send(task)
                    else:
                        self.fail(task.recording, (
                            f"{self.recordings[task.recording].path}: not checked: {lost}; "
                            f"tried {task.attempts} times",))
                    continue
                self.done += task.weight
                self.report_progress()
                self.take(task, result)
        return [r.outcome or Outcome(r.path, failed=(f"{r.path}: not checked",))
                for r in self.recordings]

    # ------------------------------------------------------------------ results

    def fail(self, k: int, messages: tuple[str, ...]) -> None:
        rec = self.recordings[k]
        if rec.outcome is None:
            rec.outcome = Outcome(rec.path, failed=messages)

    def take(self, task: _Task, result: Any) -> None:
        rec = self.recordings[task.recording]
        if rec.outcome is not None:
            return  # the recording failed already
        if isinstance(result, Failed):
            if task.kind == "whole" and not rec.cuts:
                self.fail(task.recording, result.messages)
            elif rec.cuts:
                # a part could not be read: the whole recording, in one pass, says why
                rec.cuts = []
                for future, other in list(self.out.items()):
                    if other.recording == task.recording:
                        del self.out[future]
                        future.cancel()
                self.send(_Task(whole_task, (self.job, rec.path, None), task.recording,
                                "whole"))
            else:
                self.fail(task.recording, result.messages)
            return
        if task.kind == "whole":
            rec.whole = result
            if not rec.cuts:
                rec.outcome = Outcome(rec.path, result)
                return
        elif task.kind == "part":
            rec.parts[task.number] = result
        else:
            rec.explaining -= 1
            for prop in rec.merged.properties:
                prop.explanations += [result[(prop.name, i)] for i in
                                      rec.wanted.get(prop.name, []) if (prop.name, i) in result]
        self.settle(task.recording)

    def settle(self, k: int) -> None:
        rec = self.recordings[k]
        parts = len(rec.cuts) - 1
        if len(rec.parts) < parts or (self.unbounded and rec.whole is None):
            return
        spec = spec_of(self.job)
        if rec.merged is None:
            results = [rec.parts[n] for n in range(parts)]
            rec.merged = merge_parts(subspec(spec, self.bounded), results, trace=rec.path,
                                     named=self.job.named)
            if self.job.explain:
                rec.wanted = wanted_explanations(rec.merged)
                self.explain(k, results)
        if rec.explaining:
            return
        # the explanations came part by part, in order of the parts' arrival: sort them
        for prop in rec.merged.properties:
            prop.explanations.sort(key=lambda e: e.index)
        reports = {p.name: p for p in rec.merged.properties}
        if rec.whole is not None:
            reports.update({p.name: p for p in rec.whole.report.properties})
        report = CheckReport(spec.source, rec.path, rec.merged.records,
                             [reports[name] for name in self.names])
        rec.outcome = Outcome(rec.path, Checked(rec.path, report))

    def explain(self, k: int, results: list[PartResult]) -> None:
        rec = self.recordings[k]
        if not rec.wanted:
            return
        offset = 0
        for number, result in enumerate(results):
            end = offset + result.records
            mine = {name: [i for i in indices if offset <= i < end]
                    for name, indices in rec.wanted.items()}
            mine = {name: indices for name, indices in mine.items() if indices}
            if mine:
                rec.explaining += 1
                a, b = rec.cuts[number], rec.cuts[number + 1]
                self.send(_Task(explain_task, (self.job, rec.path, a, b, self.bounded, mine,
                                               offset), k, "explain"))
            offset = end


def check_many(
    job: Job,
    paths: Sequence[str],
    *,
    engine: Engine | None = None,
    jobs: int | None = None,
    part_size: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[Outcome]:
    """Check every recording of ``paths`` against the job's properties on ``engine`` (default:
    this process), large JSONL traces cut into parts for ``jobs`` workers (default: the
    engine's, else the cores); one :class:`Outcome` per recording, in order.

    ``part_size`` (bytes) cuts every JSONL trace larger than it into parts of about that size
    (default: the traces that dwarf the rest, into two parts per job). ``progress(done,
    total)`` is called as the tasks finish (in bytes read)."""
    engine = engine if engine is not None else InProcess()
    if jobs is None:
        jobs = 1 if isinstance(engine, InProcess) else (
            getattr(engine, "jobs", None) or cores())
    run = _Run(job, paths, engine, progress)
    run.start(jobs, part_size)
    return run.run()
