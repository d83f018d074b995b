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
from dataclasses import dataclass
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
    ``msg/*.msg`` files (package: the app folder's name). A definition that does not parse
    raises :class:`SourceError` at its place."""
    from rasm.ros2 import TypeStore

    store = base if base is not None else TypeStore()
    msg = folder / "msg"
    if msg.is_dir() and any(msg.glob("*.msg")):
        store.add_msg_dir(msg, package=_package(folder))
    return store


def _package(folder: Path) -> str:
    """The ROS package name of an app's own messages: its folder's name, made a valid name."""
    name = "".join(c if c.isalnum() or c == "_" else "_" for c in folder.resolve().name)
    return name if name[:1].isalpha() else f"app_{name}"


def header_stamp(message: Mapping[str, Any]) -> float | None:
    """``header.stamp`` of a decoded message in seconds, or None without one."""
    header = message.get("header")
    stamp = header.get("stamp") if isinstance(header, Mapping) else None
    if not isinstance(stamp, Mapping):
        return None
    sec, nanosec = stamp.get("sec"), stamp.get("nanosec")
    if not isinstance(sec, int) or not isinstance(nanosec, int):
        return None
    return sec + nanosec * 1e-9


@dataclass(frozen=True)
class _Read:
    key: str
    path: Any  # a parsed rasm.ros2.FieldPath
    attributes: tuple[str | int, ...]  # its steps as rosbags' message objects name them


class MessageReader:
    """Reads one probe's signals out of its messages: ``read(message)`` from a decoded dict,
    ``read_object(message)`` from rosbags' message object (what a bag is read as, faster
    than converting every field to a dict). Each gives ``{signal: value}`` and the signals
    whose field the message did not have (an index past the end of an array)."""

    def __init__(self, probe: Probe, store: TypeStore | None = None) -> None:
        from rosbags.typesys.base import normalize_fieldname

        from rasm.ros2 import FieldPath

        self.topic = probe.topic
        self.typename = probe.type or ""
        self.store = store
        self._reads = []
        for key, signal in probe.signals.items():
            path = FieldPath.parse(signal.field or key)
            attributes = tuple(
                normalize_fieldname(step) if isinstance(step, str) else step
                for step in path.steps
            )
            self._reads.append(_Read(key, path, attributes))

    def read(self, message: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
        values: dict[str, Any] = {}
        missing: list[str] = []
        for item in self._reads:
            try:
                values[item.key] = item.path.read(message, self.typename)
            except RasmError:  # a FieldPathError: the message has no such field
                missing.append(item.key)
        return values, missing

    def read_object(self, message: Any) -> tuple[dict[str, Any], list[str]]:
        values: dict[str, Any] = {}
        missing: list[str] = []
        for item in self._reads:
            value = message
            try:
                for step in item.attributes:
                    value = value[step] if isinstance(step, int) else getattr(value, step)
            except (IndexError, AttributeError):
                missing.append(item.key)
                continue
            values[item.key] = self._plain(value)
        return values, missing

    def _plain(self, value: Any) -> Any:
        """A field's value as a decoded dict holds it: lists, dicts, Python numbers."""
        if isinstance(value, str | bool | int | float):
            return value
        if hasattr(value, "tolist"):  # a numpy array or number
            return value.tolist()
        if isinstance(value, list):
            return [self._plain(item) for item in value]
        typename = getattr(value, "__msgtype__", None)
        if typename is not None and self.store is not None and typename in self.store:
            return self.store.codec(typename).as_dict(value)
        if typename is not None:  # a type only the bag defines: its fields as they are named
            return {
                name: self._plain(item)
                for name, item in vars(value).items()
                if name != "structure_needs_at_least_one_member"
            }
        return value


def build_message(store: TypeStore, effector: Effector, payload: Mapping[str, Any]) -> dict:
    """The message an action's ``payload`` makes on ``effector``'s topic: each field of
    ``effector.message_fields`` set from its payload key, the rest zero.

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
            f"{_field_of(mapped, absent[0])} of {effector.type}"
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
        return set_fields(store, effector.type or "", values)
    except RosError as exc:
        raise ActionMismatch(f"effector {effector.name}: {exc}") from None


def _field_of(mapped: Mapping[str, str], key: str) -> str:
    return next(path for path, k in mapped.items() if k == key)

