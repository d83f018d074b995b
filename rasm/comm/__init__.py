"""rasm.comm: the Communication Manager and its transports.

``open_transport("local")`` is the in-process bus; ``open_transport("mqtt://host:port")`` talks
to an MQTT broker. Both take MQTT topic patterns (``+``, ``#``) and JSON-able dict payloads, and
deliver :class:`Message` objects. :class:`CommunicationManager` adds the seed's operations:
``create_publisher`` / ``publish_message`` and ``create_subscriber`` / ``get_queue_message``.

For a distributed loop: :class:`Presence` / :class:`PresenceTracker` (node start-up, heartbeats,
shutdown, crash via :func:`presence_will`), :func:`sign` / :func:`verify` with
:class:`UpdateReceiver` and :class:`SignedEffector` (HMAC-signed updates and actions, bound by
:class:`BoundSigner` and checked by :class:`ReplayGuard` so none can be replayed), and
:class:`InfluxWriter` (MAPLE-K timing to InfluxDB, :func:`record_to_points`).
"""

from rasm.comm.envelope import RESERVED_KEYS, MalformedPayload
from rasm.comm.influx import InfluxWriter, record_to_points, verdict_to_point
from rasm.comm.local import LocalTransport
from rasm.comm.manager import CommunicationManager, Publisher, Subscriber
from rasm.comm.message import Message, TransportStats
from rasm.comm.presence import NodeState, Presence, PresenceTracker, presence_topic, presence_will
from rasm.comm.signing import (
    BoundSigner,
    ReplayGuard,
    SignedEffector,
    UpdateOutcome,
    UpdateReceiver,
    new_epoch,
    sign,
    verify,
)
from rasm.comm.topics import topic_matches, validate_pattern, validate_topic
from rasm.comm.transport import Subscription, Transport
from rasm.comm.url import credentials_from_env, open_transport
from rasm.errors import CommError

__all__ = [
    "BoundSigner",
    "CommError",
    "CommunicationManager",
    "InfluxWriter",
    "LocalTransport",
    "MalformedPayload",
    "Message",
    "MqttTransport",
    "NodeState",
    "Presence",
    "PresenceTracker",
    "Publisher",
    "RESERVED_KEYS",
    "ReplayGuard",
    "SignedEffector",
    "Subscriber",
    "Subscription",
    "Transport",
    "TransportStats",
    "UpdateOutcome",
    "UpdateReceiver",
    "Will",
    "credentials_from_env",
    "new_epoch",
    "open_transport",
    "presence_topic",
    "presence_will",
    "record_to_points",
    "sign",
    "topic_matches",
    "validate_pattern",
    "validate_topic",
    "verdict_to_point",
    "verify",
]


def __getattr__(name: str) -> object:
    # MqttTransport and Will load paho only when asked for, so 'local' users never import it.
    if name in ("MqttTransport", "Will"):
        from rasm.comm import mqtt

        return getattr(mqtt, name)
    raise AttributeError(f"module 'rasm.comm' has no attribute {name!r}")
