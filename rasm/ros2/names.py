"""ROS 2 interface type names and field types: the vocabulary the type store
(:mod:`rasm.ros2.types`) and the codec (:mod:`rasm.ros2.codec`) share, below both."""

from __future__ import annotations

import re
from dataclasses import dataclass

from rasm.ros2.errors import UnknownTypeError

__all__ = [
    "NAME_PART",
    "PLACEHOLDER_FIELD",
    "WSTRING_TYPE",
    "FieldType",
    "dds_type_name",
    "interface_kind",
    "normalize_type",
    "ros_type_name",
]

# ROS 2 requires an empty message to carry this one byte; rasm hides it from users.
PLACEHOLDER_FIELD = "structure_needs_at_least_one_member"

#: one part of a type name: a package, a type, a file stem
NAME_PART = r"[A-Za-z][A-Za-z0-9_]*"
_TYPE_NAME = re.compile(rf"({NAME_PART})/(?:(msg|srv|action)/)?({NAME_PART})")
_DDS_NAME = re.compile(rf"({NAME_PART})::(msg|srv|action)::dds_::({NAME_PART})_")

#: The stand-in for ``wstring`` in rosbags' definitions (see :mod:`rasm.ros2.types`).
WSTRING_TYPE = "rasm_cdr/msg/WString"


def normalize_type(name: str) -> str:
    """``pkg/msg/Name`` for ``pkg/msg/Name`` or ``pkg/Name`` (``pkg/srv/...`` and
    ``pkg/action/...`` stay as they are); :class:`UnknownTypeError` else."""
    match = _TYPE_NAME.fullmatch(name) if isinstance(name, str) else None
    if match is None:
        raise UnknownTypeError(
            f"{name!r} is not a ROS 2 interface type name (write it as pkg/msg/Name, e.g. "
            "nav_msgs/msg/Odometry, or pkg/srv/Name, pkg/action/Name)"
        )
    return f"{match[1]}/{match[2] or 'msg'}/{match[3]}"


def interface_kind(name: str) -> str:
    """``msg``, ``srv`` or ``action``: the kind of a type name."""
    return normalize_type(name).split("/")[1]


def dds_type_name(name: str) -> str:
    """The DDS (and rmw_zenoh) name of a type: ``std_msgs::msg::dds_::String_``,
    ``example_interfaces::srv::dds_::AddTwoInts_``."""
    package, kind, short = normalize_type(name).split("/")
    return f"{package}::{kind}::dds_::{short}_"


def ros_type_name(dds_name: str) -> str | None:
    """``pkg/msg/Name`` for a DDS type name ``pkg::msg::dds_::Name_``, else None."""
    match = _DDS_NAME.fullmatch(dds_name)
    return f"{match[1]}/{match[2]}/{match[3]}" if match else None


@dataclass(frozen=True)
class FieldType:
    """The type of one message field, as ROS writes it (``float64[36]``, ``float32[]``, ...).

    ``base`` is a primitive (``float64``, ``string``, ...) or a message type name;
    ``array`` is ``None``, ``"fixed"`` (``length`` elements) or ``"sequence"`` (at most
    ``length`` elements, 0 meaning unbounded); ``string_bound`` limits a string's length.
    """

    base: str
    is_message: bool = False
    array: str | None = None
    length: int = 0
    string_bound: int = 0

    @property
    def element(self) -> FieldType:
        """The type of one element (the field itself when it is not an array)."""
        return FieldType(self.base, self.is_message, None, 0, self.string_bound)

    def __str__(self) -> str:
        text = self.base + (f"<={self.string_bound}" if self.string_bound else "")
        if self.array == "fixed":
            return f"{text}[{self.length}]"
        if self.array == "sequence":
            return f"{text}[<={self.length}]" if self.length else f"{text}[]"
        return text
