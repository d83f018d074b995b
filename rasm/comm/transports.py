"""Opening the transport a URL names (:mod:`rasm.comm.url` says what the URLs say).

Each transport is imported only when its URL is opened: paho is not needed for ``local``, nor
the ROS 2 middlewares for MQTT.
"""

from __future__ import annotations

from typing import Any
from urllib.parse import urlsplit

from rasm.comm.transport import Transport
from rasm.comm.url import parse_mqtt_url
from rasm.errors import CommError
from rasm.extras import missing_extra

__all__ = ["open_transport"]


def open_transport(url: str, **options: Any) -> Transport:
    """A new, not yet connected transport for ``url``.

    ``local`` gives a :class:`~rasm.comm.local.LocalTransport`; ``mqtt://host:port`` (or
    ``mqtts://``) an :class:`~rasm.comm.mqtt.MqttTransport`; ``zenoh://host:port`` a
    :class:`~rasm.ros2.zenoh.ZenohTransport` and ``dds://`` a
    :class:`~rasm.ros2.dds.DdsTransport` (ROS 2); ``options`` go to its constructor.
    Anything else raises :class:`CommError` naming the URL and the accepted forms.
    """
    if isinstance(url, str) and url.strip() == "local":
        from rasm.comm.local import LocalTransport

        return LocalTransport(**options)
    scheme = urlsplit(url.strip()).scheme if isinstance(url, str) else ""
    if scheme in ("zenoh", "dds"):
        # imported lazily: only ROS 2 users need Zenoh, Cyclone DDS and the type store
        try:
            from rasm.ros2.dds import DdsTransport
            from rasm.ros2.zenoh import ZenohTransport
        except ModuleNotFoundError as exc:
            missing = missing_extra(exc, f"{scheme}://")
            if missing is None:
                raise
            raise CommError(str(missing)) from None
        return (ZenohTransport if scheme == "zenoh" else DdsTransport)(url, **options)
    parse_mqtt_url(url)  # raises with the accepted forms
    from rasm.comm.mqtt import MqttTransport  # imported lazily: paho is not needed for 'local'

    return MqttTransport(url, **options)
