"""Loading the app's code: its stage components, its simulator and its digital twin.

The app folder is imported as a package of its own (:func:`package_name`), so its modules can
import each other relatively and two apps never share modules.
"""

from __future__ import annotations

import hashlib
import importlib
import logging
import sys
import types
from pathlib import Path
from typing import Any

from rasm.errors import Location, PlatformError, SourceError, is_interrupt
from rasm.loop import STAGES
from rasm.platform.components import missing_stage_method
from rasm.platform.manifest import AppManifest, is_chart_ref, manifest_location
from rasm.twin import DigitalTwin

__all__ = [
    "check_components",
    "load_app_components",
    "load_component",
    "load_stage_component",
    "load_twin",
    "package_name",
]

_log = logging.getLogger("rasm.platform")


def package_name(manifest: AppManifest) -> str:
    """A module package per app folder: two apps of the same name never share modules."""
    digest = hashlib.sha1(str(manifest.folder.resolve()).encode()).hexdigest()[:10]
    return f"rasm_app_{manifest.name.replace('-', '_')}_{digest}"


def load_component(
    ref: str, folder: Path, *, package: str, kwargs: dict[str, Any] | None = None
) -> object:
    """Instantiate ``module:Class`` (``module`` a file or package in ``folder``) with ``kwargs``."""
    module_name, _, class_name = ref.partition(":")
    if package not in sys.modules:
        # the app folder as a package, so its modules can import each other relatively
        parent = types.ModuleType(package)
        parent.__path__ = [str(folder)]
        parent.__package__ = package
        sys.modules[package] = parent
    qualified = f"{package}.{module_name}"
    try:
        module = importlib.import_module(qualified)
    except ModuleNotFoundError as exc:
        if exc.name == qualified or (exc.name or "").startswith(package):
            raise PlatformError(f"{ref}: no module {module_name!r} in {folder}") from exc
        raise PlatformError(f"{ref}: importing {module_name} failed: {exc}") from exc
    except BaseException as exc:  # sys.exit() at import: an error, not an exit
        if is_interrupt(exc):
            raise
        sys.modules.pop(qualified, None)
        raise PlatformError(
            f"{ref}: importing {module_name} failed: {type(exc).__name__}: {exc}"
        ) from exc
    cls = getattr(module, class_name, None)
    if cls is None:
        raise PlatformError(f"{ref}: {module_name} has no {class_name!r}")
    try:
        return cls(**(kwargs or {}))
    except BaseException as exc:
        if is_interrupt(exc):
            raise
        raise PlatformError(f"{ref}: creating {class_name}() failed: {exc}") from exc


def load_stage_component(m: AppManifest, stage: str, ref: str, package: str) -> object:
    """The manifest's component ``ref`` for ``stage`` (a chart for a path ending in .yaml); a
    problem names its place in app.yaml (or, for a chart, in the chart)."""
    if is_chart_ref(ref):
        from rasm.platform.chart_stages import ChartStage

        return ChartStage(m.folder / ref, stage)
    try:
        component = load_component(ref, m.folder, package=package)
    except PlatformError as exc:
        cause = exc.__cause__
        if isinstance(cause, SyntaxError) and cause.filename and cause.lineno:
            # the place of the mistake is in the Python file, not in app.yaml
            where = Location(cause.filename, cause.lineno, cause.offset or 1)
            raise SourceError(f"{ref}: SyntaxError: {cause.msg}", where) from exc
        raise SourceError(str(exc), manifest_location(m, m.component_path(stage))) from exc
    problem = missing_stage_method(stage, component) if stage in STAGES else None
    if problem:
        raise SourceError(
            f"components.{stage}: {ref}: {problem}, so the {stage} stage would never run it",
            manifest_location(m, m.component_path(stage)),
        )
    return component


def load_app_components(
    m: AppManifest, given: dict[str, object]
) -> tuple[dict[str, object], object | None]:
    """The run's stage components and its twin (not restored yet: :func:`load_twin`): those
    ``given`` (``RunOptions(components=...)``, by stage or ``twin``), else the manifest's."""
    package = package_name(m)
    components = {
        stage: given.get(stage) or load_stage_component(m, stage, ref, package)
        for stage, ref in m.components.items()
    }
    components.update(given)
    twin = given.get("twin")
    if twin is None and m.twin:
        twin = load_component(m.twin, m.folder, package=package)
    return components, twin


def load_twin(twin: DigitalTwin | None, model: dict[str, Any] | None) -> DigitalTwin | None:
    """``twin`` restored to ``model`` (what it learned before a restart, if anything): a model
    that does not load is logged and relearned, never fatal."""
    if twin is not None and model:
        try:
            twin.load(model)
        except BaseException as exc:
            if is_interrupt(exc):
                raise
            _log.warning("the twin's stored model was not restored: %s", exc)
    return twin


def check_components(components: object) -> None:
    """``RunOptions(components=...)``: a dict of stage (or ``twin``) to an object serving it."""
    if not isinstance(components, dict):
        raise TypeError(
            f"components must be a dict {{stage: object}}, not {type(components).__name__}"
        )
    unknown = sorted(set(components) - {*STAGES, "twin"})
    if unknown:
        raise PlatformError(
            f"components: unknown stage {unknown[0]!r} "
            f"(the stages are {', '.join(STAGES)}; or twin)"
        )
    for stage, obj in components.items():
        problem = missing_stage_method(stage, obj) if stage in STAGES else None
        if problem:
            raise PlatformError(f"components[{stage!r}]: {problem}")
