"""The in-process bus: the embedded default (``--transport local``)."""

from __future__ import annotations

import itertools
import os
import time
from typing import Any

from rasm.comm.envelope import check_payload, decode, encode
from rasm.comm.message import Message
from rasm.comm.topics import validate_topic
from rasm.comm.transport import Transport

__all__ = ["LocalTransport"]


class LocalTransport(Transport):
    """Thread-safe in-process publish/subscribe with synchronous delivery.

    :meth:`publish` calls every matching callback on the publisher's own thread before it
    returns, so a test or a simulation sees effects immediately and deterministically. Routing
    is a dict of exact topics plus a list of wildcard patterns, memoised per topic.

    Payloads are checked like on MQTT (JSON values only, reserved envelope keys refused) but are
    not serialised: every subscriber gets the publisher's dict, so treat it as read-only. With
    ``strict=True`` each message makes the full JSON round trip instead, which catches everything
    a broker would see (size limit included) at the cost of speed.
    QoS is accepted and ignored: nothing is lost in-process.

    A callback that publishes again is delivered to recursively, depth first.
    """

    def __init__(self, *, strict: bool = False) -> None:
        super().__init__()
        self.url = "local"
        self.strict = strict
        self._uid_prefix = f"{os.getpid():x}.{id(self):x}."
        self._uids = itertools.count(1)

    def connect(self) -> None:
        """Open the bus (nothing to reach)."""
        if self._state == "closed":
            self._require_open("reconnect")
        self._state = "open"

    def close(self) -> None:
        """Close the bus and end every subscription; idempotent."""
        self._state = "closed"
        self._cancel_all()

    def publish(self, topic: str, payload: dict[str, Any], *, qos: int | None = None) -> None:
        """Deliver ``payload`` to every matching subscriber now, on this thread."""
        if self._state != "open":
            self._require_open(f"publish on {topic!r}")
        validate_topic(topic)
        uid = self._uid_prefix + str(next(self._uids))
        timestamp = time.time()
        if self.strict:
            payload, _, _ = decode(encode(payload, uid=uid, timestamp=timestamp))
        else:
            check_payload(payload)
        ok, failed = self._deliver(Message(topic, payload, uid, timestamp))
        # counted after delivery: published, delivered and errors move together
        self.stats.add_delivery(ok, failed, published=1)
