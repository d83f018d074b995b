"""The events a platform chart receives, from ``statecharts/interfaces.json``.

A chart of the platform's own ``statecharts/`` folder is verified by default under the events
its driver may send it (its interface's ``receives`` and the lifecycle's), not every event its
transitions name: that is the environment it runs in.
"""

from __future__ import annotations

import json
from pathlib import Path

from sismic.model import Statechart

from rasm.resources import data_dir

__all__ = ["platform_receives", "receives"]


def platform_receives(path: str | Path, statechart: Statechart) -> list[str] | None:
    """The events the platform sends ``statechart`` when ``path`` is one of its charts, in the
    order of the interface; None for any other chart."""
    folder = data_dir("statecharts")
    try:
        inside = Path(path).resolve().parent == folder.resolve()
    except OSError:
        return None
    if not inside:
        return None
    interfaces = json.loads((folder / "interfaces.json").read_text(encoding="utf-8"))
    own = interfaces.get(statechart.name)
    if own is None:
        return None
    names = list(interfaces["lifecycle"]["receives"])
    names.extend(name for name in own["receives"] if name not in names)
    return names


def receives(path: str | Path, statechart: Statechart, waited_for: list[str]) -> list[str]:
    """The default environment's events: every event a transition of the chart waits for,
    and for a platform chart also those its interface says the platform sends it."""
    names = list(platform_receives(path, statechart) or ())
    names.extend(name for name in waited_for if name not in names)
    return names
