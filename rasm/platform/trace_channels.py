"""What an MCAP trace (``rasm run --trace OUT.mcap``) records besides the trace records: each
verdict change as a ``std_msgs/msg/Bool`` on ``/rasm/verdict/<property>``, and each message a
ROS 2 effector sends (a replay: would send) in the effector's own type on its own topic — a
service's request on the service's name, an action's goal on the action's.

Only effectors with a ROS 2 interface type have messages ROS tools decode; an untyped
effector's JSON payloads are in the trace records alone.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from rasm.platform.manifest import AppManifest, Effector
from rasm.trace import TraceWriter

__all__ = ["TraceChannels", "trace_channels"]


class ChannelWriter(Protocol):
    """The MCAP trace writer's typed channels (:class:`rasm.trace_mcap.McapTraceWriter`)."""

    def verdicts(self, verdicts: list[Any]) -> None: ...

    def message(self, time: float, topic: str, typename: str, definition: str,
                data: bytes) -> None: ...


class TraceChannels:
    """Puts effector messages and verdicts on an MCAP trace's typed channels. ``store`` gives
    the app's ROS 2 type store (asked for only when a typed effector sends)."""

    def __init__(self, writer: ChannelWriter, store: Callable[[], Any],
                 now: Callable[[], float]) -> None:
        self.writer = writer
        self.store = store
        self.now = now
        self._definitions: dict[str, str] = {}

    def verdicts(self, verdicts: list[Any]) -> None:
        self.writer.verdicts(verdicts)

    def effector_message(self, effector: Effector, message: dict[str, Any]) -> None:
        """The message ``effector`` sends, in its type on its topic."""
        typename = effector.message_type
        if not typename:
            return
        store = self.store()
        definition = self._definitions.get(typename)
        if definition is None:
            definition = self._definitions[typename] = store.rosbags.generate_msgdef(
                typename, ros_version=2)[0]
        self.writer.message(self.now(), effector.topic, typename, definition,
                            store.codec(typename).encode(message))


def trace_channels(trace: TraceWriter, manifest: AppManifest,
                   now: Callable[[], float]) -> TraceChannels | None:
    """The typed channels of ``trace`` when it is an MCAP trace (else None)."""
    from rasm.trace_mcap import McapTraceWriter

    if not isinstance(trace, McapTraceWriter):
        return None

    def store() -> Any:
        from rasm.platform.actions_out import message_types

        return message_types(manifest)

    return TraceChannels(trace, store, now)
