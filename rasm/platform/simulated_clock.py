"""The simulated clock over a network transport.

On the in-process bus a reading is delivered while it is published, so a simulated run with a
seed gives the same trace every time. Over a broker or a ROS 2 middleware the reading takes a
trip through the network: the run's scheduler waits for every message this process published to
come back before it runs the next job (:meth:`Transport.wait_own_deliveries`), so the trip
changes nothing. A process can only wait for its own messages: a simulated run over a network
has its managed system (the app's simulator) in the same process
(:func:`rasm.platform.run_options.check_simulated_run`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from rasm.comm import LocalTransport, Transport

__all__ = ["DELIVERY_TIMEOUT", "wait_for_own_messages"]

DELIVERY_TIMEOUT = 10.0
"""Seconds (wall clock) a simulated run waits for one of its messages to come back before it
fails: on loopback a message takes well under a millisecond, so one this late is lost."""


def wait_for_own_messages(
    transport: Transport, managed_topics: Iterable[str]
) -> Callable[[], None] | None:
    """What the scheduler of a simulated run calls before each job over ``transport`` (None on
    the in-process bus, which delivers at once): waits until every message this process has
    published is delivered back to its subscriptions, or raises :class:`CommError`; it raises
    too once another process has published on ``managed_topics`` (the probes' and effectors')."""
    if isinstance(transport, LocalTransport):
        return None
    transport.count_own_deliveries(exclusive=managed_topics)
    return lambda: transport.wait_own_deliveries(DELIVERY_TIMEOUT)
