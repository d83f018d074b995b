"""Signed messages (HMAC-SHA256): run-time updates and actions only the key holder can send.

A signed payload is the payload plus a ``signature`` field: the hex HMAC-SHA256, under a shared
key, of the canonical JSON of every other field (keys sorted at every depth, no spaces, UTF-8,
no NaN or infinities). So the signature does not depend on key order or on the transport, and
any change of any field, at any depth, or a different key, makes :func:`verify` fail.

:class:`UpdateReceiver` applies property and rule updates received on ``rasm/update/...`` only
when they are correctly signed; :class:`SignedEffector` passes to an effector only the actions the
Trustworthiness Checker signed. Both log every refusal with its reason.

A correct signature alone would let anyone replay a captured message, in the same run or after
a restart. So every signed action and update also carries a ``binding``: the incarnations
(``epochs``) of the receivers it is meant for, the sender's ``run`` and a ``seq`` that grows
within that run, and the ``topic`` it was sent on (:class:`BoundSigner` fills it in). A receiver
draws a random epoch when it starts and announces it (in its presence message); its
:class:`ReplayGuard` admits a message only if the binding names that epoch and the topic it came
on, and its ``seq`` is above every one admitted from the same run. A restarted receiver has a
new epoch and admits nothing sent to its previous incarnation; a restarted sender has a new run
id and starts afresh.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import logging
import secrets
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from rasm.comm.message import Message
from rasm.comm.transport import Subscription, Transport
from rasm.errors import CommError
from rasm.logs import RepeatedLogs

__all__ = [
    "BINDING",
    "SIGNATURE",
    "UPDATE_TOPICS",
    "Applier",
    "BoundSigner",
    "ReplayGuard",
    "SignedEffector",
    "SignedGate",
    "UpdateOutcome",
    "UpdateReceiver",
    "canonical",
    "new_epoch",
    "sign",
    "unsealed",
    "verify",
]

_log = logging.getLogger("rasm.comm.signing")

SIGNATURE = "signature"
"""The field that carries the signature."""

BINDING = "binding"
"""The signed field that binds a message to its receivers' incarnations, its sender's run and
sequence, and its topic: ``{"epochs": [str, ...], "run": str, "seq": int, "topic": str}``."""

_MAX_ID = 128  # characters of an epoch or run id: longer ones are refused, not stored

UPDATE_TOPICS: dict[str, tuple[str, str]] = {
    "properties": ("rasm/update/properties", "spec"),
    "rules": ("rasm/update/rules", "rules"),
}
"""Update kind -> (topic, payload field carrying the new text)."""

Applier = Callable[[str], tuple[bool, str]]
"""Applies an update's text; returns ``(accepted, reason)`` (e.g. ``RuleSet.swap_text``)."""


def _check_key(key: bytes) -> bytes:
    if not isinstance(key, bytes | bytearray) or not key:
        raise CommError(
            "a signing key must be non-empty bytes (e.g. secrets.token_bytes(32), or "
            "bytes.fromhex(...) of a key kept outside the repository)"
        )
    return bytes(key)


def canonical(payload: Mapping[str, Any]) -> bytes:
    """The bytes a signature covers: ``payload`` without ``signature``, as canonical JSON.

    Raises :class:`CommError` for what JSON cannot carry faithfully (NaN, infinities, non-str
    keys, objects).
    """
    if not isinstance(payload, Mapping):
        raise CommError(f"only a dict payload can be signed, got {type(payload).__name__}")
    body = {k: v for k, v in payload.items() if k != SIGNATURE}
    try:
        text = json.dumps(
            body, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False
        )
    except (TypeError, ValueError) as exc:
        raise CommError(f"cannot sign this payload: {exc}") from exc
    return text.encode("utf-8")


def _digest(payload: Mapping[str, Any], key: bytes) -> str:
    return hmac.new(key, canonical(payload), hashlib.sha256).hexdigest()


def sign(payload: Mapping[str, Any], key: bytes) -> dict[str, Any]:
    """A copy of ``payload`` with a ``signature`` field over every other field.

    An existing ``signature`` is replaced. The payload must be JSON (str keys; no NaN).
    """
    signed = {k: v for k, v in payload.items() if k != SIGNATURE}
    signed[SIGNATURE] = _digest(signed, _check_key(key))
    return signed


def verify(payload: Any, key: bytes) -> bool:
    """True iff ``payload`` carries a signature made with ``key`` over exactly its other fields.

    Never raises on a bad payload (unsigned, not a dict, not JSON): that is simply False. The
    comparison takes constant time.
    """
    key = _check_key(key)
    if not isinstance(payload, Mapping):
        return False
    given = payload.get(SIGNATURE)
    if not isinstance(given, str):
        return False
    try:
        expected = _digest(payload, key)
    except CommError:
        return False
    return hmac.compare_digest(expected.encode(), given.encode("utf-8", "replace"))


def _why_refused(payload: Any, key: bytes) -> str | None:
    """None if correctly signed, else the reason in words."""
    if not isinstance(payload, Mapping) or SIGNATURE not in payload:
        return "unsigned"
    if not verify(payload, key):
        return "bad signature"
    return None


# --------------------------------------------------------------------------- binding


def new_epoch() -> str:
    """A random incarnation id (128 bits, hex): draw one at every start of a receiver."""
    return secrets.token_hex(16)


class BoundSigner:
    """Signs payloads bound to their receivers' incarnations, with a growing sequence.

    ``run`` identifies this sender's run (random unless given); :meth:`sign` numbers the
    messages it signs 1, 2, 3, … within that run. A sender that restarts must take a new run id
    (the default does): its receivers admit from a run only sequences above the last they
    admitted from it.
    """

    def __init__(self, key: bytes, *, run: str | None = None) -> None:
        self._key = _check_key(key)
        self.run = run if run is not None else secrets.token_hex(8)
        if not isinstance(self.run, str) or not 0 < len(self.run) <= _MAX_ID:
            raise CommError(f"a run id must be text of 1 to {_MAX_ID} characters: {run!r}")
        self.seq = 0  # the sequence number of the last message signed

    def sign(
        self, payload: Mapping[str, Any], *, topic: str, epochs: list[str], unbound: bool = False
    ) -> dict[str, Any]:
        """``payload`` with a :data:`BINDING` for ``epochs`` and ``topic``, signed.

        ``epochs``: the announced epochs of the receivers meant (at least one; a message bound
        to none would be refused by every receiver, so that is an error here, unless
        ``unbound``: a presence message that only introduces its sender may be bound to none).
        """
        if not epochs and not unbound:
            raise CommError(
                "nothing to bind the message to: no receiver has announced its epoch yet"
            )
        self.seq += 1
        binding = {"epochs": list(epochs), "run": self.run, "seq": self.seq, "topic": topic}
        return sign({**payload, BINDING: binding}, self._key)


class ReplayGuard:
    """The receiver's half of the binding: admits each bound message at most once, in order.

    ``epoch`` is this receiver's incarnation (a fresh :func:`new_epoch` unless given). The
    guard remembers, per sender run, the highest sequence it admitted: that is one integer per
    run of a key holder's sender seen during this incarnation, whatever the traffic.
    """

    def __init__(self, epoch: str | None = None) -> None:
        self.epoch = epoch if epoch is not None else new_epoch()
        self._last: dict[str, int] = {}

    def admit(self, binding: Any, topic: str | None) -> str | None:
        """None if the message may pass (and it is remembered as admitted), else why not.

        ``topic``: where the message was received (None: not checked).
        """
        if not isinstance(binding, Mapping):
            return (
                f"signed, but not bound to a receiver's incarnation (no {BINDING!r} field): "
                "it could be a replay"
            )
        epochs, run, seq = binding.get("epochs"), binding.get("run"), binding.get("seq")
        if not isinstance(epochs, list) or self.epoch not in epochs:
            return (
                "signed for another incarnation of this receiver (a replay from an earlier "
                "run, or sent before the sender saw this process's epoch)"
            )
        if topic is not None and binding.get("topic") != topic:
            return f"signed for topic {binding.get('topic')!r}, received on {topic!r}"
        if not isinstance(run, str) or not 0 < len(run) <= _MAX_ID:
            return f"signed, but the binding's run id is not valid: {run!r}"
        if isinstance(seq, bool) or not isinstance(seq, int) or seq < 1:
            return f"signed, but the binding's sequence is not a positive integer: {seq!r}"
        last = self._last.get(run)
        if last is not None and seq <= last:
            return f"replayed or stale: sequence {seq} of run {run} after {last}"
        self._last[run] = seq
        return None


# --------------------------------------------------------------------------- updates


@dataclass(frozen=True)
class UpdateOutcome:
    """What became of one received update: ``kind`` (properties | rules), accepted or not, why."""

    kind: str
    accepted: bool
    reason: str
    uid: str | None
    time: float


class UpdateReceiver:
    """Applies signed property and rule updates received on a transport; refuses the rest.

    Subscribes to ``rasm/update/properties`` (payload ``{"spec": TEXT, "binding": …,
    "signature": …}``) and ``rasm/update/rules`` (``{"rules": TEXT, …}``) for the appliers
    given. An update reaches its applier only if signed with ``key`` and its binding passes
    this receiver's :class:`ReplayGuard` (bound to ``epoch``, on the topic it came on, newer
    than what was admitted from its sender's run); the applier returns ``(accepted, reason)``
    (e.g. ``lambda text: tuple(ruleset.swap_text(text))``-like: a refused inconsistent rule set
    is a refusal, not an error; an applier that raises is a refusal too). An update admitted
    by the guard counts as used even when its applier refuses it: sending it again is a replay.

    ``epoch`` is this process's incarnation (a fresh one unless given), to be announced where
    senders can read it (the platform's presence message). Every outcome is logged, kept in
    :attr:`outcomes` (the last ``keep``), passed to ``on_outcome``, and, if ``reply`` is true,
    published on ``rasm/update/result`` as ``{"kind", "accepted", "reason", "update",
    "epoch"}`` (``update``: the update message's envelope uid) so the sender learns what
    happened, and the epoch to bind its next update to.
    """

    def __init__(
        self,
        transport: Transport,
        key: bytes,
        *,
        properties: Applier | None = None,
        rules: Applier | None = None,
        on_outcome: Callable[[UpdateOutcome], object] | None = None,
        reply: bool = True,
        keep: int = 100,
        epoch: str | None = None,
    ) -> None:
        self.transport = transport
        self._key = _check_key(key)
        self._appliers = {"properties": properties, "rules": rules}
        self.on_outcome = on_outcome
        self.reply = reply
        self.outcomes: deque[UpdateOutcome] = deque(maxlen=keep)
        self.refused = 0  # every refusal, not only those still in ``outcomes``
        self.guard = ReplayGuard(epoch)
        self.logs = RepeatedLogs()
        self._lock = threading.Lock()  # one update at a time: appliers are not re-entered
        self._subscriptions: list[Subscription] = []

    def start(self) -> UpdateReceiver:
        """Subscribe to the update topics of the appliers given; returns self."""
        for kind, applier in self._appliers.items():
            if applier is None:
                continue
            topic, _ = UPDATE_TOPICS[kind]
            self._subscriptions.append(
                self.transport.subscribe(topic, lambda m, k=kind: self.receive(k, m), qos=1)
            )
        return self

    def stop(self) -> None:
        """Unsubscribe (idempotent)."""
        for subscription in self._subscriptions:
            subscription.cancel()
        self._subscriptions.clear()

    @property
    def epoch(self) -> str:
        """This receiver's incarnation: updates must be bound to it."""
        return self.guard.epoch

    def receive(self, kind: str, message: Message) -> UpdateOutcome:
        """Judge and (if correctly signed and bound) apply one update; usable without a
        transport too (the binding's topic is then checked against ``message.topic``)."""
        with self._lock:
            accepted, reason = self._judge(kind, message)
            outcome = UpdateOutcome(kind, accepted, reason, message.uid, time.time())
            self.outcomes.append(outcome)
            self.refused += not accepted
        if accepted:
            _log.info("%s update accepted: %s", kind, reason)
        else:
            self.logs.log(
                _log, logging.WARNING, f"{kind} update refused: {reason.split(':')[0]}",
                "%s update refused: %s", kind, reason,
            )
        if self.on_outcome is not None:
            try:
                self.on_outcome(outcome)
            except Exception:
                _log.exception("on_outcome raised on %r", outcome)
        if self.reply:
            try:
                self.transport.publish(
                    "rasm/update/result",
                    {
                        "kind": kind,
                        "accepted": accepted,
                        "reason": reason,
                        "update": message.uid,
                        "epoch": self.guard.epoch,
                    },
                    qos=1,
                )
            except CommError as exc:
                _log.warning("could not publish the outcome of a %s update: %s", kind, exc)
        return outcome

    def _judge(self, kind: str, message: Message) -> tuple[bool, str]:
        applier = self._appliers.get(kind)
        if applier is None:
            return False, f"no applier for {kind} updates"
        payload = message.payload
        refused = _why_refused(payload, self._key)
        if refused is not None:
            return False, refused
        field = UPDATE_TOPICS[kind][1]
        text = payload.get(field)
        if not isinstance(text, str):
            return False, f"signed, but the {field!r} field is missing or not text"
        refused = self.guard.admit(payload.get(BINDING), message.topic)
        if refused is not None:
            return False, refused
        try:
            ok, reason = applier(text)
        except Exception as exc:  # the applier's fault is a refusal, never the receiver's death
            _log.exception("the %s applier raised", kind)
            return False, f"applier failed: {type(exc).__name__}: {exc}"
        return bool(ok), str(reason) if ok else f"applier refused: {reason}"


# --------------------------------------------------------------------------- actions


class SignedGate:
    """A receiver's check of signed, bound messages: each must be signed with ``key`` and
    bound to ``epoch`` (a fresh one unless given), to ``topic`` when given, and newer than every
    message admitted from the same sender run (:class:`ReplayGuard`).

    The half every receiver of signed messages shares: :class:`SignedEffector` passes actions
    through one, the platform checks external verdicts and presence heartbeats with one each.
    """

    def __init__(self, key: bytes, *, epoch: str | None = None, topic: str | None = None) -> None:
        self._key = _check_key(key)
        self.topic = topic
        self.guard = ReplayGuard(epoch)
        self._lock = threading.Lock()

    @property
    def epoch(self) -> str:
        """This receiver's incarnation: messages must be bound to it."""
        return self.guard.epoch

    def signed(self, payload: Any) -> bool:
        """Whether ``payload`` carries a correct signature (its binding not looked at)."""
        return verify(payload, self._key)

    def check(self, payload: Any, topic: str | None = None) -> str | None:
        """None if ``payload`` may pass (and remember it as admitted), else why not.
        ``topic``: where it came (default: the gate's own)."""
        refused = _why_refused(payload, self._key)
        if refused is not None:
            return refused
        with self._lock:
            return self.guard.admit(payload.get(BINDING), topic or self.topic)


def unsealed(payload: Mapping[str, Any]) -> dict[str, Any]:
    """``payload`` without its signature and binding: what the sender meant."""
    return {k: v for k, v in payload.items() if k not in (SIGNATURE, BINDING)}


class SignedEffector:
    """An effector-side gate: passes on only actions signed with the Trustworthiness Checker's key
    and bound to this incarnation.

    ``handle(payload)`` verifies the signature and the binding (:class:`SignedGate`: bound to
    ``epoch``, to ``topic`` when given, and newer than every action admitted from the same
    sender run), then calls ``effector(action)`` with the payload minus its signature and
    binding and returns True; else it logs the reason, counts it in :attr:`refused` and returns
    False. ``epoch`` (a fresh one unless given) must be announced to the signer, e.g. in the
    presence message: ``Presence(transport, node, info={"epoch": gate.epoch})``.
    Subscribe it on the bus with ``transport.subscribe(topic, lambda m: gate.handle(m.payload))``.
    """

    def __init__(
        self,
        key: bytes,
        effector: Callable[[dict[str, Any]], object],
        *,
        epoch: str | None = None,
        topic: str | None = None,
    ) -> None:
        self.gate = SignedGate(key, epoch=epoch, topic=topic)
        self.effector = effector
        self.topic = topic
        self.accepted = 0
        self.refused = 0
        self.last_refusal: str | None = None
        self.guard = self.gate.guard
        self.logs = RepeatedLogs()
        self._lock = threading.Lock()

    @property
    def epoch(self) -> str:
        """This gate's incarnation: actions must be bound to it."""
        return self.gate.epoch

    def check(self, payload: Any) -> str | None:
        """None if ``payload`` may pass (and remember it as admitted), else why not."""
        return self.gate.check(payload)

    def handle(self, payload: Any) -> bool:
        """Verify and, if correctly signed, bound here and new, pass the action on."""
        reason = self.check(payload)
        if reason is not None:
            with self._lock:
                self.refused += 1
                self.last_refusal = reason
            # the first of each kind in full, then counted (an attacker's flood of replays
            # must not flood the log); the kind leaves out the sequence numbers
            kind = reason.split(":")[0]
            self.logs.log(
                _log, logging.WARNING, f"action refused by the effector gate: {kind}",
                "action refused by the effector gate: %s", reason,
            )
            return False
        action = unsealed(payload)
        with self._lock:
            self.accepted += 1
        self.effector(action)
        return True
