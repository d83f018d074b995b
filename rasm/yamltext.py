"""The one YAML reader: charts, manifests, rules, models, topic maps and packages alike.

YAML is read exactly as sismic reads it: YAML 1.2 with ruamel (``on``, ``off``, ``yes`` and
``no`` stay strings), with the round-trip loader, which records where every mapping, key and
scalar is written, so that every problem is reported at its line and column
(:class:`YamlSource`).

Every YAML file rasm reads is someone's input, nobody has vetted it. The guards: nesting deeper
than :data:`MAX_DEPTH` levels (the reader recurses once per level, and Python's recursion would
give out), aliases that repeat more than :data:`MAX_ALIAS_VALUES` values in all (a "billion
laughs" file), a value Python refuses to construct (a 5000-digit integer, the 30th of February)
and a character YAML forbids (a NUL byte): each is an error at its line and column, never a
traceback. :func:`load_yaml` raises them, and YAML syntax errors, as
:class:`~rasm.errors.SourceError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.composer import Composer, ComposerError
from ruamel.yaml.constructor import RoundTripConstructor
from ruamel.yaml.error import MarkedYAMLError, YAMLError
from ruamel.yaml.events import AliasEvent
from ruamel.yaml.reader import ReaderError
from ruamel.yaml.scalarbool import ScalarBoolean
from ruamel.yaml.scalarstring import FoldedScalarString, LiteralScalarString

from rasm.errors import Location, SourceError, mark

__all__ = ["MAX_ALIAS_VALUES", "MAX_DEPTH", "YamlSource", "document_start", "load_yaml", "plain"]

MAX_DEPTH = 100  # mappings and lists inside each other; a chart's state takes two levels
MAX_ALIAS_VALUES = 100_000  # values that aliases (*name) may repeat, all aliases together

_TOO_DEEP = f"nested more than {MAX_DEPTH} levels deep (mappings and lists inside each other)"
_TOO_MANY = f"aliases repeat more than {MAX_ALIAS_VALUES} values (an alias of aliases?)"


class _Refused(ComposerError):
    """A document refused by a guard of this module (not a syntax error)."""


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
    """Depth and alias accounting of one document."""

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


def _reader(*, preserve_quotes: bool = False) -> YAML:
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


def _yaml_error(exc: Exception, text: str, file: str) -> SourceError:
    """The :class:`SourceError` for an error of ruamel reading ``text``."""
    if isinstance(exc, ReaderError) and isinstance(exc.position, int):
        line, col = _position(text, exc.position)
        char = exc.character if isinstance(exc.character, int) else ord(str(exc.character)[:1])
        message = f"character U+{char:04X} is not allowed in a YAML file"
        return SourceError(message, Location(file, line, col), mark(text, line, col))
    if isinstance(exc, MarkedYAMLError):
        mark_ = exc.problem_mark or exc.context_mark
        problem = exc.problem or exc.context or "invalid YAML"
        if not isinstance(exc, _Refused):
            problem = f"YAML syntax error: {problem}"
        if mark_ is None:
            return SourceError(problem, Location(file))
        location = Location(file, mark_.line + 1, mark_.column + 1)
        return SourceError(problem, location, mark(text, location.line, location.col))
    return SourceError(f"YAML error: {exc}", Location(file))


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
        """Where the document's content starts (see :func:`document_start`)."""
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


def load_yaml(text: str, file: str, *, preserve_quotes: bool = False) -> YamlSource:
    """Read YAML 1.2 ``text`` (from ``file``), keeping positions; a syntax error, or a document
    a guard refuses, raises :class:`SourceError` at its place. With ``preserve_quotes``, a
    quoted scalar says how it was quoted (its type), for positions inside it."""
    try:
        data = _reader(preserve_quotes=preserve_quotes).load(text)
    except YAMLError as exc:
        raise _yaml_error(exc, text, file) from None
    return YamlSource(data, text, file)


def plain(value: Any) -> Any:
    """A copy of what ruamel read as plain Python: dicts with str keys, lists, str, bool, int
    and float (ruamel's own classes keep how a value was written: ``0o17``, ``1.50``)."""
    if isinstance(value, CommentedMap | dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, CommentedSeq | list):
        return [plain(v) for v in value]
    if isinstance(value, str):
        return str(value)
    if isinstance(value, ScalarBoolean):  # an anchored boolean: an int to Python
        return bool(value)
    if isinstance(value, int) and not isinstance(value, bool):
        return int(value)
    if isinstance(value, float):
        return float(value)
    return value
