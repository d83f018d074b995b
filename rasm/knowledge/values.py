"""Value types of the knowledge base: declarations and the checks that guard every write.

Five types: ``float``, ``int``, ``bool``, ``str`` and ``json`` (any JSON value: plans, scans as
lists, dicts with string keys). A check turns an accepted value into its canonical form (an int
given for a float becomes a float; a JSON value becomes a fresh copy as JSON would give it back)
so that what is read from memory equals what a restore from disk gives back.
"""

from __future__ import annotations

import json
import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rasm.errors import KnowledgeError

TYPES: tuple[str, ...] = ("float", "int", "bool", "str", "json")
"""The value types a key may be declared with."""

DEFAULT_HISTORY = 1000
"""Samples kept in memory per key when a declaration does not say."""

Check = Callable[[Any], Any]
"""Turns an accepted value into its canonical form, or raises :class:`KnowledgeError`."""


@dataclass(frozen=True)
class Declaration:
    """What a key holds: its type, how many samples are kept, optional numeric bounds."""

    key: str
    type: str
    history: int = DEFAULT_HISTORY
    minimum: float | int | None = None
    maximum: float | int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.key, str) or not self.key:
            raise KnowledgeError(f"a knowledge key must be a non-empty string, got {self.key!r}")
        if self.type not in TYPES:
            raise KnowledgeError(
                f"knowledge {self.key!r}: unknown type {self.type!r}; use one of {', '.join(TYPES)}"
            )
        if isinstance(self.history, bool) or not isinstance(self.history, int) or self.history < 1:
            raise KnowledgeError(
                f"knowledge {self.key!r}: history must be a whole number >= 1, got {self.history!r}"
            )
        for name in ("minimum", "maximum"):
            bound = getattr(self, name)
            if bound is None:
                continue
            if self.type not in ("float", "int"):
                raise KnowledgeError(
                    f"knowledge {self.key!r}: {name} applies only to float and int keys, "
                    f"not {self.type}"
                )
            if not _is_number(bound) or math.isnan(bound):
                raise KnowledgeError(
                    f"knowledge {self.key!r}: {name} must be a number, got {bound!r}"
                )
        if self.minimum is not None and self.maximum is not None and self.minimum > self.maximum:
            raise KnowledgeError(
                f"knowledge {self.key!r}: minimum {self.minimum!r} "
                f"is above maximum {self.maximum!r}"
            )


def _is_number(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _describe(value: object) -> str:
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{type(value).__name__} {text}"


def mismatch(key: str, expected: str, value: object, hint: str = "") -> KnowledgeError:
    """The error for a value of the wrong type: names the key, the expected type and what came."""
    message = f"knowledge {key!r}: expected {expected}, got {_describe(value)}"
    return KnowledgeError(message + (f" ({hint})" if hint else ""))


def infer_type(value: object) -> str:
    """The type an undeclared key takes from its first value."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, numbers.Integral):
        return "int"
    if isinstance(value, numbers.Real):
        return "float"
    if isinstance(value, str):
        return "str"
    return "json"


def make_check(decl: Declaration) -> Check:
    """Build the check of one declaration (a closure: the hot path does no dictionary lookups)."""
    key, kind = decl.key, decl.type
    if kind == "float":
        return _number_check(key, decl, float, numbers.Real)
    if kind == "int":
        return _number_check(key, decl, int, numbers.Integral)
    if kind == "bool":

        def check_bool(value: Any) -> Any:
            if value is True or value is False:
                return value
            raise mismatch(key, "bool", value)

        return check_bool
    if kind == "str":

        def check_str(value: Any) -> Any:
            if type(value) is str:
                return value
            if isinstance(value, str):
                return str(value)  # a str subclass is stored as a plain str, as disk gives back
            raise mismatch(key, "str", value)

        return check_str

    def check_json(value: Any) -> Any:
        # One encode both proves the value is JSON and makes the canonical copy that readers
        # share: later changes to the caller's list or dict cannot rewrite history.
        try:
            return json.loads(json.dumps(value))
        except (TypeError, ValueError, RecursionError) as exc:
            raise mismatch(
                key,
                "a JSON value",
                value,
                "None, bool, numbers, str, lists and dicts with str keys; "
                "convert arrays with .tolist()",
            ) from exc

    return check_json


def _number_check(key: str, decl: Declaration, convert: type, abstract: type) -> Check:
    kind = decl.type
    lo, hi = decl.minimum, decl.maximum

    def check(value: Any) -> Any:
        if type(value) is not convert:
            if isinstance(value, bool) or not isinstance(value, abstract):
                # bool is an int to Python, never here: True is not a count or a velocity
                raise mismatch(key, kind, value)
            try:
                value = convert(value)
            except (OverflowError, ValueError) as exc:
                raise mismatch(key, kind, value, str(exc)) from exc
        # written as "not (x >= lo)" so that NaN is out of any declared range
        if lo is not None and not value >= lo:
            raise KnowledgeError(f"knowledge {key!r}: {value!r} is below its minimum {lo!r}")
        if hi is not None and not value <= hi:
            raise KnowledgeError(f"knowledge {key!r}: {value!r} is above its maximum {hi!r}")
        return value

    return check


def encode(value: Any) -> str:
    """The JSON text a value is stored as (Python's dialect: NaN and Infinity allowed)."""
    return json.dumps(value, separators=(",", ":"))


def decode(text: str) -> Any:
    """The value back from :func:`encode`'s text."""
    return json.loads(text)
