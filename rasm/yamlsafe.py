"""YAML readers for input nobody has vetted: every YAML file rasm reads is someone's input.

The guards: nesting deeper than :data:`MAX_DEPTH` levels (the readers recurse once per level, and
Python's recursion would give out), aliases that repeat more than :data:`MAX_ALIAS_VALUES`
values in all (a "billion laughs" file), a value Python refuses to construct (a 5000-digit
integer, the 30th of February) and a character YAML forbids (a NUL byte): each is an error at
its line and column, never a traceback. :func:`yaml_reader` is ruamel's round-trip reader (it
keeps positions) with the guards; :func:`safe_load` is PyYAML's ``safe_load`` with the same
guards; :func:`yaml_error` turns what either raises into a :class:`~rasm.errors.SourceError`.
"""

from __future__ import annotations

from typing import Any

import yaml as pyyaml
from ruamel.yaml import YAML
from ruamel.yaml.composer import Composer, ComposerError
from ruamel.yaml.constructor import RoundTripConstructor
from ruamel.yaml.error import MarkedYAMLError, YAMLError
from ruamel.yaml.events import AliasEvent
from ruamel.yaml.reader import ReaderError

from rasm.errors import Location, SourceError, mark

__all__ = [
    "MAX_ALIAS_VALUES", "MAX_DEPTH", "document_start", "safe_load", "yaml_error", "yaml_reader",
]

MAX_DEPTH = 100  # mappings and lists inside each other; a chart's state takes two levels
MAX_ALIAS_VALUES = 100_000  # values that aliases (*name) may repeat, all aliases together

_TOO_DEEP = f"nested more than {MAX_DEPTH} levels deep (mappings and lists inside each other)"
_TOO_MANY = f"aliases repeat more than {MAX_ALIAS_VALUES} values (an alias of aliases?)"


class _Refused(ComposerError):
    """A document refused by a guard of this module (not a syntax error)."""


class _PyRefused(pyyaml.composer.ComposerError):
    """:class:`_Refused` for PyYAML."""


def _size(node: Any, sizes: dict[int, int]) -> int:
    """How many values ``node`` stands for once its aliases are expanded (each node counted
    once per path to it; a node that contains itself counts once)."""
    known = sizes.get(id(node))
    if known is not None:
        return known
    sizes[id(node)] = 1  # while counting: a cycle back to this node adds one
    total = 1
    if isinstance(node.value, list):
        for item in node.value:
            for part in item if isinstance(item, tuple) else (item,):  # (key, value) pairs
                total += _size(part, sizes)
    sizes[id(node)] = total
    return total


class _Guard:
    """Depth and alias accounting shared by the ruamel and PyYAML composers below."""

    def __init__(self) -> None:
        self.depth = 0
        self.repeated = 0
        self.sizes: dict[int, int] = {}

    def alias(self, node: Any, mark_: Any, error: type[Exception]) -> None:
        if node is not None:
            self.repeated += _size(node, self.sizes)
            if self.repeated > MAX_ALIAS_VALUES:
                raise error(None, None, _TOO_MANY, mark_)

    def enter(self, mark_: Any, error: type[Exception]) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise error(None, None, _TOO_DEEP, mark_)


def _value_problem(node: Any, exc: Exception) -> str:
    if not isinstance(node.value, str):  # a mapping or a list with a tag it cannot have
        return f"cannot build a {node.tag} from this {node.id}: {exc}"
    text = node.value
    if "integer string conversion" in str(exc):  # Python's guard against quadratic int()
        return f"integer with {len(text)} digits is too long (at most 4300)"
    shown = text if len(text) <= 40 else text[:37] + "..."
    return f"cannot read the value {shown!r} ({node.tag}): {exc}"


class _GuardedComposer(Composer):
    """ruamel's composer (recursive, one level per nesting level) with the guards."""

    def __init__(self, loader: Any = None) -> None:
        super().__init__(loader=loader)
        self._guard = _Guard()

    def compose_node(self, parent: Any, index: Any) -> Any:
        event = self.parser.peek_event()
        if isinstance(event, AliasEvent):
            self._guard.alias(self.anchors.get(event.anchor), event.start_mark, _Refused)
            return super().compose_node(parent, index)
        self._guard.enter(event.start_mark, _Refused)
        try:
            return super().compose_node(parent, index)
        finally:
            self._guard.depth -= 1


class _GuardedConstructor(RoundTripConstructor):
    """ruamel's round-trip constructor; a value that cannot be built is an error at its node."""

    def construct_object(self, node: Any, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep=deep)
        except YAMLError:
            raise
        except Exception as exc:  # int() of 5000 digits, 2021-02-30, !!set on a scalar, ...
            raise _Refused(None, None, _value_problem(node, exc), node.start_mark) from None


def yaml_reader(*, preserve_quotes: bool = False) -> YAML:
    """ruamel's round-trip reader (positions kept) with the guards of this module."""
    reader = YAML(typ="rt")
    reader.Composer = _GuardedComposer
    reader.Constructor = _GuardedConstructor
    reader.preserve_quotes = preserve_quotes
    return reader


def _position(text: str, index: int) -> tuple[int, int]:
    """1-based line and column of the character at ``index`` of ``text``."""
    before = text[:index]
    return before.count("\n") + 1, index - (before.rfind("\n") + 1) + 1


def document_start(text: str) -> tuple[int, int]:
    """1-based line and column where a document's content starts: its first line that is not
    blank, a comment, a directive or the ``---`` marker (1, 1 for an empty document). Where a
    problem with the whole document (a number where a mapping belongs) is reported."""
    for number, line in enumerate(text.splitlines(), start=1):
        content = line.strip()
        if content and not content.startswith(("#", "%")) and content != "---":
            return number, len(line) - len(line.lstrip()) + 1
    return 1, 1


def yaml_error(exc: Exception, text: str, file: str) -> SourceError:
    """The :class:`SourceError` for an error of ruamel or PyYAML reading ``text``."""
    if isinstance(exc, ReaderError | pyyaml.reader.ReaderError) and isinstance(
        exc.position, int
    ):
        line, col = _position(text, exc.position)
        char = exc.character if isinstance(exc.character, int) else ord(str(exc.character)[:1])
        message = f"character U+{char:04X} is not allowed in a YAML file"
        return SourceError(message, Location(file, line, col), mark(text, line, col))
    if isinstance(exc, MarkedYAMLError | pyyaml.MarkedYAMLError):
        mark_ = exc.problem_mark or exc.context_mark
        problem = exc.problem or exc.context or "invalid YAML"
        if not isinstance(exc, _Refused | _PyRefused):
            problem = f"YAML syntax error: {problem}"
        if mark_ is None:
            return SourceError(problem, Location(file))
        location = Location(file, mark_.line + 1, mark_.column + 1)
        return SourceError(problem, location, mark(text, location.line, location.col))
    return SourceError(f"YAML error: {exc}", Location(file))


class _GuardedSafeLoader(pyyaml.SafeLoader):
    """PyYAML's safe loader with the guards of this module."""

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._guard = _Guard()

    def compose_node(self, parent: Any, index: Any) -> Any:
        event = self.peek_event()
        if isinstance(event, pyyaml.AliasEvent):
            self._guard.alias(self.anchors.get(event.anchor), event.start_mark, _PyRefused)
            return super().compose_node(parent, index)
        self._guard.enter(event.start_mark, _PyRefused)
        try:
            return super().compose_node(parent, index)
        finally:
            self._guard.depth -= 1

    def construct_object(self, node: Any, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep=deep)
        except pyyaml.YAMLError:
            raise
        except Exception as exc:  # as in _GuardedConstructor
            raise _PyRefused(None, None, _value_problem(node, exc), node.start_mark) from None


def safe_load(text: str) -> Any:
    """``yaml.safe_load(text)`` (PyYAML) with the guards of this module: a problem raises
    ``yaml.YAMLError`` with its mark, which :func:`yaml_error` turns into a :class:`SourceError`."""
    return pyyaml.load(text, Loader=_GuardedSafeLoader)  # noqa: S506 - a SafeLoader subclass
