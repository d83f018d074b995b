"""The properties a run checks, compiled into monitors: the platform's own (the loop's stage
order, ...) then the app's files, each property name defined once."""

from __future__ import annotations

from pathlib import Path

from rasm.errors import PlatformError
from rasm.platform.manifest import AppManifest
from rasm.properties.monitor import Monitor
from rasm.resources import data_dir

__all__ = ["compile_app_properties"]


def compile_app_properties(m: AppManifest) -> list[Monitor]:
    """One monitor per property file: the platform's, then the app's (``properties:``).

    Verdicts are reported by property name, so a name defined in two files would merge two
    properties silently: that raises :class:`~rasm.errors.PlatformError` naming both files.
    """
    from rasm.properties import compile_properties

    files = [*sorted(data_dir("properties").glob("*.rv")), *m.properties]
    monitors = [compile_properties(p.read_text(encoding="utf-8"), source=str(p)) for p in files]
    defined: dict[str, Path] = {}
    for path, monitor in zip(files, monitors, strict=True):
        for name in monitor.properties:
            if name in defined:
                raise PlatformError(
                    f"property {name!r} of {path} is already defined in "
                    f"{defined[name]}: rename one of them"
                )
            defined[name] = path
    return monitors
