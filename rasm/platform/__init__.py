"""rasm.platform: the MAPLE-K loop and the building blocks it runs on.

One module per building block (``telegraf``, ``knowledge_manager``, ``trustworthiness_checker``,
...), each a :class:`~rasm.platform.block.Block` driven by its statechart; ``assembly``
builds them for a :class:`Platform`, which runs them with :class:`RunOptions`. The names below
are loaded on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rasm import _lazy

# public name -> the module that defines it
_PUBLIC = {
    "Action": "rasm.platform.components",
    "Anomaly": "rasm.platform.components",
    "AppManifest": "rasm.platform.manifest",
    "ChartStage": "rasm.platform.chart_stages",
    "LoopStats": "rasm.platform.protocols",
    "Plan": "rasm.platform.components",
    "Platform": "rasm.platform.platform",
    "RunOptions": "rasm.platform.run_options",
    "Clock": "rasm.platform.run_options",
    "Role": "rasm.platform.run_options",
    "RunSummary": "rasm.platform.summary",
    "StageContext": "rasm.platform.components",
    "load_manifest": "rasm.platform.manifest",
}

__all__ = [
    "Action",
    "Clock",
    "Anomaly",
    "AppManifest",
    "ChartStage",
    "LoopStats",
    "Plan",
    "Platform",
    "Role",
    "RunOptions",
    "RunSummary",
    "StageContext",
    "load_manifest",
]

if TYPE_CHECKING:  # for type checkers and editors: the same names, imported eagerly
    from rasm.platform.chart_stages import ChartStage
    from rasm.platform.components import Action, Anomaly, Plan, StageContext
    from rasm.platform.manifest import AppManifest, load_manifest
    from rasm.platform.platform import Platform
    from rasm.platform.protocols import LoopStats
    from rasm.platform.run_options import Clock, Role, RunOptions
    from rasm.platform.summary import RunSummary


__getattr__, __dir__ = _lazy.lazy_names(globals(), _PUBLIC)
