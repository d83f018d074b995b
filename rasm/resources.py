"""Where the platform's shipped YAML lives: ``statecharts/``, ``monitors/`` and ``properties/``.

In a wheel they are packaged under ``rasm/_data/``; in a source checkout (editable install) they are
the top-level folders of the repository.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["data_dir", "platform_chart", "platform_monitors"]

_PACKAGE = Path(__file__).resolve().parent


def data_dir(kind: str) -> Path:
    """The folder of shipped ``kind`` files (``statecharts``, ``monitors`` or ``properties``)."""
    packaged = _PACKAGE / "_data" / kind
    if packaged.is_dir():
        return packaged
    return _PACKAGE.parent / kind


def platform_chart(name: str) -> Path:
    """The shipped chart of building block ``name`` (e.g. ``adaptation_orchestrator``)."""
    path = data_dir("statecharts") / f"{name}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in data_dir("statecharts").glob("*.yaml"))
        raise FileNotFoundError(f"no platform statechart {name!r}; known: {', '.join(known)}")
    return path


def platform_monitors() -> list[Path]:
    """The shipped property statecharts that watch the orchestrator."""
    return sorted(data_dir("monitors").glob("*.yaml"))
