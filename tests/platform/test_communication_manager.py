"""The Communication Manager block connects its transport while it runs, and publishes only then."""

from __future__ import annotations

import pytest

from rasm.comm import LocalTransport
from rasm.errors import PlatformError
from rasm.platform.communication_manager import CommunicationManager


def test_messages_go_out_only_while_the_block_is_initialized() -> None:
    cm = CommunicationManager(LocalTransport())
    with pytest.raises(PlatformError, match="not initialized"):
        cm.publish_message("robot/cmd", {"v": 1})
    cm.send("configure")
    received = []
    cm.subscribe("robot/#", lambda message: received.append((message.topic, message.payload)))
    subscriber = cm.create_subscriber("robot/cmd")
    cm.publish_message("robot/cmd", {"v": 1})
    cm.create_publisher("robot/cmd").publish_message({"v": 2})
    assert received == [("robot/cmd", {"v": 1}), ("robot/cmd", {"v": 2})]
    assert subscriber.get_queue_message(timeout=0).payload == {"v": 1}
    cm.send("terminate")
    assert cm.mode == "terminated"
    assert subscriber.get_queue_message(timeout=0).payload == {"v": 2}  # what was queued stays
    assert subscriber.get_queue_message(timeout=0) is None  # closed: nothing more comes
    with pytest.raises(PlatformError):
        cm.publish_message("robot/cmd", {"v": 3})


def test_a_transport_that_cannot_connect_puts_the_block_in_fault() -> None:
    transport = LocalTransport()
    transport.close()  # a closed bus cannot be opened again
    cm = CommunicationManager(transport)
    cm.send("configure")
    assert cm.mode == "fault" and "closed" in (cm.failure_reason or "")
