"""``rasm lint``: check statecharts, property files, rule files and app manifests.

Each file is recognised by its content (a YAML mapping with ``statechart``, ``rules``/``variables``
or an ``app.yaml``) or its suffix (``.rv``); a folder is searched for such files. Every problem is
one ``file:line:col: message`` line, reported once however the paths overlap. An app manifest
also has the property and rule files it names checked against what the app provides
(:mod:`rasm.platform.signals`), and the charts it names against their places
(:mod:`rasm.platform.app_charts`); a chart named like a platform chart is held to that chart's
interface.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from rasm.errors import Location, RasmError, SourceError, SourceErrors, read_utf8

__all__ = ["lint_file", "lint_paths", "LintUsageError"]

YAML_SUFFIXES = {".yaml", ".yml"}
LINTED_SUFFIXES = YAML_SUFFIXES | {".rv"}


class LintUsageError(RasmError):
    """A path that does not exist or cannot be linted (a usage error: exit 2)."""


def _one_line(error: SourceError) -> str:
    return f"{error.location}: {error.message}"


def _errors_of(exc: BaseException) -> list[str]:
    if isinstance(exc, SourceErrors):
        return [_one_line(e) for e in exc.errors]
    if isinstance(exc, SourceError):
        return [_one_line(exc)]
    return [str(exc)]


def _lint_statechart(path: Path, text: str) -> list[str]:
    from rasm.statechart.load import check_statechart

    chart, problems = check_statechart(text, str(path))
    found = [p.one_line() for p in problems]
    if chart is not None:
        found += _lint_interface(path, chart.name)
    return found


def _lint_interface(path: Path, name: str) -> list[str]:
    """A chart named like a platform chart (a copy to replace it) is held to that chart's
    interface, as the app that names it would be."""
    from rasm.platform.app_charts import interface_problems, platform_chart_names

    if name not in platform_chart_names():
        return []
    return [_one_line(e) for e in interface_problems(name, path)]


def _lint_properties(path: Path, text: str) -> list[str]:
    try:
        from rasm.properties import compile_properties
    except ImportError:  # pragma: no cover - the property language ships with rasm
        return [f"{path}: cannot lint property files: rasm.properties is not available"]
    try:
        compile_properties(text, source=str(path))
    except (SourceError, SourceErrors) as exc:
        return _errors_of(exc)
    return []


def _lint_rules(path: Path, text: str) -> list[str]:
    try:
        from rasm.rules import parse_rules
    except ImportError:  # pragma: no cover
        return [f"{path}: cannot lint rule files: rasm.rules is not available"]
    try:
        parse_rules(text, source=str(path))
    except (SourceError, SourceErrors) as exc:
        return _errors_of(exc)
    return []


def _lint_manifest(path: Path, text: str) -> list[str]:
    try:
        from rasm.platform.manifest import load_manifest
    except ImportError:
        return []  # manifests are checked once the runtime is installed
    try:
        manifest = load_manifest(path)
    except (SourceError, SourceErrors) as exc:
        return _errors_of(exc)
    return _lint_app_signals(manifest)


def _lint_app_signals(manifest: Any) -> list[str]:
    """The property and rule files the manifest names, against what the app provides."""
    from rasm.platform.signals import app_problems

    return [_one_line(e) for e in app_problems(manifest)]


def _lint_model(path: Path, text: str) -> list[str]:
    from rasm.workflow.checks import lint_model

    return [_one_line(e) for e in lint_model(path)]


def _lint_model_beside_app(path: Path, text: str) -> list[str]:
    """A model linted with its app's manifest: the app's signal check (the one ``rasm run``
    applies) judges the property and rule files both name, so the model's own is left out."""
    from rasm.workflow.checks import lint_model

    return [_one_line(e) for e in lint_model(path, signals=False)]


def _yaml_kind(path: Path, text: str) -> Callable[[Path, str], list[str]] | None:
    """Which linter a YAML file needs, from its top-level keys (cheap: no full parse)."""
    keys = set()
    for line in text.splitlines():
        if line and not line[0].isspace() and not line.startswith(("#", "-", "---")):
            keys.add(line.split(":", 1)[0].strip())
    if "statechart" in keys:
        return _lint_statechart
    if "architecture" in keys:
        return _lint_model
    if path.name in ("app.yaml", "app.yml") or "components" in keys:
        return _lint_manifest
    if "rules" in keys or "variables" in keys:
        return _lint_rules
    return None


def lint_file(path: Path) -> list[str]:
    """Problems in one file, as ``file:line:col: message`` strings."""
    try:
        text = read_utf8(path)
    except SourceError as exc:  # not UTF-8: placed at its first bad byte
        return [_one_line(exc)]
    if path.suffix == ".rv":
        return _lint_properties(path, text)
    kind = _yaml_kind(path, text)
    if kind is None:
        return [
            _one_line(
                SourceError(
                    "not a statechart, rules file or app manifest "
                    "(expected a top-level 'statechart', 'rules' or an app.yaml)",
                    Location(str(path), 1, 1),
                )
            )
        ]
    return kind(path, text)


def _files(paths: Iterable[str]) -> list[Path]:
    out: list[Path] = []
    for name in paths:
        path = Path(name)
        if path.is_dir():
            found = sorted(
                p for p in path.rglob("*") if p.is_file() and p.suffix in LINTED_SUFFIXES
            )
            out.extend(p for p in found if p.suffix == ".rv" or _yaml_kind(p, _read(p)))
        elif path.is_file():
            out.append(path)
        else:
            raise LintUsageError(f"{name}: no such file or folder")
    return out


def _read(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return ""


def lint_paths(paths: Iterable[str]) -> list[str]:
    """Problems in every file named or found in the folders named, each once (a file named
    twice, or a property file linted alone and as part of its app, is reported once)."""
    named: dict[Path, Path] = {}
    for path in _files(paths):
        named.setdefault(path.resolve(), path)
    kinds = {
        path: _yaml_kind(path, _read(path)) if path.suffix in YAML_SUFFIXES else None
        for path in named.values()
    }
    apps = {path.resolve().parent for path, kind in kinds.items() if kind is _lint_manifest}
    problems: list[str] = []
    for path, kind in kinds.items():
        if kind is _lint_model and path.resolve().parent in apps:
            problems.extend(_lint_model_beside_app(path, _read(path)))
        else:
            problems.extend(lint_file(path))
    return list(dict.fromkeys(problems))
