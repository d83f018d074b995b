"""ROS 2 messages in an application: its type store, and the manifest's field paths read out
of received messages and filled into sent ones.

A probe with an interface ``type`` reads each signal from a field path of the decoded message
(``twist.twist.linear.x``, ``ranges``, ``ranges[3]``); an effector with a ``type`` builds its
message from the action's payload, ``fields`` saying which payload key fills which message
field. The app's own ``msg/*.msg`` files add types to the standard interfaces.

Only apps that name interface types import this module's ROS 2 parts (rosbags' type store):
``import rasm.platform.messages`` alone stays cheap.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rasm.errors import RasmError

if TYPE_CHECKING:
    from rasm.platform.manifest import Effector, Probe
    from rasm.ros2 import FieldType, TypeStore

__all__ = [
    "ActionMismatch",
    "MessageReader",
    "app_type_store",
    "build_message",
    "header_stamp",
    "value_type",
]

# the value type (rasm.values) a ROS 2 field holds
_FLOATS = {"float32", "float64"}
_INTS = {
    "int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64", "byte", "char",
}
_STRINGS = {"string", "wstring"}

# which value types a signal of each declared type takes from a field
_TAKES = {
    "float": {"float", "int"},
    "int": {"int"},
    "bool": {"bool"},
    "str": {"str"},
    "json": {"float", "int", "bool", "str", "json"},
}


class ActionMismatch(RasmError):
    """An action's payload that does not fill its effector's message (a key missing or left
    over, a value of the wrong type)."""


def value_type(field: FieldType) -> str:
    """The value type a field of this ROS 2 type holds: float, int, bool, str or json (arrays
    and sub-messages)."""
    if field.array is not None or field.is_message:
        return "json"
    if field.base in _FLOATS:
        return "float"
    if field.base in _INTS:
        return "int"
    if field.base == "bool":
        return "bool"
    if field.base in _STRINGS:
        return "str"
    return "json"


def takes(signal_type: str, field_type: str) -> bool:
    """Whether a signal declared ``signal_type`` can hold a field's ``field_type`` values."""
    return field_type in _TAKES.get(signal_type, set())


def app_type_store(folder: Path, base: TypeStore | None = None) -> TypeStore:
    """The standard interfaces (or ``base``, which gets them added) plus the app's own
    ``msg/*.msg``, ``srv/*.srv`` and ``action/*.action`` files (package: the app folder's
    name). A definition that does not parse raises :class:`SourceError` at its place."""
    from rasm.ros2 import TypeStore

    store = base if base is not None else TypeStore()
    if any(any((folder / kind).glob(f"*.{kind}")) for kind in ("msg", "srv", "action")):
        store.add_interface_dir(folder, package=_package(folder))
    return store


def _package(folder: Path) -> str:
    """The ROS package name of an app's own messages: its folder's name, made a valid name."""
    name = "".join(c if c.isalnum() or c == "_" else "_" for c in folder.resolve().name)
    return name if name[:1].isalpha() else f"app_{name}"


def header_stamp(message: Mapping[str, Any]) -> int | None:
    """``header.stamp`` of a decoded message in integer nanoseconds (exact), or None without
    one."""
    header = message.get("header")
    stamp = header.get("stamp") if isinstance(header, Mapping) else None
    if not isinstance(stamp, Mapping):
        return None
    sec, nanosec = stamp.get("sec"), stamp.get("nanosec")
    if not isinstance(sec, int) or not isinstance(nanosec, int):
        return None
    return sec * 10**9 + nanosec


class MessageReader:
    """Reads one probe's signals out of its decoded messages: ``read(message)`` gives
    ``{signal: value}`` (scaled as the signal says) and the signals whose field the message
    did not have (an index past the end of an array)."""

    def __init__(self, probe: Probe) -> None:
        from rasm.ros2 import FieldPath

        self.topic = probe.topic
        self.typename = probe.type or ""
        self._reads = [
            (key, FieldPath.parse(signal.field or key), signal)
            for key, signal in probe.signals.items()
        ]

    def read(self, message: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
        values: dict[str, Any] = {}
        missing: list[str] = []
        for key, path, signal in self._reads:
            try:
                values[key] = signal.scaled(path.read(message, self.typename))
            except RasmError:  # a FieldPathError: the message has no such field
                missing.append(key)
        return values, missing


def build_message(store: TypeStore, effector: Effector, payload: Mapping[str, Any]) -> dict:
    """The message an action's ``payload`` makes on ``effector``'s topic (a service's request,
    an action's goal): each field of ``effector.message_fields`` set from its payload key,
    the rest their ``.msg`` default, else zero.

    Fails closed: a payload key the effector maps that the payload lacks, a payload key it
    does not map, or a value that does not fit its field raises :class:`ActionMismatch`
    (nothing is sent). ``plan`` and ``kind``, which every action carries, are not fields.
    """
    from rasm.ros2 import RosError, set_fields

    mapped = effector.message_fields
    wanted = set(mapped.values())
    absent = sorted(wanted - set(payload))
    if absent:
        raise ActionMismatch(
            f"the action has no {absent[0]!r}, which effector {effector.name} sends as "
            f"{_field_of(mapped, absent[0])} of {effector.message_type}"
        )
    extra = sorted(set(payload) - wanted - {"plan", "kind"})
    if extra:
        raise ActionMismatch(
            f"the action's {extra[0]!r} is no field of effector {effector.name} (its fields: "
            f"{', '.join(sorted(wanted))}); it would not be sent"
        )
    empty = sorted(key for key in wanted if payload[key] is None)
    if empty:  # ROS would send a null as zero: a plan that forgot a value is not sent
        raise ActionMismatch(f"the action's {empty[0]!r} is null, not a value to send")
    values = {path: payload[key] for path, key in mapped.items()}
    try:
        return set_fields(store, effector.message_type or "", values)
    except RosError as exc:
        raise ActionMismatch(f"effector {effector.name}: {exc}") from None


def _field_of(mapped: Mapping[str, str], key: str) -> str:
    return next(path for path, k in mapped.items() if k == key)

