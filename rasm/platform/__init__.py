"""rasm.platform: the MAPLE-K loop and the building blocks it runs on.

One module per building block (``telegraf``, ``knowledge_manager``, ``trustworthiness_checker``,
...), each a :class:`~rasm.platform.block.Block` driven by its statechart; ``platform``
assembles them into a :class:`Platform`. The names below are loaded on first use.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

# public name -> the module that defines it
_PUBLIC = {
    "Action": "rasm.platform.components",
    "Anomaly": "rasm.platform.components",
    "AppManifest": "rasm.platform.manifest",
    "ChartStage": "rasm.platform.chart_stages",
    "LoopStats": "rasm.platform.adaptation_orchestrator",
    "Plan": "rasm.platform.components",
    "Platform": "rasm.platform.platform",
    "RunSummary": "rasm.platform.summary",
    "StageContext": "rasm.platform.components",
    "load_manifest": "rasm.platform.manifest",
}

__all__ = [
    "Action",
    "Anomaly",
    "AppManifest",
    "ChartStage",
    "LoopStats",
    "Plan",
    "Platform",
    "RunSummary",
    "StageContext",
    "load_manifest",
]

if TYPE_CHECKING:  # for type checkers and editors: the same names, imported eagerly
    from rasm.platform.adaptation_orchestrator import LoopStats
    from rasm.platform.chart_stages import ChartStage
    from rasm.platform.components import Action, Anomaly, Plan, StageContext
    from rasm.platform.manifest import AppManifest, load_manifest
    from rasm.platform.platform import Platform
    from rasm.platform.summary import RunSummary


def __getattr__(name: str) -> object:
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'rasm.platform' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later reads find it directly
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
