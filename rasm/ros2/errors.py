"""The errors of rasm's ROS 2 layer: one base class, one subclass per thing that can be wrong."""

from __future__ import annotations

from rasm.errors import CommError

__all__ = [
    "BagError",
    "FieldPathError",
    "MalformedMessage",
    "MessageError",
    "RosError",
    "UnknownTypeError",
]


class RosError(CommError):
    """A ROS 2 interface type, message, field path or recording could not be used."""


class UnknownTypeError(RosError):
    """An interface type the type store does not hold (neither bundled nor from a .msg file)."""


class FieldPathError(RosError):
    """A field path that does not exist in a message type, or not in one decoded message."""


class MessageError(RosError):
    """A dict that does not fit its message type (a wrong field name, value type or length)."""


class MalformedMessage(RosError):
    """Bytes that are not a valid CDR encoding of the message type they claim to be."""


class BagError(RosError):
    """A rosbag2 recording that cannot be read or written."""
