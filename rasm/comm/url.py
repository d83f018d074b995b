"""Transport URLs: ``local``, ``mqtt://host:port``, ``mqtts://host:port``, and ROS 2's
``zenoh://host:port[?domain=N]`` and ``dds://[?domain=N]``; what they say (the transport each
opens is :func:`rasm.comm.transports.open_transport`'s)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from urllib.parse import urlsplit

from rasm.errors import CommError

__all__ = ["ACCEPTED_FORMS", "credentials_from_env", "parse_mqtt_url"]

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
