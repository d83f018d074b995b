"""Which transports are a ROS 2 middleware's (and so take the app's ROS 2 wiring)."""

from __future__ import annotations

import pytest

from rasm.platform.ros_wiring import is_ros_transport


@pytest.mark.parametrize("url", ["zenoh://127.0.0.1:7447", "dds://0", "  zenoh://router:7447\n"])
def test_a_zenoh_or_dds_url_is_a_ros_transport(url):
    assert is_ros_transport(url)


@pytest.mark.parametrize("url", ["local", "mqtt://127.0.0.1:1883", "mqtts://broker", "zenohx://a"])
def test_other_transports_are_not(url):
    assert not is_ros_transport(url)
