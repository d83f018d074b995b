"""rasm.ros2: ROS 2 without a ROS install.

- :class:`TypeStore`: ROS 2's standard message types (bundled, no ROS needed) plus an app's own
  ``.msg`` files; RIHS01 type hashes; :class:`MessageCodec` turns CDR into plain dicts and back.
- :class:`ZenohTransport` (``zenoh://HOST:PORT``, rmw_zenoh's conventions) and
  :class:`DdsTransport` (``dds://``, Cyclone DDS with ROS 2 naming): rasm transports whose
  topics are ROS topics and whose payloads are messages as dicts.
- :func:`read_field`, :func:`set_fields`, :func:`field_type`: field paths such as
  ``pose.pose.position.x`` and ``ranges[3]``.
- :class:`BagReader` / :func:`read_bag` and :class:`BagWriter`: rosbag2 recordings (MCAP,
  SQLite3); :func:`recorded_topics` lists a recording's topics and types,
  :func:`recorded_types` adds the types it defines to a store.

The transports and bags load their middleware libraries only when first used.
"""

from rasm.extras import missing_extra

try:  # every part of rasm.ros2 needs the type store and the CDR codec (rosbags, numpy)
    from rasm.ros2.codec import MessageCodec
    from rasm.ros2.errors import (
        BagError,
        FieldPathError,
        MalformedMessage,
        MessageError,
        RosError,
        UnknownTypeError,
    )
    from rasm.ros2.fields import FieldPath, field_type, read_field, set_fields
    from rasm.ros2.qos import DEFAULT_QOS, QosProfile
    from rasm.ros2.types import FieldType, TypeStore, dds_type_name, normalize_type
except ModuleNotFoundError as exc:
    raise (missing_extra(exc, "rasm.ros2") or exc) from None

__all__ = [
    "BagError",
    "BagReader",
    "BagRecord",
    "BagWriter",
    "DEFAULT_QOS",
    "DdsTransport",
    "FieldPath",
    "FieldPathError",
    "FieldType",
    "MalformedMessage",
    "MessageCodec",
    "MessageError",
    "QosProfile",
    "RosError",
    "TypeStore",
    "UnknownTypeError",
    "ZenohTransport",
    "dds_type_name",
    "field_type",
    "normalize_type",
    "read_bag",
    "read_field",
    "recorded_topics",
    "recorded_types",
    "set_fields",
]

_LAZY = {
    "ZenohTransport": "rasm.ros2.zenoh",
    "DdsTransport": "rasm.ros2.dds",
    "BagReader": "rasm.ros2.bags",
    "BagRecord": "rasm.ros2.bags",
    "BagWriter": "rasm.ros2.bags",
    "read_bag": "rasm.ros2.bags",
    "recorded_topics": "rasm.ros2.bags",
    "recorded_types": "rasm.ros2.bags",
}


def __getattr__(name: str) -> object:
    # Zenoh, Cyclone DDS and the bag storages load only when asked for.
    if name in _LAZY:
        from importlib import import_module

        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'rasm.ros2' has no attribute {name!r}")
