"""The JSON envelope every message travels in, and the checks that keep bad payloads out.

On the wire a message is one UTF-8 JSON object ``{"uid": ..., "timestamp": ..., **payload}``:
``uid`` is unique per message and ``timestamp`` is the sender's wall-clock time (seconds since the
epoch). Receivers get the payload back without those two keys (see :class:`Message`), so the
names ``uid`` and ``timestamp`` are reserved: a payload using them is refused at publish time.

Allowed values are what JSON represents exactly in every language: objects with string keys,
arrays, strings of Unicode text (no lone surrogate such as ``"\\ud800"``, which no UTF-8 text
can hold), booleans, null, finite floats and integers within 64 bits. Anything else is
refused when publishing (:class:`CommError`) and counted as malformed when received
(:class:`MalformedPayload`, never fatal).
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

from rasm.errors import CommError

__all__ = ["RESERVED_KEYS", "MAX_PAYLOAD", "MalformedPayload", "check_payload", "encode", "decode"]

RESERVED_KEYS = ("uid", "timestamp")
MAX_PAYLOAD = 1 << 20  # bytes; robots exchange small records, a megabyte is already suspicious
_INT_LIMIT = 1 << 63  # integers beyond int64 lose precision in other languages' JSON parsers
_MAX_DEPTH = 64
# a JSON escape of a UTF-16 surrogate: only then can a decoded string hold a lone one
_SURROGATE_ESCAPE = re.compile(rb"\\u[dD][89a-fA-F]")


class MalformedPayload(CommError):
    """A received payload that is not a valid envelope (the reason is the message)."""


def _check_value(value: Any, path: str, depth: int) -> None:
    # bool is an int subclass: test it first so True is not range-checked as 1.
    if value is None or isinstance(value, str | bool):
        return
    if isinstance(value, int):
        if not -_INT_LIMIT <= value < _INT_LIMIT:
            raise CommError(f"payload{path}: integer {value} does not fit in 64 bits")
        return
    if isinstance(value, float):
        if not math.isfinite(value):
            raise CommError(f"payload{path}: {value} is not a finite number (JSON has no NaN/inf)")
        return
    if depth >= _MAX_DEPTH:
        raise CommError(f"payload{path}: nested deeper than {_MAX_DEPTH} levels")
    if isinstance(value, dict):
        for key, item in value.items():
            if not isinstance(key, str):
                raise CommError(f"payload{path}: key {key!r} is not a string")
            _check_value(item, f"{path}[{key!r}]", depth + 1)
        return
    if isinstance(value, list | tuple):
        for i, item in enumerate(value):
            _check_value(item, f"{path}[{i}]", depth + 1)
        return
    raise CommError(
        f"payload{path}: {type(value).__name__} is not JSON (use dicts, lists, str, int, float, "
        "bool, None)"
    )


def check_payload(payload: Any) -> dict[str, Any]:
    """Return ``payload`` if it can be published, else raise :class:`CommError` saying why."""
    if not isinstance(payload, dict):
        raise CommError(f"payload must be a dict, got {type(payload).__name__}")
    for key in RESERVED_KEYS:
        if key in payload:
            raise CommError(
                f"payload key {key!r} is reserved for the message envelope "
                f"(receivers find it as Message.{key}); rename the key"
            )
    for key, value in payload.items():
        if not isinstance(key, str):
            raise CommError(f"payload: key {key!r} is not a string")
        _check_value(value, f"[{key!r}]", 1)
    return payload


def encode(
    payload: dict[str, Any], *, uid: str, timestamp: float, max_bytes: int = MAX_PAYLOAD
) -> bytes:
    """The wire form of ``payload`` (checked with :func:`check_payload`)."""
    check_payload(payload)
    data = json.dumps(
        {"uid": uid, "timestamp": timestamp, **payload}, separators=(",", ":"), allow_nan=False
    ).encode("ascii")
    if len(data) > max_bytes:
        raise CommError(f"payload is {len(data)} bytes encoded; the limit is {max_bytes}")
    if _SURROGATE_ESCAPE.search(data) and (bad := _not_text(payload)) is not None:
        raise CommError(f"payload: {bad!r} is not Unicode text (a lone surrogate)")
    return data


def _not_text(value: Any) -> str | None:
    """The first string (key or value) in ``value`` that is not Unicode text, or None."""
    stack = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            stack.extend(item)
            stack.extend(item.values())
        elif isinstance(item, list | tuple):
            stack.extend(item)
        elif isinstance(item, str):
            try:
                item.encode("utf-8")
            except UnicodeEncodeError:
                return item
    return None


def _depth(value: Any) -> int:
    """How deep containers nest in ``value`` (the object itself is level 1)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        item, level = stack.pop()
        if isinstance(item, dict):
            item = list(item.values())
        if isinstance(item, list):
            deepest = max(deepest, level)
            stack.extend((child, level + 1) for child in item)
    return deepest


def _reject_constant(name: str) -> Any:
    raise MalformedPayload(f"non-finite number {name}")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise MalformedPayload(f"number {text[:40]} is out of range")
    return value


def _bounded_int(text: str) -> int:
    # Checked on the text first: int() of a 100 000-digit string is slow (and refused by Python).
    if len(text.lstrip("-")) > 19:
        raise MalformedPayload(f"integer {text[:40]}... does not fit in 64 bits")
    value = int(text)
    if not -_INT_LIMIT <= value < _INT_LIMIT:
        raise MalformedPayload(f"integer {text} does not fit in 64 bits")
    return value


def decode(
    data: bytes, *, max_bytes: int = MAX_PAYLOAD
) -> tuple[dict[str, Any], Any, Any]:
    """``(payload, uid, timestamp)`` from wire bytes; raises :class:`MalformedPayload`.

    The envelope keys are taken out of the payload; a message without them (a foreign publisher)
    gives ``None`` for each.
    """
    if len(data) > max_bytes:
        raise MalformedPayload(f"{len(data)} bytes is over the {max_bytes}-byte limit")
    try:
        text = bytes(data).decode("utf-8")
    except UnicodeDecodeError as exc:
        where = f"{exc.reason} at byte {exc.start}"
        raise MalformedPayload(f"binary data, not UTF-8 text ({where})") from None
    try:
        obj = json.loads(
            text, parse_constant=_reject_constant, parse_float=_finite_float, parse_int=_bounded_int
        )
    except MalformedPayload:
        raise
    except RecursionError:
        raise MalformedPayload("JSON nested too deeply") from None
    except ValueError as exc:  # JSONDecodeError and int/float conversion problems
        raise MalformedPayload(f"not JSON: {exc}") from None
    if not isinstance(obj, dict):
        raise MalformedPayload(f"a JSON {type(obj).__name__}, not an object")
    if _SURROGATE_ESCAPE.search(data) and (bad := _not_text(obj)) is not None:
        raise MalformedPayload(f"{bad!r} is not Unicode text (a lone surrogate)")
    # what is received could be sent on: no deeper than a payload may be (brackets first: a
    # flat record is not walked)
    if text.count("[") + text.count("{") > _MAX_DEPTH and _depth(obj) > _MAX_DEPTH:
        raise MalformedPayload(f"nested deeper than {_MAX_DEPTH} levels")
    uid = obj.pop("uid", None)
    timestamp = obj.pop("timestamp", None)
    return obj, uid, timestamp
