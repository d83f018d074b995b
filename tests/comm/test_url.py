"""open_transport: 'local', 'mqtt://host:port', 'mqtts://...'; anything else a clear error."""

from __future__ import annotations

import pytest

from rasm.comm import CommError, LocalTransport, MqttTransport, open_transport
from rasm.comm.url import parse_mqtt_url


def test_local_gives_the_in_process_bus():
    transport = open_transport("local")
    assert isinstance(transport, LocalTransport)
    assert transport.url == "local"


def test_mqtt_url_gives_an_unconnected_mqtt_transport():
    transport = open_transport("mqtt://127.0.0.1:1884", client_id="probe")
    assert isinstance(transport, MqttTransport)
    assert (transport.host, transport.port, transport.client_id) == ("127.0.0.1", 1884, "probe")
    assert not transport.connected


@pytest.mark.parametrize(
    ("url", "expected"),
    [
        ("mqtt://127.0.0.1:1884", ("127.0.0.1", 1884, False)),
        ("mqtt://localhost", ("localhost", 1883, False)),
        ("mqtts://broker.example:8884", ("broker.example", 8884, True)),
        ("mqtts://broker.example", ("broker.example", 8883, True)),
        ("mqtt://[::1]:1883", ("::1", 1883, False)),
    ],
)
def test_broker_urls_are_parsed(url, expected):
    assert parse_mqtt_url(url) == expected


@pytest.mark.parametrize(
    "url",
    [
        "redis://127.0.0.1:6379",
        "localhost:1883",
        "mqtt://",
        "mqtt://127.0.0.1:notaport",
        "mqtt://127.0.0.1:99999",
        "mqtt://user:secret@127.0.0.1:1883",
        "mqtt://127.0.0.1:1883/topic",
        "",
        "LOCAL",
    ],
)
def test_anything_else_is_refused_naming_the_url_and_the_accepted_forms(url):
    with pytest.raises(CommError) as info:
        open_transport(url)
    message = str(info.value)
    assert repr(url) in message
    assert "'local'" in message and "mqtt://HOST:PORT" in message


def test_a_url_that_is_not_a_string_is_refused():
    with pytest.raises(CommError, match="must be a string"):
        open_transport(None)  # type: ignore[arg-type]
