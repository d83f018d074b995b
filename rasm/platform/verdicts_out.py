"""Verdicts out: each property's verdict on the transport, for tools outside the loop.

Over ROS 2 a verdict is ``std_msgs/msg/Bool`` on ``/rasm/verdict/<property>``, a latched topic
sent to when the value changes (a late subscriber gets the current one); elsewhere it is
``{"value": …, "time": …}`` on ``rasm/verdict/<property>``, every one. The platform's own
topics live under ``rasm/`` (``/rasm/`` over ROS 2) so that none can be a probe's or an
effector's: :mod:`rasm.platform.own_topics` refuses an app whose topics clash with them.
"""

from __future__ import annotations

import logging
from collections.abc import Container, Iterable

from rasm.comm import Transport
from rasm.errors import RasmError
from rasm.logs import RepeatedLogs
from rasm.platform.manifest import AppManifest
from rasm.properties.monitor import Verdict

__all__ = ["VerdictPublisher", "publishes_verdicts", "verdict_topic"]

_log = logging.getLogger("rasm.platform")


def verdict_topic(name: str, *, ros: bool) -> str:
    """Where property ``name``'s verdicts go: ``/rasm/verdict/<name>`` over ROS 2,
    ``rasm/verdict/<name>`` elsewhere."""
    return f"/rasm/verdict/{name}" if ros else f"rasm/verdict/{name}"


def publishes_verdicts(m: AppManifest, transport_url: str, *, replaying: bool) -> bool:
    """Whether verdicts go out on the transport: as the manifest says, else on a network
    transport (never in a replay, which sends nothing)."""
    if replaying:
        return False
    return transport_url != "local" if m.publish_verdicts is None else m.publish_verdicts


class VerdictPublisher:
    """Publishes the verdicts of ``names`` (not those of ``skip``: external monitors' own)."""

    def __init__(self, transport: Transport, names: Iterable[str], *, ros: bool,
                 skip: Container[str], logs: RepeatedLogs) -> None:
        self.transport = transport
        self.ros = ros
        self.skip = skip
        self.logs = logs
        self.published = 0
        self.last_sent: dict[str, bool] = {}  # over ROS 2: the last value per property
        if ros:
            # a verdict topic holds the property's state: latched, sent when it changes
            latched = {"durability": "transient_local", "depth": 1}
            for name in names:
                transport.declare(verdict_topic(name, ros=True), "std_msgs/msg/Bool", qos=latched)

    def publish(self, verdict: Verdict) -> None:
        """One verdict out. An undecided verdict is not sent; one in error goes out false."""
        self.publish_all([verdict])

    def publish_all(self, verdicts: Iterable[Verdict]) -> None:
        """The verdicts one step decided, in order (see :meth:`publish`). Over ROS 2 only a
        change of a property's value is sent: a verdict that could not be sent is sent with
        the property's next verdict."""
        for verdict in verdicts:
            if verdict.value is None or verdict.property in self.skip:
                continue
            value = bool(verdict.value) and verdict.error is None
            # per record and property at sensor rates, the same value again over ROS would
            # outweigh the robot's own traffic
            if self.ros and self.last_sent.get(verdict.property) == value:
                continue
            self._send(verdict, value)

    def _send(self, verdict: Verdict, value: bool) -> None:
        try:
            topic = verdict_topic(verdict.property, ros=self.ros)
            if self.ros:
                self.transport.publish(topic, {"data": value})
                self.last_sent[verdict.property] = value
            else:
                self.transport.publish(topic, {"value": value, "time": verdict.time})
            self.published += 1
        except RasmError as exc:  # the loop goes on; said once, then counted
            what = f"verdict of {verdict.property} not published: {exc}"
            self.logs.log(_log, logging.WARNING, what)
