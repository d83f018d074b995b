"""Field paths: ``pose.pose.position.x``, ``ranges[3]``, ``ranges`` in a decoded message.

A path is field names joined by dots, each optionally followed by ``[i]`` indexes (``i`` from
0). :func:`read_field` reads one out of a decoded message (a nested dict, see
:mod:`rasm.ros2.codec`); :func:`set_fields` builds a message from a flat mapping of paths to
values (``{"linear.x": 0.2, "angular.z": 0.1}``), other fields zero; :func:`field_type` checks a
path against a message type without any message (what a linter needs). Errors name the path
and the type.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from rasm.ros2.errors import FieldPathError
from rasm.ros2.types import FieldType, TypeStore

__all__ = ["FieldPath", "field_type", "read_field", "set_fields"]

_STEP = re.compile(r"([A-Za-z][A-Za-z0-9_]*)((?:\[\d+\])*)")
_INDEX = re.compile(r"\[(\d+)\]")


@dataclass(frozen=True)
class FieldPath:
    """A parsed field path: ``steps`` is a tuple of field names (str) and indexes (int)."""

    text: str
    steps: tuple[str | int, ...]

    @classmethod
    def parse(cls, text: str) -> FieldPath:
        """Parse ``text``; :class:`FieldPathError` saying where it is malformed."""
        if not isinstance(text, str) or not text:
            raise FieldPathError(f"a field path must be a non-empty string, got {text!r}")
        steps: list[str | int] = []
        for part in text.split("."):
            match = _STEP.fullmatch(part)
            if match is None:
                raise FieldPathError(
                    f"field path {text!r}: {part!r} is not a field name with optional [index] "
                    "(write e.g. pose.pose.position.x or ranges[3])"
                )
            steps.append(match[1])
            steps.extend(int(i) for i in _INDEX.findall(match[2]))
        return cls(text, tuple(steps))

    def __str__(self) -> str:
        return self.text

    def read(self, message: Mapping[str, Any], typename: str = "") -> Any:
        """The value at this path in the decoded ``message`` (:func:`read_field`); a path the
        message lacks raises :class:`FieldPathError` (``typename`` makes it clearer)."""
        value: Any = message
        for at, step in enumerate(self.steps):
            if isinstance(step, int):
                if not isinstance(value, (list, tuple)) or step >= len(value):
                    raise _no_such_field(self, at, value, typename)
            # a decoded message is a dict: checked first, before the Mapping ABC's slower check
            elif not isinstance(value, (dict, Mapping)) or step not in value:
                raise _no_such_field(self, at, value, typename)
            value = value[step]
        return value


def _as_path(path: str | FieldPath) -> FieldPath:
    return path if isinstance(path, FieldPath) else FieldPath.parse(path)


def _prefix(steps: tuple[str | int, ...]) -> str:
    text = ""
    for step in steps:
        text += f"[{step}]" if isinstance(step, int) else (f".{step}" if text else step)
    return text


def read_field(message: Mapping[str, Any], path: str | FieldPath, typename: str = "") -> Any:
    """The value at ``path`` in the decoded ``message`` (a sub-message is a dict, an array a
    list). ``typename`` only makes error messages clearer."""
    return _as_path(path).read(message, typename)


def _no_such_field(path: FieldPath, at: int, value: Any, typename: str) -> FieldPathError:
    """Why ``value``, reached by the steps of ``path`` before step ``at``, has no step ``at``."""
    what = f" of {typename}" if typename else ""
    step = path.steps[at]
    if isinstance(step, int):
        if not isinstance(value, list | tuple):
            return FieldPathError(
                f"field path {path.text!r}{what}: {_prefix(path.steps[:at])} is not an "
                "array, it cannot be indexed"
            )
        return FieldPathError(
            f"field path {path.text!r}{what}: index {step} is out of range, "
            f"{_prefix(path.steps[:at])} has {len(value)} elements in this message"
        )
    where = _prefix(path.steps[:at]) or "the message"
    if not isinstance(value, Mapping):
        return FieldPathError(
            f"field path {path.text!r}{what}: {where} is not a message, it has no field {step!r}"
        )
    return FieldPathError(
        f"field path {path.text!r}{what}: {where} has no field {step!r} "
        f"(its fields: {', '.join(value) or 'none'})"
    )


def field_type(store: TypeStore, typename: str, path: str | FieldPath) -> FieldType:
    """The type at ``path`` in messages of ``typename``, checked against the type store.

    ``ranges`` of a LaserScan is ``float32[]``; ``ranges[3]`` is ``float32``. Raises
    :class:`FieldPathError` naming the path, the type and the fields that do exist.
    """
    parsed = _as_path(path)
    root = store.resolve(typename)
    current = FieldType(root, is_message=True)
    for i, step in enumerate(parsed.steps):
        where = _prefix(parsed.steps[:i])
        if isinstance(step, int):
            if current.array is None:
                raise FieldPathError(
                    f"field path {parsed.text!r} of {root}: {where} is {current}, not an array"
                )
            if current.array == "fixed" and step >= current.length:
                raise FieldPathError(
                    f"field path {parsed.text!r} of {root}: index {step} is out of range for "
                    f"{where} ({current})"
                )
            current = current.element
            continue
        if current.array is not None or not current.is_message:
            raise FieldPathError(
                f"field path {parsed.text!r} of {root}: {where} is {current}, not a message "
                f"with a field {step!r}"
            )
        fields = store.fields(current.base)
        if step not in fields:
            inside = f"{where} ({current.base})" if where else current.base
            raise FieldPathError(
                f"field path {parsed.text!r} of {root}: {inside} has no field {step!r} "
                f"(its fields: {', '.join(fields) or 'none'})"
            )
        current = fields[step]
    return current


def set_fields(
    store: TypeStore,
    typename: str,
    values: Mapping[str, Any],
    base: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """A message of ``typename`` with each ``path: value`` of ``values`` set, everything else
    as in ``base`` (default: zero). The result is checked against the type: a wrong path, index
    or value raises, naming the path and the type.

    ``set_fields(store, "geometry_msgs/msg/Twist", {"linear.x": 0.2, "angular.z": 0.1})``
    """
    codec = store.codec(typename)
    message = codec.zero() if base is None else copy.deepcopy(dict(base))
    for text, value in values.items():
        parsed = _as_path(text)
        field_type(store, codec.typename, parsed)  # names the path and the type when wrong
        target: Any = message
        for i, step in enumerate(parsed.steps[:-1]):
            following = parsed.steps[i + 1]
            if isinstance(step, int):
                _check_index(target, step, parsed, i, codec.typename)
            elif step not in target or target[step] is None:
                target[step] = [] if isinstance(following, int) else {}
            target = target[step]
        last = parsed.steps[-1]
        if isinstance(last, int):
            _check_index(target, last, parsed, len(parsed.steps) - 1, codec.typename)
        target[last] = value
    codec.check(message)
    return message


def _check_index(target: Any, index: int, parsed: FieldPath, at: int, typename: str) -> None:
    if index >= len(target):
        raise FieldPathError(
            f"field path {parsed.text!r} of {typename}: index {index} is out of range, "
            f"{_prefix(parsed.steps[:at])} has {len(target)} elements (set the whole "
            f"{_prefix(parsed.steps[:at])} to a list first)"
        )
