"""rasm.properties: the temporal property language and its monitors.

``compile_properties(text)`` turns a property file into an incremental :class:`Monitor`;
``load_specification`` gives the checked syntax tree.

``parse_expression``, ``infer_types``, ``evaluate`` and ``compile_expression`` form the
non-temporal expression sub-language that the legitimacy rules share.
"""

from rasm.properties.ast import (
    Aggregate,
    Binary,
    Bound,
    Call,
    Expr,
    Future,
    Literal,
    Name,
    Not,
    Past,
    Prev,
    Since,
    Time,
    Unary,
    Until,
)
from rasm.properties.expr import compile_expression, evaluate
from rasm.properties.loader import load_specification
from rasm.properties.monitor import Monitor, PropertyRun, Rejection, Verdict, compile_properties
from rasm.properties.types import Typing, infer_types

__all__ = [
    "Aggregate",
    "Binary",
    "Bound",
    "Call",
    "Expr",
    "Future",
    "Literal",
    "Monitor",
    "Name",
    "Not",
    "Past",
    "Prev",
    "PropertyRun",
    "Rejection",
    "Since",
    "Time",
    "Typing",
    "Unary",
    "Until",
    "Verdict",
    "compile_properties",
    "compile_expression",
    "evaluate",
    "infer_types",
    "load_specification",
    "parse_expression",
]


def __getattr__(name: str) -> object:
    # the parser (and lark) load on first use: a command on a cached property file needs none
    if name == "parse_expression":
        from rasm.properties.parser import parse_expression

        return parse_expression
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
