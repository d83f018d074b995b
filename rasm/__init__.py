"""rasm: a statechart-first platform for trustworthy self-adaptive robots.

The RoboSAPIENS Adaptive Platform's MAPLE-K loop (Monitor, Analyse, Plan, Legitimate, Execute over
Knowledge), its building blocks driven by YAML statecharts executed with sismic, a temporal
property language checked online, and z3-checked legitimacy rules.

``import rasm`` is the front door: the names an application is written with. ::

    import rasm

    class Analyse:
        def analyse(self, ctx: rasm.StageContext) -> rasm.Anomaly | None:
            ...

    options = rasm.RunOptions(clock=rasm.Clock.SIMULATED, seed=1)
    summary = rasm.Platform("examples/hotbox", options).run(duration=60)

The names are loaded on first use, so ``import rasm`` (and every ``rasm`` command) stays cheap.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rasm import _lazy

__version__ = "0.1.0"

# public name -> the module that defines it
_PUBLIC = {
    "Platform": "rasm.platform.platform",
    "RunOptions": "rasm.platform.run_options",
    "Clock": "rasm.platform.run_options",
    "Role": "rasm.platform.run_options",
    "RunSummary": "rasm.platform.summary",
    "Anomaly": "rasm.platform.components",
    "Plan": "rasm.platform.components",
    "Action": "rasm.platform.components",
    "StageContext": "rasm.platform.components",
    "load_manifest": "rasm.platform.manifest",
    "compile_properties": "rasm.properties",
    "RasmError": "rasm.errors",
    "SourceError": "rasm.errors",
}

__all__ = [
    "Action",
    "Clock",
    "Anomaly",
    "Plan",
    "Platform",
    "Role",
    "RunOptions",
    "RasmError",
    "RunSummary",
    "SourceError",
    "StageContext",
    "__version__",
    "compile_properties",
    "load_manifest",
]

if TYPE_CHECKING:  # for type checkers and editors: the same names, imported eagerly
    from rasm.errors import RasmError, SourceError
    from rasm.platform.components import Action, Anomaly, Plan, StageContext
    from rasm.platform.manifest import load_manifest
    from rasm.platform.platform import Platform
    from rasm.platform.run_options import Clock, Role, RunOptions
    from rasm.platform.summary import RunSummary
    from rasm.properties import compile_properties


__getattr__, __dir__ = _lazy.lazy_names(globals(), _PUBLIC)
