"""rasm.comm: the Communication Manager and its transports (seed §5.5.1).

``open_transport("local")`` is the in-process bus; ``open_transport("mqtt://host:port")`` talks
to an MQTT broker. Both take MQTT topic patterns (``+``, ``#``) and JSON-able dict payloads, and
deliver :class:`Message` objects. :class:`CommunicationManager` adds the seed's operations:
``create_publisher`` / ``publish_message`` and ``create_subscriber`` / ``get_queue_message``.
"""

from rasm.comm.envelope import RESERVED_KEYS, MalformedPayload
from rasm.comm.local import LocalTransport
from rasm.comm.manager import CommunicationManager, Publisher, Subscriber
from rasm.comm.message import Message, TransportStats
from rasm.comm.topics import topic_matches, validate_pattern, validate_topic
from rasm.comm.transport import Subscription, Transport
from rasm.comm.url import open_transport
from rasm.errors import CommError

__all__ = [
    "CommError",
    "CommunicationManager",
    "LocalTransport",
    "MalformedPayload",
    "Message",
    "MqttTransport",
    "Publisher",
    "RESERVED_KEYS",
    "Subscriber",
    "Subscription",
    "Transport",
    "TransportStats",
    "Will",
    "open_transport",
    "topic_matches",
    "validate_pattern",
    "validate_topic",
]


def __getattr__(name: str) -> object:
    # MqttTransport and Will load paho only when asked for, so 'local' users never import it.
    if name in ("MqttTransport", "Will"):
        from rasm.comm import mqtt

        return getattr(mqtt, name)
    raise AttributeError(f"module 'rasm.comm' has no attribute {name!r}")
