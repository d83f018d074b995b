"""From a property file to a checked :class:`~rasm.properties.ast.Specification`.

Resolves ``let`` names (each use stands for the definition above it), strips the outermost
unbounded ``always`` of each property, rejects any other unbounded ``always``, and type-checks
all properties together so that a signal has one type in the whole file.
"""

from __future__ import annotations

import os
import pickle
import sys
import zlib
from dataclasses import replace
from pathlib import Path, PurePath

from rasm.errors import SourceError, mark
from rasm.properties.ast import (
    INF,
    Event,
    Expr,
    Future,
    Input,
    Let,
    Name,
    Property,
    Specification,
    children,
    rebuild,
    walk,
)
from rasm.properties.cache import cache_folder, trusted
from rasm.properties.types import TypeScope

__all__ = ["cached_specification", "load_specification", "signals_of"]

# Deeper formulas would overflow Python's parser (200 nested parentheses) in the generated
# monitor, or its recursion limit in the passes over the tree: refuse them with their place.
MAX_DEPTH = 150


def load_specification(text: str, *, source: str = "<text>") -> Specification:
    """Parse and check a property file; raises :class:`SourceError` at the first problem."""
    if not isinstance(text, str):
        hint = (
            f" (for a file: compile_properties(Path({str(text)!r}).read_text(),"
            f" source={str(text)!r}))"
            if isinstance(text, PurePath)
            else " (decode it first: text.decode('utf-8'))"
            if isinstance(text, bytes | bytearray)
            else ""
        )
        raise TypeError(
            f"a property specification is the text of a .rv file, not {type(text).__name__}" + hint
        )
    try:
        return _load(text, source)
    except RecursionError:
        raise SourceError(
            f"formulas nested too deeply (at most {MAX_DEPTH} levels)", _origin(source)
        ) from None
    except SourceError as error:
        if error.excerpt is None and error.location.file == source:
            error.excerpt = mark(text, error.location.line, error.location.col)
        raise


SLOTS = 64  # specifications kept in the cache folder


def cached_specification(text: str, source: str) -> Specification:
    """:func:`load_specification` of a property file ``source`` whose text is ``text``, kept
    in the user's cache folder for the next command on the same file: unchanged, it is read
    back, without building the parser (or loading lark) or parsing again.

    An entry per file name, rewritten when the text changes; read back only if its text, its
    name and the code that made it (:func:`_stamp`) are those of this call. A file that does
    not load raises each time, as :func:`load_specification` does.
    """
    folder = cache_folder()
    # at most SLOTS entries, whatever the files and test runs: two names in one slot take turns
    slot = zlib.crc32(source.encode()) % SLOTS
    path = None if folder is None else folder / f"spec-{slot:02d}.pickle"
    stamp = (_stamp(), text, source)
    if path is not None:
        try:
            with path.open("rb") as handle:
                if trusted(os.fstat(handle.fileno())):
                    kept, spec = pickle.load(handle)
                    if kept == stamp and isinstance(spec, Specification):
                        return spec
        except Exception:  # missing, unreadable, stale (a class renamed): load it afresh
            pass
    spec = load_specification(text, source=source)
    if path is not None:
        try:
            fresh = path.with_suffix(f".{os.getpid()}")
            with open(os.open(fresh, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600), "wb") as out:
                pickle.dump((stamp, spec), out, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(fresh, path)  # whole or not at all, for a command running beside
        except OSError:
            pass
    return spec


def _stamp() -> tuple:
    """What a cached specification depends on besides its text: Python, lark, and the size
    and time of change of each source file of the property language and the modules it uses
    (as Python's own bytecode cache does)."""
    from importlib.util import find_spec

    here = Path(__file__).parent
    lark = find_spec("lark")
    files = [*sorted(here.glob("*.py")), here / "grammar.lark", here.parent / "times.py",
             here.parent / "errors.py", *([Path(lark.origin)] if lark and lark.origin else [])]
    stats = [(file.name, file.stat()) for file in files]
    return sys.version, tuple((name, info.st_size, info.st_mtime_ns) for name, info in stats)


def _load(text: str, source: str) -> Specification:
    from rasm.properties.parser import parse_declarations  # here: a cached file needs no lark

    declarations = parse_declarations(text, source=source)
    inputs: list[Input] = []
    events: list[Event] = []
    lets: dict[str, Let] = {}
    properties: list[Property] = []
    defined: dict[str, object] = {}  # every declared name -> its declaration
    used_as_signal: dict[str, Name] = {}

    def define(name: str, item) -> None:
        if name in defined:
            raise SourceError(
                f"{name!r} is already defined at {defined[name].location}", item.location
            )
        if name in used_as_signal and not isinstance(item, (Input, Event)):
            raise SourceError(
                f"{name!r} is defined here but was already used as a signal at "
                f"{used_as_signal[name].location}; define it before its first use",
                item.location,
            )
        defined[name] = item

    def expand(node: Expr, defining: str | None = None) -> Expr:
        if isinstance(node, Name):
            if node.name in lets:
                return lets[node.name].expr
            if node.name == defining:
                raise SourceError(f"let {defining!r} refers to itself", node.location)
            used_as_signal.setdefault(node.name, node)
            return node
        return rebuild(node, [expand(c, defining) for c in children(node)])

    def shallow(root: Expr, what: str, where) -> Expr:
        depth, stack = 0, [(root, 1)]
        while stack:
            node, level = stack.pop()
            depth = max(depth, level)
            stack.extend((c, level + 1) for c in children(node))
        if depth > MAX_DEPTH:
            raise SourceError(
                f"{what} is nested {depth} levels deep (lets expanded), more than the "
                f"{MAX_DEPTH} a monitor can compile",
                where,
            )
        return root

    scope_declared: dict[str, str] = {}
    for item in declarations:
        if isinstance(item, Input):
            define(item.name, item)
            inputs.append(item)
            scope_declared[item.name] = item.type
        elif isinstance(item, Event):
            define(item.name, item)
            events.append(item)
            scope_declared[item.name] = "bool"
    scope = TypeScope(scope_declared)

    property_names: dict[str, Property] = {}
    for item in declarations:
        if isinstance(item, Let):
            define(item.name, item)
            shallow(item.expr, f"let {item.name!r}", item.location)
            body = shallow(expand(item.expr, item.name), f"let {item.name!r}", item.location)
            _check_always(body)
            scope.check(body)
            lets[item.name] = replace(item, expr=body)
        elif isinstance(item, Property):
            if item.name in property_names:
                raise SourceError(
                    f"property {item.name!r} is already defined at "
                    f"{property_names[item.name].location}",
                    item.location,
                )
            where = f"property {item.name!r}"
            shallow(item.formula, where, item.location)
            formula = shallow(expand(item.formula), where, item.location)
            formula = _strip_always(formula)
            _check_always(formula)
            scope.check(formula, "bool")
            properties.append(replace(item, formula=formula))
            property_names[item.name] = item
    if not properties:
        raise SourceError(
            "no property in this file (write: property NAME: FORMULA)", _origin(source)
        )
    signals = {
        name: kind
        for name, kind in scope.signals().items()
        if name not in lets
    }
    for item in inputs:
        signals.setdefault(item.name, item.type)
    for item in events:
        signals[item.name] = "bool"
    return Specification(
        source=source,
        inputs=tuple(inputs),
        events=tuple(events),
        lets=tuple(lets.values()),
        properties=tuple(properties),
        signals=signals,
    )


def _origin(source: str):
    from rasm.errors import Location

    return Location(source, 1, 1)


def _strip_always(formula: Expr) -> Expr:
    # "always φ" outermost, unbounded: φ is judged at every record anyway
    if (
        isinstance(formula, Future)
        and formula.op == "always"
        and formula.bound.low == 0
        and formula.bound.high == INF
    ):
        return formula.operand
    return formula


def _check_always(formula: Expr) -> None:
    for node in walk(formula):
        if isinstance(node, Future) and node.bound.high == INF:
            raise SourceError(
                "an unbounded 'always' is allowed only as the outermost operator of a property; "
                "give it a bound, always[a, b]",
                node.location,
            )


def signals_of(node: Expr) -> list[str]:
    """The signal names ``node`` reads, in order of first appearance."""
    return list(dict.fromkeys(n.name for n in walk(node) if isinstance(n, Name)))
