"""``rasm report``: a trace file (and property files) into one self-contained HTML page.

Which properties: the platform's own (``rasm:properties/*.rv``: MAPLE-K stage order, legitimacy
gating, timeliness), which every trace ``rasm run`` writes is subject to — as ``app`` sets them
(its ``platform_properties:``), when given — plus the app's property files and the files given
with ``props``. Nothing is picked up from beside the trace: a report shows exactly the
properties it was asked for, and names them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from rasm.errors import Location, SourceError
from rasm.report.model import TraceModel
from rasm.report.page import render_page
from rasm.report.verdicts import check_trace, load_properties
from rasm.trace import read_trace

__all__ = ["build_model", "missing_notes", "write_report"]


def _read(trace: str | Path) -> list[tuple[float, dict[str, Any]]]:
    path = Path(trace)
    if path.is_dir():
        raise SourceError("is a folder, not a trace file (JSONL)", Location(str(path)))
    records = read_trace(path)
    if not records:
        raise SourceError(
            "empty trace: no records (a trace has one JSON object a line with a numeric 'time';"
            " rasm run APP --trace FILE writes one)",
            Location(str(path), 1),
        )
    return records


def missing_notes(model: dict[str, Any]) -> list[str]:
    """What the trace lacks, in words (shown at the top of the page)."""
    notes = []
    if not model["iterations"]:
        notes.append("no MAPLE-K stage timing: no record has a 'stage' key with its 'duration'")
    if not model["adaptations"]:
        notes.append("no adaptations: no record has 'anomaly' or 'planned'")
    if not model["signals"]:
        notes.append("no knowledge signals: the records carry only the loop's own keys")
    props = model.get("properties") or {}
    if not props.get("timelines"):
        notes.append("no properties checked: pass property files with --props FILE.rv")
    for timeline in props.get("timelines", []):
        if timeline["verdict"] == "not judged":
            missing = ", ".join(timeline["missing"]) or ", ".join(timeline["reads"]) or "nothing"
            notes.append(
                f"property {timeline['name']} not judged: no value for {missing} in this trace"
            )
        elif timeline["verdict"] == "error":
            notes.append(
                f"property {timeline['name']} in error at {timeline['errors']} records: "
                f"{timeline['first_error']}"
            )
    if props.get("off"):
        notes.append("platform properties off for this app (not checked): "
                     + ", ".join(props["off"]))
    if model["other_stages"]:
        notes.append(f"stages not drawn (not MAPLE-K): {', '.join(model['other_stages'])}")
    return notes


def build_model(
    trace: str | Path,
    props: Sequence[str | Path] = (),
    *,
    platform_props: bool = True,
    app: str | Path | None = None,
) -> dict[str, Any]:
    """Everything the page draws, for one trace file; ``app``: the app that wrote it (its
    settings of the platform's properties and its property files)."""
    from rasm.platform.app_properties import platform_specifications

    manifest = None
    if app is not None:
        from rasm.platform.manifest import load_manifest

        manifest = load_manifest(app)
    records = _read(trace)
    specs = []
    off: list[str] = []
    if platform_props:
        settings = manifest.platform_properties if manifest is not None else {}
        budget = manifest.stage_budget if manifest is not None else None
        specs += platform_specifications(settings, stage_budget=budget)
        off = [name for name, limits in settings.items() if limits is None]
    files = [_shown(f) for f in [*(manifest.properties if manifest is not None else []), *props]]
    specs += load_properties(files)
    model = TraceModel()
    for time, record in records:
        model.add(time, record)
    data = model.to_dict()
    timelines = check_trace(specs, trace) if specs else []
    data["properties"] = {
        "files": list(dict.fromkeys(spec.source for spec in specs)),
        "off": off,
        "timelines": [t.to_dict() for t in timelines],
        "note": "No properties: verdict timelines need property files "
        "(rasm report TRACE -o OUT.html --props FILE.rv).",
    }
    data["source"] = str(trace)
    data["live"] = False
    data["generated"] = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    data["missing"] = missing_notes(data)
    return _clean(data)


def _shown(path: str | Path) -> str:
    """A property file's name as the page shows it: relative to the working folder if inside."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def _clean(value: Any) -> Any:
    """JSON has no NaN or infinity: they become null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    return value


def write_report(
    trace: str | Path,
    output: str | Path,
    props: Sequence[str | Path] = (),
    *,
    platform_props: bool = True,
    app: str | Path | None = None,
    title: str | None = None,
) -> dict[str, Any]:
    """Write the self-contained report of ``trace`` to ``output``; returns the model drawn."""
    model = build_model(trace, props, platform_props=platform_props, app=app)
    page = render_page(model, title=title or f"rasm report: {Path(trace).name}")
    Path(output).write_text(page, encoding="utf-8")
    return model
