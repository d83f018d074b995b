"""What a ROS 2 transport needs from an app: its topics' interface types and QoS, how far each
probe's messages are decoded, the app's type store and the node's name."""

from __future__ import annotations

from typing import Any

from rasm.errors import SourceError, SourceErrors
from rasm.platform.manifest import AppManifest, manifest_location

__all__ = ["is_ros_transport", "ros_options"]


def is_ros_transport(url: str) -> bool:
    """Whether a transport URL is a ROS 2 middleware's (zenoh://, dds://)."""
    return url.strip().startswith(("zenoh://", "dds://"))


def ros_options(m: AppManifest, transport_url: str) -> dict[str, Any]:
    """What a ROS 2 transport needs: every topic's type and QoS, the app's type store,
    the node's name. A probe or effector without an interface type cannot be on ROS 2."""
    untyped = [
        (["probes", i, "topic"], f"probe {p.topic}")
        for i, p in enumerate(m.probes)
        if not p.type
    ] + [
        (["effectors", name, "topic"], f"effector {name}")
        for name, e in m.effectors.items()
        if not e.type
    ] + [
        (["trustworthiness", "external_verdicts", name, "topic"], f"external verdict {name}")
        for name, v in m.external_verdicts.items()
        if not v.type
    ]
    if untyped:
        raise SourceErrors([
            SourceError(
                f"{what} has no ROS 2 interface type, so it cannot be on "
                f"{transport_url}: give it one (type: pkg/msg/Name)",
                manifest_location(m, path),
            )
            for path, what in untyped
        ])
    from rasm.ros2.types import default_store

    types = {topic: typename for topic, (typename, _) in m.ros_topics.items()}
    qos = {topic: q for topic, (_, q) in m.ros_topics.items() if q}
    # a probe's messages are decoded only as far as its signals (and stamp) read them
    sources = {v.topic for v in m.external_verdicts.values()}
    fields = {
        p.topic: [s.field or key for key, s in p.signals.items()]
        + (["header.stamp.sec", "header.stamp.nanosec"] if p.stamp == "header" else [])
        for p in m.probes
        if p.topic not in sources
    }
    node = "".join(c if c.isalnum() or c == "_" else "_" for c in m.name)
    return {
        "types": types,
        "qos": qos,
        "fields": fields,
        "store": m.types if m.types is not None else default_store(),
        "node_name": f"rasm_{node}",
    }
