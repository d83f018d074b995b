"""Values against their declared types: whether a value fits, the form it is kept in, why not.

Every place a value meets a declared type asks :func:`fit`: the knowledge store's declarations,
Telegraf's probe signals, the trace reader and the monitors' signals. The types:

``float``
    a real number, not a bool (an int, a float, numpy's numbers); kept as a float, or with
    ``int_as_float=False`` an integral number as an exact int (properties compare exactly).
``int``
    an integral number, not a bool; kept as an int. True is not a count or a velocity.
``bool``
    True or False (numpy's bool too); kept as a bool.
``str``
    a string; kept as a plain str.
``json``
    any JSON value; kept as a fresh copy, as JSON gives it back (later changes to the caller's
    list or dict cannot rewrite what was kept).
``any``
    a number, a string or a boolean: a property's signal whose type nothing declares.

The differences between the readers are parameters, not copies: Telegraf refuses non-finite
numbers (``finite=True``), a trace may hold them; knowledge and probes keep an int given for a
float as a float, the trace reader and the monitors keep it exact.
"""

from __future__ import annotations

import json
import math
import numbers
from typing import Any

from rasm.errors import Misfit

__all__ = ["SIGNAL_TYPES", "TYPES", "fit", "infer_type", "wanted"]

TYPES: tuple[str, ...] = ("float", "int", "bool", "str", "json")
"""The types a knowledge key or a probe signal may be declared with."""

SIGNAL_TYPES: tuple[str, ...] = ("float", "int", "bool", "str", "any")
"""The types a property's signal is read as."""

_EXPECTED = {"json": "a JSON value", "any": "a number, string or boolean"}
_WANTED = {
    "float": "a number",
    "int": "an integer",
    "bool": "true or false",
    "str": "a string",
    "json": "a JSON value",
    "any": "a number, string or boolean",
}
_JSON_HINT = (
    "None, bool, numbers, str, lists and dicts with str keys; convert arrays with .tolist()"
)


def wanted(kind: str) -> str:
    """What a value of ``kind`` is, in words (``'float'`` -> ``'a number'``)."""
    return _WANTED[kind]


def _is_bool(value: object) -> bool:
    """True, False or numpy's bool (which neither is a ``bool`` nor says it is a number)."""
    cls = type(value)
    return cls is bool or (cls.__module__ == "numpy" and cls.__name__ in ("bool", "bool_"))


def _describe(value: object) -> str:
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{type(value).__name__} {text}"


def _misfit(kind: str, value: object, detail: str = "") -> Misfit:
    """A value of the wrong type: ``expected float, got str`` (and ``'hot'`` in the message)."""
    reason = f"expected {_EXPECTED.get(kind, kind)}, got {type(value).__name__}"
    message = f"expected {_EXPECTED.get(kind, kind)}, got {_describe(value)}"
    return Misfit(reason, message + (f" ({detail})" if detail else ""))


def _out_of(value: object, reason: str) -> Misfit:
    """A number out of what is allowed: ``below the declared minimum 0``."""
    return Misfit(reason, f"{value!r} is {reason}")


def _number(value: Any, kind: str, int_as_float: bool) -> int | float:
    """``value`` as the int or float ``kind`` keeps, or :class:`Misfit`."""
    if isinstance(value, float):  # the common case, without the slower checks of the ABCs
        if kind == "int":
            raise _misfit(kind, value)
        return float(value)
    if _is_bool(value) or not isinstance(value, numbers.Real):
        raise _misfit(kind, value)
    integral = isinstance(value, numbers.Integral)
    if kind == "int" and not integral:
        raise _misfit(kind, value)
    try:
        if integral and (kind == "int" or not int_as_float):
            return int(value)
        return float(value)
    except (OverflowError, ValueError) as exc:  # an int too large for a float
        raise _misfit(kind, value, str(exc)) from exc


def _typed(value: Any, kind: str, int_as_float: bool) -> Any:
    """``value`` in the form ``kind`` keeps it, or :class:`Misfit` (the type alone)."""
    if kind in ("float", "int"):
        return _number(value, kind, int_as_float)
    if kind == "bool":
        if _is_bool(value):
            return bool(value)
        raise _misfit(kind, value)
    if kind == "str":
        if isinstance(value, str):
            return str(value)  # a str subclass is kept as a plain str, as disk gives it back
        raise _misfit(kind, value)
    if kind == "json":
        # one encode both proves the value is JSON and makes the copy
        try:
            return json.loads(json.dumps(value))
        except (TypeError, ValueError, RecursionError) as exc:
            raise _misfit(kind, value, _JSON_HINT) from exc
    if kind == "any":
        if _is_bool(value):
            return bool(value)
        if isinstance(value, str):
            return str(value)
        if isinstance(value, numbers.Real):
            return _number(value, "float", int_as_float=False)
        raise _misfit(kind, value)
    raise ValueError(f"unknown type {kind!r}; use one of {', '.join(TYPES + ('any',))}")


def fit(
    value: Any,
    kind: str,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    finite: bool = False,
    int_as_float: bool = True,
) -> Any:
    """``value`` in the form a ``kind`` value is kept in, if it fits; else :class:`Misfit`.

    ``minimum`` and ``maximum`` bound a number (NaN is outside any declared range);
    ``finite`` refuses NaN and the infinities; ``int_as_float=False`` keeps an integral number
    given for a float as an int. The :class:`Misfit` says why not: ``misfit.reason`` without
    the value (``'expected float, got str'``, ``'not a finite number'``, ``'below the declared
    minimum 0'``), ``str(misfit)`` with it.
    """
    kept = _typed(value, kind, int_as_float)
    if isinstance(kept, float) and finite and not math.isfinite(kept):
        raise _out_of(kept, "not a finite number")
    if isinstance(kept, int | float) and not isinstance(kept, bool):
        if minimum is not None and not kept >= minimum:
            raise _out_of(kept, f"below the declared minimum {minimum!r}")
        if maximum is not None and not kept <= maximum:
            raise _out_of(kept, f"above the declared maximum {maximum!r}")
    return kept


def infer_type(value: object) -> str:
    """The type a value declares by itself (an undeclared knowledge key takes its first's)."""
    if _is_bool(value):
        return "bool"
    if isinstance(value, numbers.Integral):
        return "int"
    if isinstance(value, numbers.Real):
        return "float"
    if isinstance(value, str):
        return "str"
    return "json"
