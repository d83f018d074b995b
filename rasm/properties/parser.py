"""From text to syntax tree: the lark grammar (``grammar.lark``) and a Transformer.

Both entry points raise :class:`~rasm.errors.SourceError` with the user's file, line and column
and a marked excerpt. ``line``/``col`` shift every position, so that an expression embedded in
another file (a YAML scalar of a rules file) reports places in that file.
"""

from __future__ import annotations

import ast as python_ast
import hashlib
import math
from functools import lru_cache
from pathlib import Path

from lark import Lark, Token, Transformer, Tree, v_args
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from rasm.errors import Location, SourceError, mark
from rasm.properties.ast import (
    INF,
    Aggregate,
    Binary,
    Bound,
    Call,
    Declaration,
    Event,
    Expr,
    Future,
    Input,
    Let,
    Literal,
    Name,
    Not,
    Past,
    Prev,
    Property,
    Since,
    Time,
    Unary,
    Until,
)
from rasm.properties.cache import cache_folder, trusted
from rasm.properties.times import bound_nanoseconds, format_nanoseconds

__all__ = ["parse_declarations", "parse_expression"]

UNITS = {"ms": 1e-3, "s": 1.0, "min": 60.0}
TYPES = ("float", "int", "bool", "str")

# how lark names terminals, and how a user would call them
_TOKEN_NAMES = {
    "NAME": "a name",
    "NUMBER": "a number",
    "STRING": "a string",
    "AGGREGATE": "count/sum/avg/min/max",
    "$END": "end of input",
    "LPAR": "'('",
    "RPAR": "')'",
    "LSQB": "'['",
    "RSQB": "']'",
    "COMMA": "','",
    "COLON": "':'",
}


@lru_cache(maxsize=2)
def _parser(start: str) -> Lark:
    grammar = (Path(__file__).with_name("grammar.lark")).read_text(encoding="utf-8")
    return Lark(grammar, parser="lalr", start=start, propagate_positions=True,
                cache=_cache_file(grammar, start))


def _cache_file(grammar: str, start: str) -> str | bool:
    """Where lark keeps the parser it built: building its tables takes longer than the rest of
    ``rasm lint`` on a small file. A file in the user's cache folder, which lark rebuilds when
    the grammar, lark or Python changed; False (no cache) where there is none to trust."""
    folder = cache_folder()
    if folder is None:
        return False
    digest = hashlib.sha256(grammar.encode("utf-8")).hexdigest()[:16]
    path = folder / f"properties-{start}-{digest}.lark"
    try:
        if path.exists() and not trusted(path.stat()):
            return False
    except OSError:
        return False
    return str(path)


class _Place:
    """Maps positions in the parsed text to the user's file."""

    def __init__(self, text: str, source: str, line: int, col: int) -> None:
        self.text, self.source, self.line, self.col = text, source, line, col

    def location(self, line: int, col: int) -> Location:
        if line == 1:
            return Location(self.source, self.line, self.col + col - 1)
        return Location(self.source, self.line + line - 1, col)

    def error(self, message: str, line: int, col: int, width: int = 1) -> SourceError:
        return SourceError(message, self.location(line, col), mark(self.text, line, col, width))


def _describe(token_type: str, start: str) -> str:
    if token_type in _TOKEN_NAMES:
        return _TOKEN_NAMES[token_type]
    try:
        pattern = _parser(start).get_terminal(token_type).pattern
    except KeyError:
        return token_type.lower()
    if pattern.type == "str":
        return repr(pattern.value)
    return token_type.lower()


def _end_position(text: str) -> tuple[int, int]:
    lines = text.rstrip().splitlines() or [""]
    return len(lines), len(lines[-1]) + 1


def _syntax_error(exc: UnexpectedInput, place: _Place, start: str) -> SourceError:
    if isinstance(exc, UnexpectedToken):
        token = exc.token
        expected = sorted({_describe(t, start) for t in exc.accepts or exc.expected})
        if "a name" in expected:  # a whole expression fits here: say so, not 20 token names
            expected = [e for e in expected if e in ("')'", "','", "']'")] + ["an expression"]
        hint = f"; expected {', '.join(expected[:8])}" if expected else ""
        if token.type == "$END":
            line, col = _end_position(place.text)
            return place.error("unexpected end of input" + hint, line, col)
        return place.error(
            f"unexpected {token.value!r}{hint}", token.line, token.column, len(str(token.value))
        )
    if isinstance(exc, UnexpectedCharacters):
        char = place.text[exc.pos_in_stream] if exc.pos_in_stream < len(place.text) else "?"
        return place.error(f"unexpected character {char!r}", exc.line, exc.column)
    if isinstance(exc, UnexpectedEOF):
        return place.error("unexpected end of input", *_end_position(place.text))
    return place.error(str(exc), getattr(exc, "line", 1) or 1, getattr(exc, "column", 1) or 1)


@v_args(meta=True, inline=True)
class _Build(Transformer):
    """Turns lark's tree into ``rasm.properties.ast`` nodes; one method per grammar rule."""

    def __init__(self, place: _Place, temporal: bool) -> None:
        super().__init__()
        self.place = place
        self.temporal = temporal

    # ----------------------------------------------------------------- helpers
    def _loc(self, meta) -> Location:
        if getattr(meta, "empty", True):
            return self.place.location(1, 1)
        return self.place.location(meta.line, meta.column)

    def _error(self, message: str, meta) -> SourceError:
        if getattr(meta, "empty", True):
            return self.place.error(message, 1, 1)
        width = meta.end_column - meta.column if meta.end_line == meta.line else 1
        return self.place.error(message, meta.line, meta.column, max(width, 1))

    def _token_error(self, message: str, token: Token) -> SourceError:
        return self.place.error(message, token.line, token.column, len(token.value))

    def _finite_number(self, token: Token) -> int | float:
        """The number ``token`` spells, refused if a float cannot hold it (1e999, 10**400)."""
        value = _number(token.value)
        try:
            finite = math.isfinite(value)
        except OverflowError:
            finite = False
        if not finite:
            text = token.value if len(token.value) <= 24 else token.value[:20] + "…"
            raise self._token_error(
                f"number {text} is too large (the largest is about 1.8e308)", token
            )
        return value

    def _string(self, token: Token) -> str:
        """The text a string literal spells (Python's escapes), refused with its position when
        it holds a NUL character or an escape Python cannot decode."""
        nul = token.value.find("\0")
        if nul >= 0:
            raise self.place.error(
                "a NUL character cannot be written in a string (write \\x00 to mean one)",
                token.line,
                token.column + nul,
            )
        try:
            return python_ast.literal_eval(token.value)
        except (SyntaxError, ValueError) as exc:
            problem = getattr(exc, "msg", None) or str(exc)
            raise self._token_error(f"invalid string literal: {problem}", token) from None

    def _no_temporal(self, meta, what: str) -> None:
        if not self.temporal:
            raise self._error(f"temporal operator not allowed here ({what})", meta)

    # ----------------------------------------------------------------- declarations
    def start(self, meta, *items):
        return list(items)

    def expression(self, meta, formula):
        return formula

    def input_decl(self, meta, name, type_name, default):
        if type_name.value not in TYPES:
            raise self._token_error(
                f"unknown type {type_name.value!r}; use float, int, bool or str", type_name
            )
        if default is not None:
            value, where = default
            kind = type(value).__name__
            ok = {
                "float": kind in ("int", "float"),
                "int": kind == "int",
                "bool": kind == "bool",
                "str": kind == "str",
            }[type_name.value]
            if not ok:
                raise self._error(
                    f"default {value!r} is not of type {type_name.value} "
                    f"(input {name.value!r})",
                    where,
                )
            if type_name.value == "float":
                value = float(value)
        else:
            value = None
        return Input(name.value, type_name.value, value, location=self._loc(meta))

    def event_decl(self, meta, *names):
        return [
            Event(n.value, location=self.place.location(n.line, n.column)) for n in names
        ]

    def let_decl(self, meta, name, formula):
        return Let(name.value, formula, location=self.place.location(name.line, name.column))

    def property_decl(self, meta, name, formula):
        return Property(name.value, formula, location=self.place.location(name.line, name.column))

    def default_number(self, meta, token):
        return (self._finite_number(token), meta)

    def default_negative(self, meta, token):
        return (-self._finite_number(token), meta)

    def default_string(self, meta, token):
        return (self._string(token), meta)

    def default_true(self, meta):
        return (True, meta)

    def default_false(self, meta):
        return (False, meta)

    # ----------------------------------------------------------------- boolean
    def implies(self, meta, left, right):
        return Binary("->", left, right, location=self._loc(meta))

    def or_(self, meta, left, right):
        return Binary("or", left, right, location=self._loc(meta))

    def and_(self, meta, left, right):
        return Binary("and", left, right, location=self._loc(meta))

    def not_(self, meta, operand):
        return Not(operand, location=self._loc(meta))

    # ----------------------------------------------------------------- temporal
    def since(self, meta, left, bound, right):
        self._no_temporal(meta, "since")
        return Since(left, right, bound or Bound(0.0, INF), location=self._loc(meta))

    def until(self, meta, left, bound, right):
        self._no_temporal(meta, "until")
        if bound is None:
            raise self._error(
                "'until' needs a bound: until[a, b] (a future window is finite)", meta
            )
        self._finite(bound, "until", meta)
        return Until(left, right, bound, location=self._loc(meta))

    def once(self, meta, bound, operand):
        self._no_temporal(meta, "once")
        return Past("once", bound or Bound(0.0, INF), operand, location=self._loc(meta))

    def historically(self, meta, bound, operand):
        self._no_temporal(meta, "historically")
        return Past("historically", bound or Bound(0.0, INF), operand, location=self._loc(meta))

    def eventually(self, meta, bound, operand):
        self._no_temporal(meta, "eventually")
        if bound is None:
            raise self._error(
                "'eventually' needs a bound: eventually[a, b] (a future window is finite)", meta
            )
        self._finite(bound, "eventually", meta)
        return Future("eventually", bound, operand, location=self._loc(meta))

    def always(self, meta, bound, operand):
        self._no_temporal(meta, "always")
        if bound is not None:
            self._finite(bound, "always", meta)
        # an unbounded always is checked later: only the outermost operator may be one
        return Future("always", bound or Bound(0.0, INF), operand, location=self._loc(meta))

    def _finite(self, bound: Bound, op: str, meta) -> None:
        if bound.high == INF:
            raise SourceError(
                f"a future operator cannot have an infinite bound ({op}{bound}): "
                "give a finite upper bound",
                bound.location,
                _excerpt_at(self.place, bound.location),
            )

    def aggregate(self, meta, op, bound, operand):
        self._no_temporal(meta, op.value)
        return Aggregate(op.value, bound, operand, location=self._loc(meta))

    # ----------------------------------------------------------------- bounds
    def bound(self, meta, low, high):
        # each end is (seconds, exact nanoseconds), from duration() or infinity()
        (low, low_ns), (high, high_ns) = low, high
        location = self._loc(meta)
        if low == INF:
            raise self._error("the lower bound of a window cannot be inf", meta)
        if high_ns < low_ns:
            raise self._error(
                f"empty window [{format_nanoseconds(low_ns)}, {format_nanoseconds(high_ns)}]: "
                "the upper bound is smaller than the lower",
                meta,
            )
        return Bound(low, high, location=location, low_ns=low_ns, high_ns=high_ns)

    def duration(self, meta, number, unit):
        scale = 1.0
        if unit is not None:
            if unit.value not in UNITS:
                raise self._token_error(
                    f"unknown time unit {unit.value!r}; use ms, s or min", unit
                )
            scale = UNITS[unit.value]
        value = self._finite_number(number)
        # the monitors compare exact nanoseconds, taken from the text (0.1 is 100000000 ns)
        ns = bound_nanoseconds(number.value, unit.value if unit is not None else None)
        if ns is None:
            raise self._token_error(
                f"window bound {number.value}{unit.value if unit is not None else ''} is finer "
                "than a nanosecond, the resolution of record times",
                number,
            )
        # ms divides (exact decimal rounding: 3ms == 0.003) rather than multiplying by 1e-3
        return (value / 1000 if scale == 1e-3 else value * scale), ns

    def negative_duration(self, meta, number, unit):
        raise self._error("a window bound cannot be negative", meta)

    def infinity(self, meta):
        return INF, INF

    # ----------------------------------------------------------------- arithmetic
    def compare(self, meta, left, op, right):
        return Binary(str(op.children[0]), left, right, location=self._loc(meta))

    def arith(self, meta, left, op, right):
        return Binary(str(op.children[0]), left, right, location=self._loc(meta))

    def negate(self, meta, operand):
        if isinstance(operand, Literal) and type(operand.value) in (int, float):
            return Literal(-operand.value, location=self._loc(meta))
        return Unary("-", operand, location=self._loc(meta))

    # ----------------------------------------------------------------- atoms
    def number(self, meta, token):
        return Literal(self._finite_number(token), location=self._loc(meta))

    def string(self, meta, token):
        return Literal(self._string(token), location=self._loc(meta))

    def true(self, meta):
        return Literal(True, location=self._loc(meta))

    def false(self, meta):
        return Literal(False, location=self._loc(meta))

    def time(self, meta):
        self._no_temporal(meta, "time")
        return Time(location=self._loc(meta))

    def name(self, meta, token):
        return Name(token.value, location=self._loc(meta))

    def function(self, meta, token):
        return token

    def call(self, meta, func, *args):
        args = tuple(a for a in args if a is not None)
        name = func.value
        location = self._loc(meta)
        if name == "prev":
            self._no_temporal(meta, "prev")
            if len(args) != 1:
                raise self._error(f"prev takes one argument, not {len(args)}", meta)
            return Prev(args[0], location=location)
        if name == "in_mode":
            # the managed system's modes chart writes mode_<state> (true while the state is
            # active) in the trace: in_mode("docking") reads that signal
            if len(args) != 1 or not (
                isinstance(args[0], Literal)
                and isinstance(args[0].value, str)
                and args[0].value.isidentifier()
            ):
                raise self._error(
                    'in_mode takes the name of a state of the modes chart, as in_mode("docking")',
                    meta,
                )
            return Name(f"mode_{args[0].value}", location=location)
        if name in ("count", "sum", "avg") or (name in ("min", "max") and len(args) == 1):
            # an aggregate without a window ranges over the whole past: [0, inf]
            self._no_temporal(meta, name)
            if len(args) != 1:
                raise self._error(f"{name} takes one argument, not {len(args)}", meta)
            return Aggregate(name, Bound(0.0, INF, location=location), args[0], location=location)
        return Call(name, args, location=location)


def _number(text: str) -> int | float:
    if any(c in text for c in ".eE"):
        return float(text)
    digits = text.lstrip("0") or "0"
    if len(digits) > 309:  # past the largest float; int() of a long text is slow, then refused
        return math.inf
    return int(digits)


def _excerpt_at(place: _Place, location: Location) -> str | None:
    line = location.line - place.line + 1
    col = location.col - place.col + 1 if line == 1 else location.col
    return mark(place.text, line, col)


def _parse(text: str, start: str, place: _Place, temporal: bool):
    try:
        tree = _parser(start).parse(text)
    except UnexpectedInput as exc:
        raise _syntax_error(exc, place, start) from None
    try:
        return _Build(place, temporal).transform(tree)
    except SourceError:
        raise
    except Exception as exc:  # lark wraps errors raised in callbacks
        inner = getattr(exc, "orig_exc", exc)
        if isinstance(inner, SourceError):
            raise inner from None
        if isinstance(inner, RecursionError):
            line, col = _deepest_item(tree)
            raise place.error("expression nested too deeply", line, col) from None
        if isinstance(inner, ValueError | ArithmeticError):  # a literal Python cannot convert
            meta = getattr(getattr(exc, "obj", None), "meta", None)
            line, col = (meta.line, meta.column) if meta and not meta.empty else (1, 1)
            raise place.error(f"cannot read this: {inner}", line, col) from None
        raise


def _deepest_item(tree: Tree) -> tuple[int, int]:
    """Line and column of the top-level item of ``tree`` that nests deepest (without recursing)."""
    best, where = -1, (1, 1)
    for item in tree.children if tree.data == "start" else [tree]:
        depth, stack = 0, [(item, 1)]
        while stack:
            node, level = stack.pop()
            depth = max(depth, level)
            stack.extend((c, level + 1) for c in getattr(node, "children", ()))
        meta = getattr(item, "meta", None)
        if depth > best and meta is not None and not getattr(meta, "empty", True):
            best, where = depth, (meta.line, meta.column)
    return where


def parse_expression(text: str, *, source: str = "<text>", line: int = 1, col: int = 1) -> Expr:
    """Parse one non-temporal expression (the sub-language shared with legitimacy rules).

    ``line``/``col`` say where ``text`` starts in the user's file ``source``. Temporal operators,
    ``prev`` and ``time`` raise :class:`SourceError` "temporal operator not allowed here".
    """
    place = _Place(text, source, line, col)
    return _parse(text, "expression", place, temporal=False)


def parse_declarations(text: str, *, source: str = "<text>") -> list[Declaration]:
    """Parse a property file into its declarations, in order (no type checking yet)."""
    place = _Place(text, source, 1, 1)
    items = _parse(text, "start", place, temporal=True)
    flat: list[Declaration] = []
    for item in items:
        if isinstance(item, list):
            flat.extend(item)
        else:
            flat.append(item)
    return flat
