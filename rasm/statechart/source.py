"""YAML read with positions: every mapping, key and scalar can be traced to its line and column.

sismic reads YAML without keeping positions, so its errors cannot say where a problem is. We read
the same YAML 1.2 with ruamel's round-trip loader, which records them, and turn YAML syntax errors
into :class:`~rasm.errors.SourceError` instead of letting raw ruamel exceptions escape. The
reader is guarded against hostile documents (too deep, too many aliases, values Python refuses,
forbidden characters): see :mod:`rasm.yamlsafe`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.error import YAMLError
from ruamel.yaml.scalarstring import FoldedScalarString, LiteralScalarString

from rasm.errors import Location, SourceError, mark
from rasm.yamlsafe import document_start, yaml_error, yaml_reader

__all__ = ["YamlSource", "load_yaml", "plain"]


@dataclass
class YamlSource:
    """A parsed YAML document with the text and file name it came from."""

    data: Any
    text: str
    file: str

    def location(self, line0: int, col0: int) -> Location:
        """A location from ruamel's 0-based line and column."""
        return Location(self.file, line0 + 1, col0 + 1)

    def node(self, node: Any) -> Location:
        """Where a mapping or sequence starts (for anything else: where the document starts)."""
        lc = getattr(node, "lc", None)
        if lc is None or lc.line is None:
            return self.start()
        return self.location(lc.line, lc.col)

    def start(self) -> Location:
        """Where the document's content starts (see :func:`~rasm.yamlsafe.document_start`)."""
        return Location(self.file, *document_start(self.text))

    def key(self, mapping: Any, key: str) -> Location:
        """Where ``key`` is written in ``mapping``."""
        try:
            line, col = mapping.lc.key(key)
        except (AttributeError, KeyError, TypeError):
            return self.node(mapping)
        return self.location(line, col)

    def value(self, mapping: Any, key: str) -> Location:
        """Where the value of ``key`` starts in ``mapping`` (for a block scalar, its indicator)."""
        try:
            line, col = mapping.lc.value(key)
        except (AttributeError, KeyError, TypeError):
            return self.key(mapping, key)
        return self.location(line, col)

    def item(self, seq: Any, index: int) -> Location:
        try:
            line, col = seq.lc.item(index)
        except (AttributeError, KeyError, TypeError, IndexError):
            return self.node(seq)
        return self.location(line, col)

    def at(self, path: list[Any]) -> Location:
        """Where the node at ``path`` (mapping keys and sequence indexes from the root) is
        written: a scalar's value, a container's key or item; the nearest parent if the path
        goes beyond the document (a missing key is reported where its mapping is)."""
        node = self.data
        parent, last = None, None
        for step in path:
            try:
                parent, last, node = node, step, node[step]
            except (KeyError, IndexError, TypeError):
                break
        if parent is None:
            return self.node(node)
        if isinstance(last, int):
            return self.item(parent, last)
        if isinstance(node, str | int | float | bool) or node is None:
            return self.value(parent, last)
        return self.key(parent, last)

    def code_location(self, mapping: Any, key: str, code_line: int, code_col: int) -> Location:
        """Where line ``code_line``, column ``code_col`` (1-based) of the code in ``key`` is.

        Handles literal/folded block scalars (content starts on the next line, indented), quoted
        scalars (content starts one column after the quote) and plain scalars.
        """
        value = mapping[key]
        start = self.value(mapping, key)
        lines = self.text.splitlines()
        if isinstance(value, LiteralScalarString | FoldedScalarString):
            line = start.line + code_line
            if 1 <= line <= len(lines):
                content = lines[line - 1]
                indent = len(content) - len(content.lstrip(" "))
                return Location(self.file, line, indent + max(code_col, 1))
            return Location(self.file, start.line)
        col = start.col
        if 1 <= start.line <= len(lines):
            source_line = lines[start.line - 1]
            if start.col - 1 < len(source_line) and source_line[start.col - 1] in "'\"":
                col += 1
        if code_line <= 1:
            return Location(self.file, start.line, col + max(code_col, 1) - 1)
        return Location(self.file, start.line + code_line - 1, max(code_col, 1))

    def error(self, message: str, location: Location, width: int = 1) -> SourceError:
        return SourceError(message, location, mark(self.text, location.line, location.col, width))


def load_yaml(text: str, file: str) -> YamlSource:
    """Parse YAML 1.2 text, keeping positions; syntax errors become :class:`SourceError`."""
    try:
        data = yaml_reader().load(text)
    except YAMLError as exc:
        raise yaml_error(exc, text, file) from None
    return YamlSource(data, text, file)


def plain(value: Any) -> Any:
    """A copy of ruamel's commented containers as plain dicts, lists and strings."""
    if isinstance(value, CommentedMap | dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, CommentedSeq | list):
        return [plain(v) for v in value]
    if isinstance(value, str):
        return str(value)
    return value
