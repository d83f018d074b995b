"""Running an application on the simulated clock, and the adaptation trace it leaves.

``run_app(app, seed=1, duration=30)`` builds the app's platform (knowledge in memory, simulated
clock), runs it and returns a :class:`Trace`: the records ``rasm run --trace`` would have written,
with the run's summary. With the same seed and scenario two runs give the same records (but for
the wall-clock ``duration`` of each stage).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from rasm.platform.manifest import AppManifest, load_manifest
from rasm.platform.platform import Platform
from rasm.platform.run_options import Clock, RunOptions
from rasm.platform.summary import RunSummary
from rasm.testing.assertions import check_trace
from rasm.trace import trace_line

__all__ = ["Trace", "app_manifest", "run_app"]

_MANIFESTS: dict[tuple[str, float], AppManifest] = {}
# manifest fields run_app() may override that are durations (a string there failed every tick)
_SECONDS = {"period", "stage_budget", "simulator_period", "duration", "twin_horizon", "twin_dt"}


def _positive(value: Any) -> bool:
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and value > 0
        and math.isfinite(value)
    )


def app_manifest(app: str | Path | AppManifest) -> AppManifest:
    """The manifest of ``app`` (a folder, its ``app.yaml``, or a manifest), as a fresh copy."""
    if isinstance(app, AppManifest):
        return dataclasses.replace(app)
    path = Path(app)
    file = path / "app.yaml" if path.is_dir() else path
    key = (str(file.resolve()), file.stat().st_mtime if file.is_file() else 0.0)
    if key not in _MANIFESTS:
        _MANIFESTS[key] = load_manifest(path)
    return dataclasses.replace(_MANIFESTS[key])


def run_app(
    app: str | Path | AppManifest,
    *,
    seed: int,
    duration: float,
    scenario: Mapping[str, Any] | None = None,
    components: Mapping[str, Any] | None = None,
    trace: str | Path | None = None,
    check_signals: bool = True,
    **overrides: Any,
) -> Trace:
    """Run ``app`` for ``duration`` simulated seconds and return its adaptation trace.

    * ``scenario``: the disturbance schedule handed to the app's simulator (default: the one in
      ``app.yaml``); draw them with :func:`rasm.testing.scenarios`.
    * ``components``: stage objects replacing the app's, e.g. ``{"plan": SlowPlanner()}``.
    * ``trace``: also write the trace to this JSONL file.
    * ``check_signals=False``: run an app whose properties or rules read a name no part of it
      provides (by default refused like ``rasm run`` refuses it, with SourceErrors).
    * ``overrides``: fields of the manifest to change for this run, e.g. ``stage_budget=0.05``
      or ``period=0.25``.

    Knowledge is kept in memory and timing is not written (``timing: off``), so nothing is left
    on disk but ``trace``.
    """
    manifest = app_manifest(app)
    if not isinstance(seed, int) or isinstance(seed, bool):
        raise TypeError(f"seed must be an int (e.g. seed=1), not {seed!r}")
    if scenario is not None and not isinstance(scenario, Mapping):
        raise TypeError(
            f"scenario must be a dict (e.g. {{'openings': [[3.0, 10.0]]}}; draw them with "
            f"rasm.testing.scenarios) or None, not {type(scenario).__name__}"
        )
    if overrides:
        fields = {f.name for f in dataclasses.fields(AppManifest)}
        unknown = sorted(set(overrides) - fields)
        if unknown:
            raise TypeError(
                f"run_app() got {unknown[0]!r}, which is neither one of its arguments nor a "
                f"manifest field; the manifest fields are: {', '.join(sorted(fields))}"
            )
        for name in sorted(_SECONDS & set(overrides)):
            value = overrides[name]
            if not _positive(value):
                raise ValueError(f"{name} must be a positive number of seconds, not {value!r}")
        replans = overrides.get("max_replans", 0)
        if not isinstance(replans, int) or isinstance(replans, bool) or replans < 0:
            raise ValueError(f"max_replans must be an int >= 0, not {replans!r}")
        manifest = dataclasses.replace(manifest, **overrides)
    if "timing" not in (overrides or {}):
        # a test run leaves nothing on disk but its trace (timing=... in overrides to keep it)
        manifest = dataclasses.replace(manifest, timing="off")
    if not _positive(duration):
        raise ValueError(f"duration must be a positive number of seconds, not {duration!r}")
    platform = Platform(
        manifest,
        RunOptions(
            clock=Clock.SIMULATED,
            seed=seed,
            knowledge="memory",
            trace=trace,
            scenario=dict(scenario) if scenario is not None else None,
            components=dict(components) if components else None,
            check_signals=check_signals,
        ),
    )
    records: list[dict[str, Any]] = []
    last = -math.inf

    def collect(time: float, record: dict[str, Any]) -> None:
        nonlocal last
        last = max(time, last)  # the trace never goes back in time, as the file
        records.append(trace_line(last, record))

    platform.on_record.append(collect)
    summary = platform.run(duration)
    return Trace(
        records, summary=summary, app=manifest.name, seed=seed, scenario=platform.scenario,
        duration=duration,
    )


class Trace(Sequence[dict[str, Any]]):
    """An adaptation trace in memory: a list of records, and how it was made.

    ``records`` is the list, each record as :func:`trace_line` gives it; ``summary`` the run's
    :class:`~rasm.RunSummary` (None for a trace that was not made by
    :func:`rasm.testing.run_app`); ``seed``, ``scenario`` and ``duration`` say how to make it
    again.
    """

    def __init__(
        self,
        records: Sequence[Mapping[str, Any]],
        *,
        summary: RunSummary | None = None,
        app: str = "",
        seed: int | None = None,
        scenario: Mapping[str, Any] | None = None,
        duration: float | None = None,
    ) -> None:
        self.records = [dict(r) for r in records]
        self.summary = summary
        self.app = app
        self.seed = seed
        self.scenario = dict(scenario) if scenario is not None else None
        self.duration = duration

    def __len__(self) -> int:
        return len(self.records)

    def __getitem__(self, index):  # type: ignore[override]
        return self.records[index]

    def __iter__(self) -> Iterator[dict[str, Any]]:
        return iter(self.records)

    def __repr__(self) -> str:
        how = f" seed={self.seed} scenario={self.scenario}" if self.app else ""
        return f"<Trace {self.app}{how}: {len(self.records)} records>"

    def when(self, event: str) -> list[float]:
        """The times of the records on which ``event`` is true (``trace.when("executed")``)."""
        return [r["time"] for r in self.records if r.get(event) is True]

    def values(self, signal: str) -> list[tuple[float, Any]]:
        """``(time, value)`` for every record that sets ``signal``."""
        return [(r["time"], r[signal]) for r in self.records if signal in r]

    def lines(self) -> list[str]:
        """The trace as JSON lines (what ``rasm run --trace`` writes)."""
        return [json.dumps(r) for r in self.records]

    def save(self, path: str | Path) -> Path:
        """Write the trace as JSONL to ``path`` (for ``rasm check``); returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("".join(line + "\n" for line in self.lines()), encoding="utf-8")
        return path

    def check(self, props: Any) -> Any:
        """Check a property file on this trace: a :class:`rasm.properties.check.CheckReport`
        (as :func:`rasm.testing.check_trace` does)."""
        return check_trace(props, self)
