"""rasm.spec: the temporal property language (SPEC §5, §6).

``parse_expression``, ``infer_types``, ``evaluate`` and ``compile_expression`` form the
non-temporal expression sub-language that the legitimacy rules share.
"""

from rasm.spec.ast import (
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
from rasm.spec.expr import compile_expression, evaluate
from rasm.spec.parser import parse_expression
from rasm.spec.types import Typing, infer_types

__all__ = [
    "Aggregate",
    "Binary",
    "Bound",
    "Call",
    "Expr",
    "Future",
    "Literal",
    "Name",
    "Not",
    "Past",
    "Prev",
    "Since",
    "Time",
    "Typing",
    "Unary",
    "Until",
    "compile_expression",
    "evaluate",
    "infer_types",
    "parse_expression",
]
