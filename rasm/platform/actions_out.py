"""Actions out: each action the Trustworthiness Checker lets through, on its effector's topic,
or as a call of its effector's service or action.

An effector with a ROS 2 interface ``type`` gets the message its fields build from the action's
payload (a service's request, an action's goal); an untyped one gets the payload with the
action's plan and kind, sealed by the distribution (signed, when actions are). A service or
action effector's call runs off the loop (:mod:`rasm.platform.calls`). A replay sends nothing:
the action goes in the trace as it would have been sent.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from rasm.errors import CommError
from rasm.platform.action_outcome import Emit
from rasm.platform.components import Action
from rasm.platform.manifest import AppManifest, Effector
from rasm.platform.protocols import CallStarter
from rasm.statechart import Clock

if TYPE_CHECKING:
    from rasm.ros2 import TypeStore

__all__ = ["ActionSender", "message_types"]


def message_types(m: AppManifest) -> TypeStore:
    """The app's ROS 2 types (the standard interfaces when it has none of its own)."""
    if m.types is not None:
        return m.types
    from rasm.ros2.types import default_store

    return default_store()


class ActionSender:
    """Sends an action on its effector's topic (:meth:`send`, the checker's ``send``).

    ``publish(topic, payload)`` puts it on the transport; ``seal(topic, payload)`` signs an
    untyped payload (raising when it cannot be sent); ``emit(time, record)`` writes the trace
    record of an action a replay does not send; ``calls`` starts a service or action
    effector's call (None: the app has none); ``sent(effector, message)`` sees each ROS 2
    message built (sent, or recorded in a replay), as the MCAP trace records it.
    """

    def __init__(
        self,
        manifest: AppManifest,
        *,
        publish: Callable[[str, dict[str, Any]], object],
        seal: Callable[[str, dict[str, Any]], dict[str, Any]],
        emit: Emit,
        clock: Clock,
        replaying: bool,
        calls: CallStarter | None = None,
        sent: Callable[[Effector, dict[str, Any]], object] | None = None,
    ) -> None:
        self.manifest = manifest
        self.publish = publish
        self.seal = seal
        self.emit = emit
        self.clock = clock
        self.replaying = replaying
        self.calls = calls
        self.sent = sent

    def send(self, effector: Effector, action: Action) -> str | None:
        """Send ``action`` on ``effector``'s topic; why it was not sent (a replay), or None."""
        payload: dict[str, Any] = {**action.payload, "plan": action.plan, "kind": action.kind}
        if effector.type:
            from rasm.platform.messages import build_message

            payload = build_message(message_types(self.manifest), effector, action.payload)
            if self.sent is not None:
                self.sent(effector, payload)
        if self.replaying:
            action_record = {"effector": effector.name, effector.kind: effector.topic,
                             "payload": payload}
            self.emit(self.clock.time, {"recorded_action": action_record, "plan": action.plan})
            return f"recorded in the trace, not sent (replay): {effector.name} on {effector.topic}"
        if effector.call is not None:
            if self.calls is None:
                raise CommError(f"{effector.call} {effector.topic} cannot be called here")
            return self.calls.start(effector, action, payload)
        if not effector.type:
            payload = self.seal(effector.topic, payload)
        self.publish(effector.topic, payload)
        return None
