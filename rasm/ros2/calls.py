"""ROS 2 services and actions as a client, over rmw_zenoh's conventions.

A service ``/dock`` of type ``pkg/srv/Dock`` is a Zenoh queryable on the key expression of a
topic (``<domain>/dock/pkg::srv::dds_::Dock_/<RIHS01 hash of the service>``): the request is a
query whose payload is the request's CDR, with the rmw attachment (sequence number, time stamp,
the client's GID); the reply's payload is the response's CDR.

An action ``/navigate`` of type ``pkg/action/Nav`` is three services and two topics under
``/navigate/_action/``: ``send_goal`` (``Nav_SendGoal``: a goal id and the goal; accepted or
not), ``get_result`` (``Nav_GetResult``: answers when the goal ends, with its status and
result), ``cancel_goal`` (``action_msgs/srv/CancelGoal``), ``feedback`` (``Nav_FeedbackMessage``:
the goal id and a feedback) and ``status``.

Every failure is a :class:`CallFailed` saying what happened (no server, a timeout, a refused
goal, an aborted or cancelled goal, an error reply, a response that does not decode): a call
never ends in a silent success.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

import zenoh

from rasm.errors import CommError
from rasm.ros2.types import dds_type_name
from rasm.times import format_seconds

__all__ = ["ActionGoal", "CallFailed", "GOAL_STATUS", "ZenohCalls", "calls_for"]

#: action_msgs/msg/GoalStatus's status values
GOAL_STATUS = {0: "unknown", 1: "accepted", 2: "executing", 3: "canceling", 4: "succeeded",
               5: "canceled", 6: "aborted"}
_SUCCEEDED = 4
_POLL = 0.01  # how often a waiting goal looks at its feedback, its result and a cancel


class CallFailed(CommError):
    """A service call or an action goal that did not succeed; the message says why."""


class ActionGoal:
    """A goal being pursued: :meth:`cancel` asks the server to cancel it (thread-safe)."""

    def __init__(self, goal_id: bytes) -> None:
        self.goal_id = goal_id
        self.cancel_requested = threading.Event()
        self.cancel_reason = ""

    def cancel(self, reason: str) -> None:
        self.cancel_reason = reason
        self.cancel_requested.set()


class ZenohCalls:
    """Service calls and action goals on a connected :class:`~rasm.ros2.zenoh.ZenohTransport`
    (its session, domain, type store and attachments)."""

    def __init__(self, transport: Any) -> None:
        self.transport = transport
        self._sequence = iter(range(1, 1 << 62))
        self._lock = threading.Lock()
        self._gid = os.urandom(16)

    # -- services -------------------------------------------------------------------------------
    def call(self, service: str, typename: str, request: Mapping[str, Any],
             timeout: float) -> dict[str, Any]:
        """Call ``service`` (of type ``pkg/srv/Name``, or an action's inner service) with
        ``request``; its response as a dict. :class:`CallFailed` unless a response came."""
        replies = self._query(service, typename, request, timeout)
        return self._response(service, typename, replies, timeout)

    def _query(self, service: str, typename: str, request: Mapping[str, Any],
               timeout: float) -> Any:
        from rasm.ros2.zenoh import attachment, topic_key

        store = self.transport.store
        data = store.codec(f"{typename}_Request").encode(request)
        key = topic_key(self.transport.domain, service, dds_type_name(typename),
                        store.type_hash(typename))
        with self._lock:
            sequence = next(self._sequence)
        session = self.transport.session
        if session is None:
            raise CallFailed(f"service {service}: the transport is not connected")
        return session.get(key, payload=data, timeout=timeout,
                           attachment=attachment(sequence, time.time_ns(), self._gid))

    def _response(self, service: str, typename: str, replies: Any, timeout: float,
                  goal: ActionGoal | None = None,
                  idle: Callable[[], object] | None = None) -> dict[str, Any]:
        """The decoded response among ``replies``. With a ``goal``, the replies are polled:
        ``idle`` runs between looks (the goal's feedback), and a cancel requested ends the
        wait (:class:`_Cancelled`)."""
        started = time.monotonic()
        while True:
            try:
                reply = replies.try_recv() if goal is not None else replies.recv()
            except zenoh.ZError:  # the channel ended: every reply is in, or the query timed out
                reply = None
                if time.monotonic() - started >= timeout * 0.9:
                    raise CallFailed(
                        f"service {service}: no response within {format_seconds(timeout)} s"
                    ) from None
                raise CallFailed(
                    f"service {service}: no server answers ({typename} on this network)"
                ) from None
            if reply is None:  # nothing yet (polling for a goal's feedback and cancel)
                if goal is not None and goal.cancel_requested.is_set():
                    raise _Cancelled()
                if idle is not None:
                    idle()
                if goal is not None:
                    goal.cancel_requested.wait(_POLL)
                continue
            if reply.ok is None:
                error = reply.err.payload.to_string()[:200]
                if error == "Timeout":  # what Zenoh itself replies when the query times out
                    raise CallFailed(
                        f"service {service}: no response within {format_seconds(timeout)} s"
                    )
                raise CallFailed(f"service {service} answered an error: {error}")
            try:
                return self.transport.store.codec(f"{typename}_Response").decode(
                    reply.ok.payload.to_bytes()
                )
            except CommError as exc:
                raise CallFailed(
                    f"service {service}: its response does not decode: {exc}"
                ) from None

    # -- actions --------------------------------------------------------------------------------
    def pursue(self, action: str, typename: str, goal_fields: Mapping[str, Any], timeout: float,
               feedback: Callable[[dict[str, Any]], object], goal: ActionGoal) -> dict[str, Any]:
        """Send ``goal_fields`` as a goal of ``action`` (type ``pkg/action/Name``) and wait for
        its result (at most ``timeout`` s from now), passing each feedback to ``feedback``.

        The result as a dict when the goal succeeded; :class:`CallFailed` when it was
        refused, aborted, cancelled or timed out. A cancel requested on ``goal`` (or the
        timeout) sends a cancel request to the server before that.
        """
        from rasm.ros2.zenoh import topic_key

        store = self.transport.store
        deadline = time.monotonic() + timeout
        goal_id = {"uuid": list(goal.goal_id)}
        base = f"{action}/_action"
        fb_type = f"{typename}_FeedbackMessage"
        fb_codec = store.codec(fb_type)
        fb_key = topic_key(self.transport.domain, f"{base}/feedback", dds_type_name(fb_type),
                           store.type_hash(fb_type))
        subscriber = self.transport.session.declare_subscriber(
            fb_key, zenoh.handlers.FifoChannel(256)
        )
        try:
            answer = self.call(f"{base}/send_goal", f"{typename}_SendGoal",
                               {"goal_id": goal_id, "goal": dict(goal_fields)}, timeout)
            if not answer.get("accepted"):
                raise CallFailed(f"action {action}: the server refused the goal")
            remaining = max(deadline - time.monotonic(), 0.001)
            replies = self._query(f"{base}/get_result", f"{typename}_GetResult",
                                  {"goal_id": goal_id}, remaining)

            def drain() -> None:  # each feedback as it comes, while the result is awaited
                self._drain_feedback(subscriber, fb_codec, goal.goal_id, feedback)

            while True:
                drain()
                try:
                    result = self._response(f"{base}/get_result", f"{typename}_GetResult",
                                            replies, remaining, goal, drain)
                    break
                except _Cancelled:
                    self._cancel(base, goal_id, deadline)
                    raise CallFailed(
                        f"action {action}: goal cancelled ({goal.cancel_reason})"
                    ) from None
                except CallFailed as exc:
                    if "no response within" in str(exc):
                        self._cancel(base, goal_id, deadline + 1.0)
                        raise CallFailed(
                            f"action {action}: no result within {format_seconds(timeout)} s "
                            "(goal cancelled)"
                        ) from None
                    raise
            self._drain_feedback(subscriber, fb_codec, goal.goal_id, feedback)
        finally:
            subscriber.undeclare()
        status = result.get("status")
        if status != _SUCCEEDED:
            raise CallFailed(
                f"action {action}: goal {GOAL_STATUS.get(status, status)}"
            )
        return result["result"]

    def _drain_feedback(self, subscriber: Any, codec: Any, goal_id: bytes,
                        feedback: Callable[[dict[str, Any]], object]) -> None:
        while (sample := subscriber.handler.try_recv()) is not None:
            try:
                message = codec.decode(sample.payload.to_bytes())
            except CommError:
                continue  # a malformed feedback is no feedback
            if bytes(message["goal_id"]["uuid"]) == goal_id:
                feedback(message["feedback"])

    def _cancel(self, base: str, goal_id: dict, deadline: float) -> None:
        """Ask the server to cancel the goal (its answer is awaited briefly, not required)."""
        try:
            self.call(f"{base}/cancel_goal", "action_msgs/srv/CancelGoal",
                      {"goal_info": {"goal_id": goal_id}},
                      max(deadline - time.monotonic(), 1.0))
        except CallFailed:
            pass


def calls_for(transport: Any) -> Any:
    """The service and action client of a ROS 2 transport (Zenoh or DDS)."""
    from rasm.ros2.zenoh import ZenohTransport

    if isinstance(transport, ZenohTransport):
        return ZenohCalls(transport)
    raise CommError(
        f"services and actions are called over ROS 2 (zenoh:// or dds://), not over "
        f"{type(transport).__name__}"
    )


class _Cancelled(Exception):
    """A cancel was requested while waiting for a result."""
