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
from rasm.platform.runtime import Platform, RunSummary
from rasm.platform.trace import jsonable as _jsonable
from rasm.platform.trace import round_time

__all__ = ["Trace", "run_app", "app_manifest"]

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


class _NotPlain(Exception):
    """A value :func:`json_copy`'s fast path might copy differently from the JSON round trip."""


# The JSON round trip refuses ints of more than sys.get_int_max_str_digits() digits; bigger ones
# (never seen in a trace) take it, so they fail exactly as they did.
_INT_LIMIT = 1 << 63
# deeper containers (or a circular one) take the round trip and its own recursion handling
_MAX_DEPTH = 64


def _plain(value: Any, depth: int) -> Any:
    """The fast path of :func:`json_copy`: raises :class:`_NotPlain` (or UnicodeEncodeError)
    where the copy could differ from ``json.loads(json.dumps(value))``.

    Only the exact types JSON gives back are handled: a subclass (an IntEnum, a str subclass
    with its own ``__str__``) or any other type takes the round trip.
    """
    cls = value.__class__
    # immutable scalars the round trip gives back equal (nan/inf included: NaN, Infinity)
    if cls is float or cls is bool or value is None:
        return value
    if cls is str:
        if not value.isascii():
            # the JSON decoder joins a surrogate pair into one character: refuse surrogates
            value.encode("utf-8")
        return value
    if cls is int:
        if -_INT_LIMIT < value < _INT_LIMIT:
            return value
        raise _NotPlain
    if depth >= _MAX_DEPTH:
        raise _NotPlain
    if cls is list or cls is tuple:  # a tuple comes back as a list
        depth += 1
        return [_plain(item, depth) for item in value]
    if cls is dict:
        out = {}
        depth += 1
        for key, item in value.items():
            # other keys are converted (1 -> "1") and may then collide: the round trip decides
            if key.__class__ is not str:
                raise _NotPlain
            if not key.isascii():
                key.encode("utf-8")
            out[key] = _plain(item, depth)
        return out
    raise _NotPlain


def json_copy(value: Any) -> Any:
    """``json.loads(json.dumps(value))``, without the round trip for the values traces hold.

    Scalars, strings, None and lists, tuples and dicts of them (str keys) are copied directly
    (about 20 times cheaper); anything else takes the round trip, so the result, or the error,
    is always the round trip's.
    """
    try:
        return _plain(value, 0)
    except (_NotPlain, UnicodeEncodeError):
        return json.loads(json.dumps(value))


def trace_line(time: float, record: Mapping[str, Any]) -> dict[str, Any]:
    """The record as it reads back from the trace file: ``time`` first (rounded to the
    nanosecond), a non-finite float at the top level as None, and every value a JSON value."""
    rounded = round_time(time)
    line: dict[str, Any] = {"time": rounded}
    # one pass that is _jsonable then json_copy's fast path: a record is mostly finite floats,
    # bools and ascii strings under str keys, copied here without two calls per value
    # type() first, a pointer test; __class__ (what an object says it is, an attribute lookup)
    # only when type() is not the class looked for, so the answer is what __class__ gave
    try:
        if type(rounded) is not float and rounded.__class__ is not float:
            raise _NotPlain  # an int time: json_copy decides on its size
        for key, value in record.items():
            if (type(key) is not str and key.__class__ is not str) or not key.isascii():
                raise _NotPlain
            cls = type(value)
            if cls is not float and cls is not bool and cls is not str and value is not None:
                cls = value.__class__
            if cls is float:
                line[key] = value if value - value == 0 else None  # nan and inf: null
            elif cls is bool or value is None or (cls is str and value.isascii()):
                line[key] = value
            else:
                line[key] = _plain(_jsonable(value), 1)
        return line
    except (_NotPlain, UnicodeEncodeError):
        pass
    line = {"time": rounded}
    for key, value in record.items():
        line[key] = _jsonable(value)
    return json_copy(line)


class Trace(Sequence[dict[str, Any]]):
    """An adaptation trace: a list of SPEC §4 records, and how it was made.

    ``records`` is the list; ``summary`` the run's :class:`~rasm.platform.runtime.RunSummary`
    (None for a trace that was not made by :func:`run_app`); ``seed``, ``scenario`` and
    ``duration`` say how to make it again.
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

    def check(self, props: Any):
        """Check a property file on this trace: a :class:`rasm.properties.check.CheckReport`."""
        from rasm.testing.assertions import check_trace

        return check_trace(props, self)


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
        clock="simulated",
        seed=seed,
        knowledge="memory",
        trace=trace,
        scenario=dict(scenario) if scenario is not None else None,
        components=dict(components) if components else None,
        check_signals=check_signals,
    )
    records: list[dict[str, Any]] = []
    last = -math.inf

    def collect(time: float, record: dict[str, Any]) -> None:
        nonlocal last
        # the trace never goes back in time (SPEC §4), as the file: max(time, last), no call
        last = last if last > time else time
        records.append(trace_line(last, record))

    platform.on_record.append(collect)
    summary = platform.run(duration)
    trace = Trace(
        (), summary=summary, app=manifest.name, seed=seed, scenario=platform.scenario,
        duration=duration,
    )
    trace.records = records  # fresh dicts of collect()'s own: no copy of each (Trace() makes one)
    return trace
