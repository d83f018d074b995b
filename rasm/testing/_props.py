"""Accepting a property file as a path, as text, or already loaded."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rasm.properties.ast import Specification
from rasm.properties.loader import load_specification

__all__ = ["PropertyFile", "property_file"]


@dataclass(frozen=True)
class PropertyFile:
    """A checked property file and where it came from."""

    spec: Specification
    text: str
    source: str

    @property
    def stem(self) -> str:
        name = Path(self.source).name
        return name[: -len(".rv")] if name.endswith(".rv") else "properties"


def _looks_like_path(value: str) -> bool:
    return "\n" not in value and (value.endswith(".rv") or Path(value).is_file())


def property_file(props: str | Path | Specification | PropertyFile) -> PropertyFile:
    """Load ``props``: a path to a ``.rv`` file, the text of one, or a loaded specification."""
    if isinstance(props, PropertyFile):
        return props
    if isinstance(props, Specification):
        return PropertyFile(props, "", props.source)
    if isinstance(props, Path) or (isinstance(props, str) and _looks_like_path(props)):
        path = Path(props)
        if not path.is_file():
            raise FileNotFoundError(
                f"no property file {path} (pass the path of a .rv file, or the text of one)"
            )
        text = path.read_text(encoding="utf-8")
        return PropertyFile(load_specification(text, source=str(path)), text, str(path))
    if isinstance(props, str):
        return PropertyFile(load_specification(props, source="<text>"), props, "<text>")
    raise TypeError(f"expected a property file (a path or its text), not {type(props).__name__}")
