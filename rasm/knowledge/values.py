"""Declarations of the knowledge base and the checks that guard every write.

Five types: ``float``, ``int``, ``bool``, ``str`` and ``json`` (any JSON value: plans, scans as
lists, dicts with string keys), checked by :func:`rasm.values.fit`. A check turns an accepted
value into the form it is kept in (an int given for a float becomes a float; a JSON value becomes
a fresh copy as JSON would give it back) so that what is read from memory equals what a restore
from disk gives back.
"""

from __future__ import annotations

import json
import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rasm.errors import KnowledgeError, Misfit
from rasm.values import TYPES, fit, infer_type

__all__ = [
    "DEFAULT_HISTORY", "TYPES", "Check", "Declaration", "decode", "encode",
    "infer_type", "make_check",
]

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


def make_check(decl: Declaration) -> Check:
    """The check of one declaration: :func:`rasm.values.fit` with its type and bounds."""
    key, kind, low, high = decl.key, decl.type, decl.minimum, decl.maximum

    def check(value: Any) -> Any:
        try:
            return fit(value, kind, minimum=low, maximum=high)
        except Misfit as misfit:
            raise KnowledgeError(f"knowledge {key!r}: {misfit}") from None

    return check


# one encoder for every call: json.dumps with options builds a new one each time, which cost more
# than the encoding of a flush's batch
_ENCODER = json.JSONEncoder(separators=(",", ":"))


def encode(value: Any) -> str:
    """The JSON text a value is stored as (Python's dialect: NaN and Infinity allowed)."""
    return _ENCODER.encode(value)


def decode(text: str) -> Any:
    """The value back from :func:`encode`'s text."""
    return json.loads(text)
