"""Signed messages (HMAC-SHA256): run-time updates and actions only the key holder can send.

A signed payload is the payload plus a ``signature`` field: the hex HMAC-SHA256, under a shared
key, of the canonical JSON of every other field (keys sorted at every depth, no spaces, UTF-8,
no NaN or infinities). So the signature does not depend on key order or on the transport, and
any change of any field, at any depth, or a different key, makes :func:`verify` fail.

:class:`UpdateReceiver` applies property and rule updates received on ``rasm/update/...`` only
when they are correctly signed; :class:`SignedEffector` passes to an effector only the actions the
Trustworthiness Checker signed. Both log every refusal with its reason.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import logging
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from rasm.comm.message import Message
from rasm.comm.transport import Subscription, Transport
from rasm.errors import CommError

__all__ = [
    "SIGNATURE",
    "UPDATE_TOPICS",
    "Applier",
    "SignedEffector",
    "UpdateOutcome",
    "UpdateReceiver",
    "canonical",
    "sign",
    "verify",
]

_log = logging.getLogger("rasm.comm.signing")

SIGNATURE = "signature"
"""The field that carries the signature."""

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

    Subscribes to ``rasm/update/properties`` (payload ``{"spec": TEXT, "signature": …}``) and
    ``rasm/update/rules`` (``{"rules": TEXT, "signature": …}``) for the appliers given. An update
    reaches its applier only if signed with ``key``; the applier returns ``(accepted, reason)``
    (e.g. ``lambda text: tuple(ruleset.swap_text(text))``-like: a refused inconsistent rule set
    is a refusal, not an error; an applier that raises is a refusal too). An optional integer
    ``version`` field must grow per kind: a replayed older update is refused.

    Every outcome is logged, kept in :attr:`outcomes` (the last ``keep``), passed to
    ``on_outcome``, and, if ``reply`` is true, published on ``rasm/update/result`` as
    ``{"kind", "accepted", "reason", "update"}`` (``update``: the update message's envelope
    uid) so the sender learns what happened.
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
    ) -> None:
        self.transport = transport
        self._key = _check_key(key)
        self._appliers = {"properties": properties, "rules": rules}
        self.on_outcome = on_outcome
        self.reply = reply
        self.outcomes: deque[UpdateOutcome] = deque(maxlen=keep)
        self.refused = 0  # every refusal, not only those still in ``outcomes``
        self._versions: dict[str, int] = {}
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

    def receive(self, kind: str, message: Message) -> UpdateOutcome:
        """Judge and (if correctly signed) apply one update; usable without a transport too."""
        with self._lock:
            accepted, reason = self._judge(kind, message.payload)
            outcome = UpdateOutcome(kind, accepted, reason, message.uid, time.time())
            self.outcomes.append(outcome)
            self.refused += not accepted
        if accepted:
            _log.info("%s update accepted: %s", kind, reason)
        else:
            _log.warning("%s update refused: %s", kind, reason)
        if self.on_outcome is not None:
            try:
                self.on_outcome(outcome)
            except Exception:
                _log.exception("on_outcome raised on %r", outcome)
        if self.reply:
            try:
                self.transport.publish(
                    "rasm/update/result",
                    {"kind": kind, "accepted": accepted, "reason": reason, "update": message.uid},
                    qos=1,
                )
            except CommError as exc:
                _log.warning("could not publish the outcome of a %s update: %s", kind, exc)
        return outcome

    def _judge(self, kind: str, payload: Mapping[str, Any]) -> tuple[bool, str]:
        applier = self._appliers.get(kind)
        if applier is None:
            return False, f"no applier for {kind} updates"
        refused = _why_refused(payload, self._key)
        if refused is not None:
            return False, refused
        field = UPDATE_TOPICS[kind][1]
        text = payload.get(field)
        if not isinstance(text, str):
            return False, f"signed, but the {field!r} field is missing or not text"
        version = payload.get("version")
        if version is not None:
            if isinstance(version, bool) or not isinstance(version, int):
                return False, f"signed, but 'version' is not an integer: {version!r}"
            last = self._versions.get(kind)
            if last is not None and version <= last:
                return False, f"replayed or stale: version {version} after {last}"
        try:
            ok, reason = applier(text)
        except Exception as exc:  # the applier's fault is a refusal, never the receiver's death
            _log.exception("the %s applier raised", kind)
            return False, f"applier failed: {type(exc).__name__}: {exc}"
        if ok and version is not None:
            self._versions[kind] = version
        return bool(ok), str(reason) if ok else f"applier refused: {reason}"


# --------------------------------------------------------------------------- actions


class SignedEffector:
    """An effector-side gate: passes on only actions signed with the Trustworthiness Checker's key.

    ``handle(payload)`` verifies the signature and that the same signed action was not seen
    before among the last ``remember`` ones (a replayed action is refused: give every action a
    unique field such as an ``id`` or sequence number so two real actions never look alike;
    ``uid`` and ``timestamp`` are the bus envelope's own keys),
    then calls ``effector(action)`` with the payload minus its signature and returns True; else
    it logs the reason, counts it in :attr:`refused` and returns False.
    Subscribe it on the bus with ``transport.subscribe(topic, lambda m: gate.handle(m.payload))``.
    """

    def __init__(
        self, key: bytes, effector: Callable[[dict[str, Any]], object], *, remember: int = 10_000
    ) -> None:
        self._key = _check_key(key)
        self.effector = effector
        self.accepted = 0
        self.refused = 0
        self.last_refusal: str | None = None
        self._seen: OrderedDict[str, None] = OrderedDict()
        self._remember = remember
        self._lock = threading.Lock()

    def check(self, payload: Any) -> str | None:
        """None if ``payload`` may pass (and remember it), else why not."""
        refused = _why_refused(payload, self._key)
        if refused is not None:
            return refused
        signature = payload[SIGNATURE]
        with self._lock:
            if signature in self._seen:
                return "replayed"
            self._seen[signature] = None
            if len(self._seen) > self._remember:
                self._seen.popitem(last=False)
        return None

    def handle(self, payload: Any) -> bool:
        """Verify and, if correctly signed and new, pass the action to the effector."""
        reason = self.check(payload)
        if reason is not None:
            with self._lock:
                self.refused += 1
                self.last_refusal = reason
            _log.warning("action refused by the effector gate: %s", reason)
            return False
        action = {k: v for k, v in payload.items() if k != SIGNATURE}
        with self._lock:
            self.accepted += 1
        self.effector(action)
        return True

