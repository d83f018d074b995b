"""Node presence: advertise start-up, periodic presence and shutdown; follow others.

Every node owns the topic ``rasm/presence/<node>``:

- start-up: ``{"state": "online", "role": …, "period": P, "seq": 0, **info}`` (retained where
  the transport can retain, so a tracker started later learns of the node at once); ``info``
  carries what the node tells others about itself, e.g. its ``app`` and the ``epoch`` that signed
  actions and updates must be bound to (:mod:`rasm.comm.signing`);
- every ``period`` seconds a heartbeat, the same payload with a growing ``seq``;
- a clean shutdown: ``{"state": "offline", "role": …, "reason": "shutdown"}`` (retained);
- a crash: the broker publishes the node's last will, ``{"state": "offline", "reason":
  "lost"}`` (retained). The will must be given when the MQTT transport is created:
  ``MqttTransport(url, will=presence_will(node, role))``.

:class:`PresenceTracker` follows every node: ``online`` (start-up or a heartbeat), ``offline``
(shutdown or will), ``silent`` (online, but no heartbeat for ``timeout`` seconds: hung, or cut
off without the broker noticing yet). Silence is detected by a timer thread that sleeps until the
earliest deadline, never by polling.

Signed presence (with a shared key, ``RASM_ACTION_KEY`` in ``rasm run``): a :class:`Presence`
given a ``signer`` signs every message it sends, bound (:class:`rasm.comm.signing.BoundSigner`)
to the epochs of the receivers it knows (``receivers()``; none at first: such a message only
introduces its sender). A :class:`PresenceTracker` given a ``gate`` counts an ``online``
message only when it is signed with the key *and* bound to the tracker's own epoch, newer than
every one admitted from its sender's run: a forged heartbeat (unsigned, or a replay of a real
one) is refused, counted in ``refused`` and cannot keep a dead node online. A correctly signed
message bound to someone else introduces its sender (:meth:`PresenceTracker.known_epochs`), so
the two sides learn each other's epochs within a period or two. ``offline`` messages count from
anyone, signed or not: they can only stop things (the broker publishes the unsigned will).
"""

from __future__ import annotations

import inspect
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rasm.comm.message import Message
from rasm.comm.signing import BINDING, BoundSigner, SignedGate
from rasm.comm.topics import validate_topic
from rasm.comm.transport import Subscription, Transport
from rasm.errors import CommError
from rasm.logs import RepeatedLogs
from rasm.times import format_seconds

__all__ = [
    "PRESENCE_PREFIX",
    "NodeState",
    "Presence",
    "PresenceTracker",
    "presence_topic",
    "presence_will",
]

_log = logging.getLogger("rasm.comm.presence")

PRESENCE_PREFIX = "rasm/presence"
STATES = ("online", "offline", "silent")
_OWN_FIELDS = ("state", "role", "period", "seq", "reason")


def presence_topic(node: str) -> str:
    """``rasm/presence/<node>``; :class:`CommError` if ``node`` is not one topic level."""
    if not isinstance(node, str) or not node or any(c in node for c in "/+#\0"):
        raise CommError(
            f"node name {node!r} must be non-empty text without '/', '+', '#' (it is one "
            "level of the topic rasm/presence/<node>)"
        )
    topic = f"{PRESENCE_PREFIX}/{node}"
    validate_topic(topic)
    return topic


def presence_will(node: str, role: str | None = None) -> Any:
    """The last will that marks ``node`` offline if it vanishes: pass it as
    ``MqttTransport(url, will=presence_will(node, role))`` (retained, QoS 1)."""
    from rasm.comm.mqtt import Will  # paho only when MQTT is used

    return Will(
        presence_topic(node),
        {"state": "offline", "role": role, "reason": "lost"},
        qos=1,
        retain=True,
    )


def _publish(transport: Transport, topic: str, payload: dict[str, Any], retain: bool) -> None:
    # Transport.publish has no retain parameter yet; use it as soon as a transport offers one.
    if retain and "retain" in inspect.signature(transport.publish).parameters:
        transport.publish(topic, payload, qos=1, retain=True)  # type: ignore[call-arg]
    else:
        transport.publish(topic, payload, qos=1)


class Presence:
    """Advertises one node: start-up on :meth:`start`, a heartbeat every ``period`` seconds,
    shutdown on :meth:`stop`. Also a context manager.

    The transport must be connected (and, over MQTT, created with :func:`presence_will` so a
    crash is advertised too). Heartbeats come from a daemon thread; a failed publish (broker
    away) is logged and the next heartbeat tries again. ``info``: more fields of every online
    message (start-up and heartbeats), e.g. ``{"epoch": gate.epoch}``. With a ``signer``
    every message is signed, bound to the epochs ``receivers()`` gives at the time (see the
    module docstring).
    """

    def __init__(
        self,
        transport: Transport,
        node: str,
        *,
        role: str | None = None,
        period: float = 1.0,
        info: dict[str, Any] | None = None,
        signer: BoundSigner | None = None,
        receivers: Callable[[], list[str]] = list,
    ) -> None:
        if not isinstance(period, int | float) or isinstance(period, bool) or not period > 0:
            raise CommError(f"presence period must be a positive number of seconds: {period!r}")
        clash = sorted(set(info or ()) & set(_OWN_FIELDS))
        if clash:
            raise CommError(f"presence info must not set the presence's own fields: {clash}")
        self.transport = transport
        self.node = node
        self.role = role
        self.period = float(period)
        self.topic = presence_topic(node)
        self.info = dict(info or {})
        self.signer = signer
        self.receivers = receivers
        self.heartbeats = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _online(self, seq: int) -> dict[str, Any]:
        return {
            "state": "online",
            "role": self.role,
            "period": self.period,
            "seq": seq,
            **self.info,
        }

    def _sealed(self, payload: dict[str, Any]) -> dict[str, Any]:
        if self.signer is None:
            return payload
        epochs = sorted(self.receivers())
        return self.signer.sign(payload, topic=self.topic, epochs=epochs, unbound=True)

    def start(self) -> Presence:
        """Announce start-up and start the heartbeats; returns self."""
        if self._thread is not None:
            return self
        _publish(self.transport, self.topic, self._sealed(self._online(0)), retain=True)
        self._thread = threading.Thread(
            target=self._beat, name=f"rasm-presence-{self.node}", daemon=True
        )
        self._thread.start()
        return self

    def _beat(self) -> None:
        seq = 0
        while not self._stop.wait(self.period):  # the wait is the timer: stop() ends it at once
            seq += 1
            try:
                _publish(self.transport, self.topic, self._sealed(self._online(seq)), retain=False)
                self.heartbeats += 1
            except CommError as exc:
                _log.warning("presence heartbeat of %s not sent: %s", self.node, exc)

    def stop(self) -> None:
        """Stop the heartbeats and announce shutdown (idempotent). Close the transport after."""
        if self._thread is None or self._stop.is_set():
            return
        self._stop.set()
        self._thread.join(timeout=5.0)
        try:
            _publish(
                self.transport,
                self.topic,
                self._sealed({"state": "offline", "role": self.role, "reason": "shutdown"}),
                retain=True,
            )
        except CommError as exc:
            _log.warning("shutdown of %s not announced: %s", self.node, exc)

    def __enter__(self) -> Presence:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


@dataclass
class NodeState:
    """What a tracker knows of one node."""

    node: str
    state: str
    role: str | None = None
    last_seen: float = 0.0  # time.monotonic() of its last message
    reason: str | None = None
    payload: dict[str, Any] = field(default_factory=dict)


OnChange = Callable[[str, str], object]


class PresenceTracker:
    """Follows every node's presence: ``online``, ``offline`` or ``silent``.

    ``on_change(node, state)`` is called at every change of state (a new node counts), in the
    order the changes happen, from the transport's delivery thread or the tracker's timer thread,
    while the tracker is locked: keep it short (it may read :meth:`nodes`). ``timeout`` is how
    long an online node may stay without a heartbeat before it is ``silent``; a heartbeat makes a
    silent node online again. With a ``gate`` only signed heartbeats bound to the gate's epoch
    count (see the module docstring); the others are counted in :attr:`refused`.
    """

    def __init__(
        self,
        transport: Transport,
        *,
        timeout: float = 3.0,
        on_change: OnChange | None = None,
        gate: SignedGate | None = None,
    ) -> None:
        if not isinstance(timeout, int | float) or isinstance(timeout, bool) or not timeout > 0:
            raise CommError(f"presence timeout must be a positive number of seconds: {timeout!r}")
        self.transport = transport
        self.timeout = float(timeout)
        self.on_change = on_change
        self.gate = gate
        self.malformed = 0
        self.refused = 0  # online messages a gate refused: unsigned, forged or replayed
        # nodes that introduced themselves with a correct signature: name -> (role, app, epoch)
        self._introduced: dict[str, tuple[Any, Any, str]] = {}
        self.logs = RepeatedLogs()
        self._nodes: dict[str, NodeState] = {}
        self._cond = threading.Condition(threading.RLock())
        self._stopped = False
        self._subscription: Subscription | None = None
        self._timer: threading.Thread | None = None

    def start(self) -> PresenceTracker:
        """Subscribe to ``rasm/presence/+`` and start the silence timer; returns self."""
        if self._subscription is None:
            self._timer = threading.Thread(
                target=self._watch, name="rasm-presence-tracker", daemon=True
            )
            self._timer.start()
            self._subscription = self.transport.subscribe(
                f"{PRESENCE_PREFIX}/+", self._receive, qos=1
            )
        return self

    def stop(self) -> None:
        """Unsubscribe and end the timer (idempotent)."""
        if self._subscription is not None:
            self._subscription.cancel()
        with self._cond:
            self._stopped = True
            self._cond.notify_all()
        if self._timer is not None and self._timer is not threading.current_thread():
            self._timer.join(timeout=5.0)

    def __enter__(self) -> PresenceTracker:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def nodes(self) -> dict[str, NodeState]:
        """A copy of every known node's state, by name."""
        with self._cond:
            return {
                name: NodeState(s.node, s.state, s.role, s.last_seen, s.reason, dict(s.payload))
                for name, s in self._nodes.items()
            }

    def epochs(self, *, role: str | None = None, app: str | None = None) -> dict[str, str]:
        """The announced ``epoch`` of every online node (of ``role`` and ``app`` when given), by
        name: what a signer binds its messages to (:class:`rasm.comm.BoundSigner`)."""
        with self._cond:
            return {
                name: known.payload["epoch"]
                for name, known in self._nodes.items()
                if known.state == "online"
                and (role is None or known.role == role)
                and (app is None or known.payload.get("app") == app)
                and isinstance(known.payload.get("epoch"), str)
                and 0 < len(known.payload["epoch"]) <= 128
            }

    def known_epochs(self, *, role: str | None = None, app: str | None = None) -> list[str]:
        """With a gate: the epochs of the nodes (of ``role`` and ``app`` when given) that
        introduced themselves with a correctly signed message and have not gone offline since,
        online or not yet verified; what a :class:`Presence` binds its own heartbeats to.
        Without a gate: :meth:`epochs`."""
        if self.gate is None:
            return sorted(self.epochs(role=role, app=app).values())
        with self._cond:
            return sorted(
                epoch
                for known_role, known_app, epoch in self._introduced.values()
                if (role is None or known_role == role) and (app is None or known_app == app)
            )

    def state(self, node: str) -> str | None:
        """``online``, ``offline``, ``silent``, or None for a node never heard of."""
        with self._cond:
            known = self._nodes.get(node)
            return known.state if known is not None else None

    # -- internals ------------------------------------------------------------------------------
    def _receive(self, message: Message) -> None:
        node = message.topic.rsplit("/", 1)[-1]
        payload = message.payload
        state = payload.get("state")
        role = payload.get("role")
        if state not in ("online", "offline") or not (role is None or isinstance(role, str)):
            with self._cond:
                self.malformed += 1
            self.logs.log(
                _log, logging.WARNING, f"malformed presence message on {message.topic!r} ignored",
                "malformed presence message on %r ignored: %r", message.topic, payload,
            )
            return
        if state == "online" and self.gate is not None and not self._admitted(message):
            return
        reason = payload.get("reason")
        with self._cond:
            if state == "offline":
                # that incarnation is gone; one under the same name (a restart, a container's
                # pid) introduces itself anew, even while this tracker still holds it offline
                self._introduced.pop(node, None)
            known = self._nodes.get(node)
            if known is None:
                known = self._nodes[node] = NodeState(node, "new")
            before = known.state
            known.state = state
            known.role = role
            known.last_seen = time.monotonic()
            known.reason = reason if isinstance(reason, str) else None
            known.payload = dict(payload)
            if state == "online":
                self._cond.notify_all()  # the timer recomputes its earliest deadline
            if before != state:
                self._changed(node, state)

    def _admitted(self, message: Message) -> bool:
        """Whether a gate admits an online message as a heartbeat; a correctly signed one that
        is bound elsewhere only introduces its sender."""
        payload = message.payload
        node = message.topic.rsplit("/", 1)[-1]
        if self.gate.signed(payload):
            epoch = payload.get("epoch")
            if isinstance(epoch, str) and 0 < len(epoch) <= 128:
                with self._cond:
                    if node in self._introduced or len(self._introduced) < 10_000:
                        self._introduced[node] = (payload.get("role"), payload.get("app"), epoch)
            binding = payload.get(BINDING)
            epochs = binding.get("epochs") if isinstance(binding, dict) else None
            if not isinstance(epochs, list) or self.gate.epoch not in epochs:
                return False  # an introduction, not a heartbeat for this tracker
        why = self.gate.check(payload, message.topic)
        if why is None:
            return True
        with self._cond:
            self.refused += 1
        self.logs.log(
            _log, logging.WARNING, f"presence on {message.topic} refused: {why.split(':')[0]}",
            "presence message on %r refused (it does not count as a heartbeat): %s",
            message.topic, why,
        )
        return False

    def _changed(self, node: str, state: str) -> None:
        if state == "offline":
            _log.info("node %s is offline", node)
        elif state == "silent":
            _log.warning(
                "node %s is silent (no heartbeat for %s s)", node, format_seconds(self.timeout)
            )
        if self.on_change is not None:
            try:
                self.on_change(node, state)
            except Exception:
                _log.exception("presence on_change(%r, %r) raised", node, state)

    def _watch(self) -> None:
        with self._cond:
            while not self._stopped:
                now = time.monotonic()
                earliest: float | None = None
                for known in list(self._nodes.values()):
                    if known.state != "online":
                        continue
                    deadline = known.last_seen + self.timeout
                    if deadline <= now:
                        known.state = "silent"
                        self._changed(known.node, "silent")
                    elif earliest is None or deadline < earliest:
                        earliest = deadline
                # sleeps until the earliest deadline, or until a message or stop() wakes it
                self._cond.wait(None if earliest is None else earliest - now)
