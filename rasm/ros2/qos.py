"""ROS 2 quality of service: the handful of policies a rasm topic can set."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from rasm.ros2.errors import RosError

__all__ = ["QosProfile", "DEFAULT_QOS"]

_CHOICES = {
    "reliability": ("reliable", "best_effort"),
    "durability": ("volatile", "transient_local"),
    "history": ("keep_last", "keep_all"),
}


@dataclass(frozen=True)
class QosProfile:
    """Reliability, durability, history and depth of one topic.

    The default is ROS 2's default profile: reliable, volatile, keep the last 10 messages.
    ``depth`` counts for ``keep_last`` only: that many received messages wait per topic before
    the oldest is dropped (the DDS reader's history; on Zenoh, rasm's own queue, as rmw_zenoh's).
    """

    reliability: str = "reliable"
    durability: str = "volatile"
    history: str = "keep_last"
    depth: int = 10

    def __post_init__(self) -> None:
        for name, allowed in _CHOICES.items():
            value = getattr(self, name)
            if value not in allowed:
                raise RosError(f"QoS {name} {value!r} is not one of {', '.join(allowed)}")
        if isinstance(self.depth, bool) or not isinstance(self.depth, int) or self.depth < 1:
            raise RosError(f"QoS depth must be a positive integer, got {self.depth!r}")

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> QosProfile:
        """A profile from ``{"reliability": "best_effort", "depth": 5}`` (missing keys default).

        Unknown keys are refused, naming the ones that exist.
        """
        unknown = sorted(set(values) - {"reliability", "durability", "history", "depth"})
        if unknown:
            raise RosError(
                f"unknown QoS setting {unknown[0]!r}; the settings are reliability, durability, "
                "history and depth"
            )
        return cls(**values)

    @property
    def keeps_all(self) -> bool:
        return self.history == "keep_all"


DEFAULT_QOS = QosProfile()
