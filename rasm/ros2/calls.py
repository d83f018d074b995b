"""ROS 2 services and actions as a client, over rmw_zenoh's and rmw_cyclonedds' conventions.

Over **Zenoh** (:class:`ZenohCalls`) a service ``/dock`` of type ``pkg/srv/Dock`` is a Zenoh
queryable on the key expression of a topic (``<domain>/dock/pkg::srv::dds_::Dock_/<RIHS01 hash
of the service>``): the request is a query whose payload is the request's CDR, with the rmw
attachment (sequence number, time stamp, the client's GID); the reply's payload is the
response's CDR.

Over **DDS** (:class:`DdsCalls`) it is two topics, as rmw_cyclonedds makes them: requests on
``rq/dockRequest`` (type ``pkg::srv::dds_::Dock_Request_``), replies on ``rr/dockReply``
(``pkg::srv::dds_::Dock_Response_``); each sample starts, right after its CDR header, with the
request id: the client's 64-bit id and the request's sequence number (``int64``), which the
reply repeats.

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
import struct
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

from rasm.errors import CommError
from rasm.ros2.types import dds_type_name
from rasm.times import format_seconds

__all__ = ["ActionGoal", "CallFailed", "DdsCalls", "GOAL_STATUS", "ZenohCalls", "calls_for"]

#: action_msgs/msg/GoalStatus's status values
GOAL_STATUS = {0: "unknown", 1: "accepted", 2: "executing", 3: "canceling", 4: "succeeded",
               5: "canceled", 6: "aborted"}
_SUCCEEDED = 4
_POLL = 0.01  # how often a waiting call looks at its answer, its feedback and a cancel


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


class _Cancelled(Exception):
    """A cancel was requested while waiting for a result."""


class _Pending:
    """A request on its way: :meth:`poll` gives the decoded response once it is there (None
    before), raising :class:`CallFailed` when none can come."""

    def poll(self) -> dict[str, Any] | None:
        raise NotImplementedError

    def close(self) -> None:
        """The answer is no longer awaited."""


class _Feedback:
    """An action's feedback subscription: :meth:`drain` hands each waiting feedback message
    (decoded) to ``take``."""

    def drain(self, take: Callable[[dict[str, Any]], object]) -> None:
        raise NotImplementedError

    def close(self) -> None:
        pass


class _Calls:
    """Service calls and action goals over a connected ROS 2 transport; a middleware gives the
    requests (:meth:`_request`) and the feedback subscription (:meth:`_feedback`)."""

    def __init__(self, transport: Any) -> None:
        self.transport = transport
        self._sequence = iter(range(1, 1 << 62))
        self._lock = threading.Lock()

    def _next(self) -> int:
        with self._lock:
            return next(self._sequence)

    def _request(self, service: str, typename: str, request: Mapping[str, Any],
                 timeout: float) -> _Pending:
        raise NotImplementedError

    def _feedback(self, action: str, typename: str) -> _Feedback:
        raise NotImplementedError

    # -- services -------------------------------------------------------------------------------
    def call(self, service: str, typename: str, request: Mapping[str, Any],
             timeout: float) -> dict[str, Any]:
        """Call ``service`` (of type ``pkg/srv/Name``, or an action's inner service) with
        ``request``; its response as a dict. :class:`CallFailed` unless a response came."""
        return self._wait(self._request(service, typename, request, timeout))

    def _wait(self, pending: _Pending, goal: ActionGoal | None = None,
              idle: Callable[[], object] | None = None) -> dict[str, Any]:
        """The response ``pending`` gives. With a ``goal``, ``idle`` runs between looks (the
        goal's feedback), and a cancel requested ends the wait (:class:`_Cancelled`)."""
        pause = threading.Event() if goal is None else goal.cancel_requested
        try:
            while True:
                answer = pending.poll()
                if answer is not None:
                    return answer
                if goal is not None and goal.cancel_requested.is_set():
                    raise _Cancelled()
                if idle is not None:
                    idle()
                pause.wait(_POLL)
        finally:
            pending.close()

    # -- actions --------------------------------------------------------------------------------
    def pursue(self, action: str, typename: str, goal_fields: Mapping[str, Any], timeout: float,
               feedback: Callable[[dict[str, Any]], object], goal: ActionGoal) -> dict[str, Any]:
        """Send ``goal_fields`` as a goal of ``action`` (type ``pkg/action/Name``) and wait for
        its result (at most ``timeout`` s from now), passing each feedback to ``feedback`` as
        it comes.

        The result as a dict when the goal succeeded; :class:`CallFailed` when it was
        refused, aborted, cancelled or timed out. A cancel requested on ``goal`` (or the
        timeout) sends a cancel request to the server before that.
        """
        deadline = time.monotonic() + timeout
        goal_id = {"uuid": list(goal.goal_id)}
        base = f"{action}/_action"
        source = self._feedback(action, typename)

        def drain() -> None:  # each feedback of this goal as it comes
            def take(message: dict[str, Any]) -> None:
                if bytes(message["goal_id"]["uuid"]) == goal.goal_id:
                    feedback(message["feedback"])

            source.drain(take)

        try:
            answer = self.call(f"{base}/send_goal", f"{typename}_SendGoal",
                               {"goal_id": goal_id, "goal": dict(goal_fields)}, timeout)
            if not answer.get("accepted"):
                raise CallFailed(f"action {action}: the server refused the goal")
            remaining = max(deadline - time.monotonic(), 0.001)
            pending = self._request(f"{base}/get_result", f"{typename}_GetResult",
                                    {"goal_id": goal_id}, remaining)
            try:
                result = self._wait(pending, goal, drain)
            except _Cancelled:
                self._cancel(base, goal_id, deadline)
                raise CallFailed(
                    f"action {action}: goal cancelled ({goal.cancel_reason})") from None
            except CallFailed as exc:
                if "no response within" in str(exc):
                    self._cancel(base, goal_id, deadline + 1.0)
                    raise CallFailed(
                        f"action {action}: no result within {format_seconds(timeout)} s "
                        "(goal cancelled)"
                    ) from None
                raise
            drain()
        finally:
            source.close()
        status = result.get("status")
        if status != _SUCCEEDED:
            raise CallFailed(f"action {action}: goal {GOAL_STATUS.get(status, status)}")
        return result["result"]

    def _cancel(self, base: str, goal_id: dict, deadline: float) -> None:
        """Ask the server to cancel the goal (its answer is awaited briefly, not required)."""
        try:
            self.call(f"{base}/cancel_goal", "action_msgs/srv/CancelGoal",
                      {"goal_info": {"goal_id": goal_id}},
                      max(deadline - time.monotonic(), 1.0))
        except CallFailed:
            pass


def _decode_response(store: Any, service: str, typename: str, data: bytes) -> dict[str, Any]:
    try:
        return store.codec(f"{typename}_Response").decode(data)
    except CommError as exc:
        raise CallFailed(f"service {service}: its response does not decode: {exc}") from None


# -- Zenoh ----------------------------------------------------------------------------------------
class _ZenohPending(_Pending):
    def __init__(self, store: Any, service: str, typename: str, replies: Any,
                 timeout: float) -> None:
        self.store, self.service, self.typename = store, service, typename
        self.replies = replies
        self.timeout = timeout
        self.started = time.monotonic()

    def poll(self) -> dict[str, Any] | None:
        import zenoh

        try:
            reply = self.replies.try_recv()
        except zenoh.ZError:  # the channel ended: every reply is in, or the query timed out
            if time.monotonic() - self.started >= self.timeout * 0.9:
                raise CallFailed(f"service {self.service}: no response within "
                                 f"{format_seconds(self.timeout)} s") from None
            raise CallFailed(f"service {self.service}: no server answers ({self.typename} on "
                             "this network)") from None
        if reply is None:
            return None
        if reply.ok is None:
            error = reply.err.payload.to_string()[:200]
            if error == "Timeout":  # what Zenoh itself replies when the query times out
                raise CallFailed(f"service {self.service}: no response within "
                                 f"{format_seconds(self.timeout)} s")
            raise CallFailed(f"service {self.service} answered an error: {error}")
        return _decode_response(self.store, self.service, self.typename,
                                reply.ok.payload.to_bytes())


class _ZenohFeedback(_Feedback):
    def __init__(self, subscriber: Any, codec: Any) -> None:
        self.subscriber = subscriber
        self.codec = codec

    def drain(self, take: Callable[[dict[str, Any]], object]) -> None:
        while (sample := self.subscriber.handler.try_recv()) is not None:
            try:
                message = self.codec.decode(sample.payload.to_bytes())
            except CommError:
                continue  # a malformed feedback is no feedback
            take(message)

    def close(self) -> None:
        self.subscriber.undeclare()


class ZenohCalls(_Calls):
    """Service calls and action goals on a connected :class:`~rasm.ros2.zenoh.ZenohTransport`
    (its session, domain, type store and attachments)."""

    def __init__(self, transport: Any) -> None:
        super().__init__(transport)
        self._gid = os.urandom(16)

    def _request(self, service: str, typename: str, request: Mapping[str, Any],
                 timeout: float) -> _Pending:
        from rasm.ros2.zenoh import attachment, topic_key

        store = self.transport.store
        data = store.codec(f"{typename}_Request").encode(request)
        key = topic_key(self.transport.domain, service, dds_type_name(typename),
                        store.type_hash(typename))
        session = self.transport.session
        if session is None:
            raise CallFailed(f"service {service}: the transport is not connected")
        replies = session.get(key, payload=data, timeout=timeout,
                              attachment=attachment(self._next(), time.time_ns(), self._gid))
        return _ZenohPending(store, service, typename, replies, timeout)

    def _feedback(self, action: str, typename: str) -> _Feedback:
        import zenoh

        from rasm.ros2.zenoh import topic_key

        store = self.transport.store
        fb_type = f"{typename}_FeedbackMessage"
        key = topic_key(self.transport.domain, f"{action}/_action/feedback",
                        dds_type_name(fb_type), store.type_hash(fb_type))
        subscriber = self.transport.session.declare_subscriber(
            key, zenoh.handlers.FifoChannel(256))
        return _ZenohFeedback(subscriber, store.codec(fb_type))


# -- DDS ------------------------------------------------------------------------------------------
_REQUEST_ID = struct.Struct("<Qq")  # the client's id, the request's sequence number


class _DdsService:
    """One service's request writer and reply reader, shared by the calls to it; replies are
    taken by whichever call looks and kept by sequence number for the call they answer."""

    def __init__(self, calls: DdsCalls, service: str, typename: str) -> None:
        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        store = calls.transport.store
        self.service, self.typename, self.store = service, typename, store
        participant = calls.transport.participant
        if participant is None:
            raise CallFailed(f"service {service}: the transport is not connected")
        request, response = f"{typename}_Request", f"{typename}_Response"
        self.writer = DataWriter(participant, Topic(
            participant, f"rq{service}Request", calls.wrapped(request)),
            qos=calls.qos(request))
        self.reader = DataReader(participant, Topic(
            participant, f"rr{service}Reply", calls.wrapped(response)),
            qos=calls.qos(response))
        self.client = calls.client_id
        self.lock = threading.Lock()
        self.answers: dict[int, bytes] = {}

    def matched(self) -> bool:
        """Whether a server reads the requests and writes the replies back to us."""
        return bool(self.writer.get_matched_subscriptions()) and bool(
            self.reader.get_matched_publications())

    def send(self, sequence: int, data: bytes) -> None:
        from cyclonedds._clayer import ddspy_write

        wire = data[:4] + _REQUEST_ID.pack(self.client, sequence) + data[4:]
        if ddspy_write(self.writer._ref, wire + b"\0" * (-len(wire) % 4)) < 0:
            raise CallFailed(f"service {self.service}: the request could not be written")

    def answer(self, sequence: int) -> bytes | None:
        """The reply to request ``sequence``, once it is here (replies to others are kept)."""
        from cyclonedds._clayer import ddspy_take
        from cyclonedds.core import InstanceState, SampleState, ViewState

        with self.lock:
            while True:
                samples = ddspy_take(self.reader._ref,
                                     SampleState.Any | ViewState.Any | InstanceState.Any, 64)
                if isinstance(samples, int) or not samples:
                    break
                for data, info in samples:
                    if not info.valid_data or len(data) < 20:
                        continue
                    client, number = _REQUEST_ID.unpack_from(data, 4)
                    if client == self.client and len(self.answers) < 1024:
                        self.answers[number] = data[:4] + data[20:]
            return self.answers.pop(sequence, None)

    def forget(self, sequence: int) -> None:
        with self.lock:
            self.answers.pop(sequence, None)


class _DdsPending(_Pending):
    def __init__(self, service: _DdsService, sequence: int, timeout: float) -> None:
        self.service, self.sequence, self.timeout = service, sequence, timeout
        self.deadline = time.monotonic() + timeout

    def poll(self) -> dict[str, Any] | None:
        data = self.service.answer(self.sequence)
        if data is not None:
            return _decode_response(self.service.store, self.service.service,
                                    self.service.typename, data)
        if time.monotonic() >= self.deadline:
            raise CallFailed(f"service {self.service.service}: no response within "
                             f"{format_seconds(self.timeout)} s")
        return None

    def close(self) -> None:
        self.service.forget(self.sequence)


class _DdsFeedback(_Feedback):
    def __init__(self, reader: Any, codec: Any) -> None:
        self.reader, self.codec = reader, codec

    def drain(self, take: Callable[[dict[str, Any]], object]) -> None:
        from cyclonedds._clayer import ddspy_take
        from cyclonedds.core import InstanceState, SampleState, ViewState

        while True:
            samples = ddspy_take(self.reader._ref,
                                 SampleState.Any | ViewState.Any | InstanceState.Any, 64)
            if isinstance(samples, int) or not samples:
                return
            for data, info in samples:
                if not info.valid_data:
                    continue
                try:
                    message = self.codec.decode(data)
                except CommError:
                    continue  # a malformed feedback is no feedback
                take(message)

    def close(self) -> None:
        self.reader.__del__()  # stop receiving now, not at collection


class DdsCalls(_Calls):
    """Service calls and action goals on a connected :class:`~rasm.ros2.dds.DdsTransport`, as
    rmw_cyclonedds makes them (see the module doc). A server must be matched (discovered)
    within the call's timeout, else the call fails as no server answering."""

    def __init__(self, transport: Any) -> None:
        super().__init__(transport)
        self.client_id = int.from_bytes(os.urandom(8), "little")
        self._services: dict[str, _DdsService] = {}
        self._structs: dict[str, Any] = {}

    def wrapped(self, typename: str) -> Any:
        """The DDS struct of a request or reply: the request id, then the message's fields."""
        from cyclonedds.idl import make_idl_struct
        from cyclonedds.idl import types as idl

        from rasm.ros2.dds import idl_struct

        found = self._structs.get(typename)
        if found is None:
            inner = idl_struct(self.transport.store, typename)
            fields = {"request_guid": idl.uint64, "request_seq": idl.int64,
                      **inner.__annotations__}
            found = self._structs[typename] = make_idl_struct(
                f"{typename.replace('/', '_')}_wrapped", dds_type_name(typename), fields)
        return found

    def qos(self, typename: str) -> Any:
        """ROS 2's services QoS (reliable, volatile, keep last 10), with the type's hash."""
        from rasm.ros2.dds import _qos
        from rasm.ros2.qos import QosProfile

        return _qos(QosProfile(), self.transport.store.type_hash(typename))

    def _service(self, service: str, typename: str) -> _DdsService:
        with self._lock:
            found = self._services.get(service)
            if found is None:
                found = self._services[service] = _DdsService(self, service, typename)
            return found

    def _request(self, service: str, typename: str, request: Mapping[str, Any],
                 timeout: float) -> _Pending:
        endpoint = self._service(service, typename)
        data = self.transport.store.codec(f"{typename}_Request").encode(request)
        deadline = time.monotonic() + timeout
        pause = threading.Event()
        while not endpoint.matched():  # discovery takes a moment; nobody: no server
            if time.monotonic() >= deadline:
                raise CallFailed(f"service {service}: no server answers ({typename} on this "
                                 "network)")
            pause.wait(_POLL)
        sequence = self._next()
        endpoint.send(sequence, data)
        return _DdsPending(endpoint, sequence, max(deadline - time.monotonic(), 0.001))

    def _feedback(self, action: str, typename: str) -> _Feedback:
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        from rasm.ros2.dds import idl_struct

        participant = self.transport.participant
        fb_type = f"{typename}_FeedbackMessage"
        topic = Topic(participant, f"rt{action}/_action/feedback",
                      idl_struct(self.transport.store, fb_type))
        return _DdsFeedback(DataReader(participant, topic, qos=self.qos(fb_type)),
                            self.transport.store.codec(fb_type))


def calls_for(transport: Any) -> _Calls:
    """The service and action client of a ROS 2 transport (Zenoh or DDS)."""
    from rasm.ros2.transport import RosTransport

    if isinstance(transport, RosTransport):
        from rasm.ros2.dds import DdsTransport
        from rasm.ros2.zenoh import ZenohTransport

        if isinstance(transport, ZenohTransport):
            return ZenohCalls(transport)
        if isinstance(transport, DdsTransport):
            return DdsCalls(transport)
    raise CommError(
        f"services and actions are called over ROS 2 (zenoh:// or dds://), not over "
        f"{type(transport).__name__}"
    )
