"""rasm.comm: the Communication Manager and its transports.

``open_transport("local")`` is the in-process bus; ``open_transport("mqtt://host:port")`` talks
to an MQTT broker. Both take MQTT topic patterns (``+``, ``#``) and JSON-able dict payloads, and
deliver :class:`Message` objects. :class:`Endpoints` gives the Communication Manager's
operations: ``create_publisher`` / ``publish_message`` and ``create_subscriber`` /
``get_queue_message``.

For a distributed loop: :class:`Presence` / :class:`PresenceTracker` (node start-up, heartbeats,
shutdown, crash via :func:`presence_will`), :func:`sign` / :func:`verify` with
:class:`UpdateReceiver` and :class:`SignedEffector` (HMAC-signed updates and actions, bound by
:class:`BoundSigner` so none can be replayed), and :class:`InfluxWriter` (MAPLE-K timing to
InfluxDB).
"""

from rasm.comm.endpoints import Endpoints, Publisher, Subscriber
from rasm.comm.envelope import MalformedPayload
from rasm.comm.influx import InfluxWriter
from rasm.comm.local import LocalTransport
from rasm.comm.message import Message
from rasm.comm.presence import Presence, PresenceTracker, presence_will
from rasm.comm.signing import (
    BoundSigner,
    SignedEffector,
    SignedGate,
    UpdateOutcome,
    UpdateReceiver,
    sign,
    verify,
)
from rasm.comm.transport import Subscription, Transport
from rasm.comm.transports import open_transport
from rasm.errors import CommError

__all__ = [
    "BoundSigner",
    "CommError",
    "Endpoints",
    "InfluxWriter",
    "LocalTransport",
    "MalformedPayload",
    "Message",
    "MqttTransport",
    "Presence",
    "PresenceTracker",
    "Publisher",
    "SignedEffector",
    "SignedGate",
    "Subscriber",
    "Subscription",
    "Transport",
    "UpdateOutcome",
    "UpdateReceiver",
    "open_transport",
    "presence_will",
    "sign",
    "verify",
]


def __getattr__(name: str) -> object:
    # MqttTransport loads paho only when asked for, so 'local' users never import it.
    if name == "MqttTransport":
        from rasm.comm import mqtt

        return getattr(mqtt, name)
    raise AttributeError(f"module 'rasm.comm' has no attribute {name!r}")
