"""Transport URLs: ``local``, ``mqtt://host:port``, ``mqtts://host:port``, and ROS 2's
``zenoh://host:port[?domain=N]`` and ``dds://[?domain=N]``."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any
from urllib.parse import urlsplit

from rasm.comm.transport import Transport
from rasm.errors import CommError
from rasm.extras import missing_extra

__all__ = ["open_transport", "parse_mqtt_url", "credentials_from_env", "ACCEPTED_FORMS"]

ACCEPTED_FORMS = (
    "'local', 'mqtt://HOST:PORT', 'mqtts://HOST:PORT' (TLS), 'zenoh://HOST:PORT[?domain=N]' "
    "or 'dds://[?domain=N]' (ROS 2)"
)
_DEFAULT_PORTS = {"mqtt": 1883, "mqtts": 8883}


def parse_mqtt_url(url: str) -> tuple[str, int, bool]:
    """``(host, port, tls)`` of an ``mqtt://`` or ``mqtts://`` URL; :class:`CommError` otherwise.

    The port defaults to 1883 (8883 for ``mqtts``). Paths, queries and credentials are refused:
    give credentials to :class:`~rasm.comm.mqtt.MqttTransport` instead, not in a URL that ends up
    in logs.
    """
    def bad(why: str) -> CommError:
        return CommError(f"bad transport URL {url!r}: {why}; expected {ACCEPTED_FORMS}")

    if not isinstance(url, str):
        raise CommError(f"transport URL must be a string, got {url!r}; expected {ACCEPTED_FORMS}")
    parts = urlsplit(url.strip())
    if parts.scheme not in _DEFAULT_PORTS:
        raise bad(f"unknown scheme {parts.scheme!r}" if parts.scheme else "no scheme")
    if parts.username is not None or parts.password is not None:
        raise bad("credentials do not belong in the URL (pass username= and password=)")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise bad("a broker URL has no path, query or fragment")
    try:
        port = parts.port
    except ValueError as exc:
        raise bad(str(exc)) from None
    host = parts.hostname
    if not host:
        raise bad("no host")
    return host, port if port is not None else _DEFAULT_PORTS[parts.scheme], parts.scheme == "mqtts"


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


def credentials_from_env(url: str, environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """``username=``/``password=`` for an MQTT ``url`` from ``RASM_MQTT_USERNAME`` and
    ``RASM_MQTT_PASSWORD`` (what ``rasm run`` and ``rasm monitor`` use: credentials never go in
    the URL, which ends up in logs); empty for ``local`` or when neither is set."""
    env = os.environ if environ is None else environ
    if not isinstance(url, str) or urlsplit(url.strip()).scheme not in _DEFAULT_PORTS:
        return {}
    found = {}
    if env.get("RASM_MQTT_USERNAME"):
        found["username"] = env["RASM_MQTT_USERNAME"]
    if env.get("RASM_MQTT_PASSWORD"):
        if "username" not in found:
            raise CommError("RASM_MQTT_PASSWORD is set but RASM_MQTT_USERNAME is not: set both")
        found["password"] = env["RASM_MQTT_PASSWORD"]
    return found
