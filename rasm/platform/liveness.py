"""Whether the managed system is there, and which of its readings are still live.

Three witnesses, each where the transport has it:

- **probe staleness** (every transport): a probe that declares ``staleness: S`` and has stored
  no value for S seconds (counted from the start of the run until its first message) is
  *stale*: its signals are stale, and the managed system counts as lost;
- **the ROS graph** (ROS 2): a probe that declares ``publisher: /node`` is stale, and the
  managed system lost, while that node is not in the graph (its liveliness token over Zenoh,
  its participant's ``ros_discovery_info`` over DDS);
- **presence** (MQTT): every managed process of the app offline or silent
  (:mod:`rasm.platform.distribution`; with ``RASM_ACTION_KEY`` only signed heartbeats count).

The managed system is lost while any witness says so, and back when none does. A stale signal
reaches the Trustworthiness Checker as an error: every property reading it is in error on the
records while it is stale (it is not judged on the last reading), which vetoes like any error.

:func:`lost_trigger_problems` says when an app's ``fallback.when`` names
``managed_system_lost`` on a transport where nothing could ever report it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from rasm.errors import SourceError
from rasm.platform.manifest import AppManifest, Probe, manifest_location
from rasm.times import elapsed_seconds, format_seconds, from_nanoseconds, nanoseconds

__all__ = [
    "ManagedSystemWatch",
    "can_report_loss",
    "declared_publishers",
    "lost_trigger_problems",
    "publisher_problems",
]


@dataclass
class _Watched:
    probe: Probe
    last: float  # when it last stored a value (the run's start before its first message)


class ManagedSystemWatch:
    """Follows the managed system's witnesses (see the module docstring).

    ``probes``: the app's; ``clock()`` the loop's time; ``presence()`` whether presence says a
    managed process is online (True where there is no presence); ``alive(node)`` whether a ROS
    2 node is in the graph (None off ROS 2). :meth:`evaluate` reads them all and calls
    ``on_change(lost, why)`` when the managed system is lost (``lost`` True) or back, and
    ``on_stale(signals, why)`` when signals go stale (or live again: an empty ``why``).
    """

    def __init__(
        self,
        probes: list[Probe],
        *,
        clock: Callable[[], float],
        presence: Callable[[], bool] = lambda: True,
        alive: Callable[[str], bool] | None = None,
        on_change: Callable[[bool, str], object] = lambda lost, why: None,
        on_stale: Callable[[dict[str, str]], object] = lambda stale: None,
    ) -> None:
        self.clock = clock
        self.presence = presence
        self.alive = alive
        self.on_change = on_change
        self.on_stale = on_stale
        self._watched = {
            probe.topic: _Watched(probe, -math.inf)
            for probe in probes
            if probe.staleness is not None or (probe.publisher and alive is not None)
        }
        self.lost_why = ""  # why the managed system is lost now ("" while it is there)
        self._stale: dict[str, str] = {}  # signal -> why it is stale now

    def begin(self) -> None:
        """The run starts now: each probe's staleness is counted from here until its first
        message."""
        now = self.clock()
        for watched in self._watched.values():
            watched.last = max(watched.last, now)

    def online(self) -> bool:
        """Whether the managed system is there, as of the last :meth:`evaluate`."""
        return not self.lost_why

    def stale(self) -> dict[str, str]:
        """The signals that are stale now, each with why."""
        return dict(self._stale)

    def heard(self, topic: str, time: float) -> None:
        """Probe ``topic`` stored values at ``time``; a stale one is live again at once."""
        watched = self._watched.get(topic)
        if watched is not None:
            watched.last = max(watched.last, time)
            if any(key in self._stale for key in watched.probe.signals):
                self.evaluate()

    def next_deadline(self) -> float | None:
        """When the next watched probe goes stale if nothing comes (None: none can)."""
        now = self.clock()
        times = [
            due
            for w in self._watched.values()
            if w.probe.staleness is not None
            and (due := _stale_from(w.last, w.probe.staleness)) > now
        ]
        return min(times, default=None)

    def evaluate(self) -> None:
        """Read every witness; report what changed."""
        now = self.clock()
        stale: dict[str, str] = {}
        reasons: list[str] = []
        for topic, watched in self._watched.items():
            why = self._why_stale(topic, watched, now)
            if why is not None:
                reasons.append(why)
                stale.update(dict.fromkeys(watched.probe.signals, why))
        if not self.presence():
            reasons.append("every managed process is offline or silent (presence)")
        if stale != self._stale:
            self._stale = stale
            self.on_stale(dict(stale))
        why = "; ".join(reasons)
        if bool(why) != bool(self.lost_why):
            self.lost_why = why
            self.on_change(bool(why), why)
        else:
            self.lost_why = why

    def _why_stale(self, topic: str, watched: _Watched, now: float) -> str | None:
        probe = watched.probe
        if probe.publisher and self.alive is not None and not self.alive(probe.publisher):
            return f"probe {topic}: its publisher {probe.publisher} is not in the ROS graph"
        if probe.staleness is not None and now >= _stale_from(watched.last, probe.staleness):
            silent = elapsed_seconds(watched.last, now)
            return (
                f"probe {topic} silent for {_seconds(silent)} "
                f"(staleness {format_seconds(probe.staleness)} s)"
            )
        return None


def _stale_from(last: float, staleness: float) -> float:
    """When a probe last heard at ``last`` goes stale if nothing comes: their sum, exact to the
    nanosecond (heard at 1.8 with a staleness of 0.5, stale from 2.3, where in floats
    ``2.3 - 1.8`` falls short of 0.5); ``-inf`` for a probe not heard yet (stale already).
    Being stale (now at or past it) and the next deadline (after now) read this one time, so
    the two never disagree."""
    heard, limit = nanoseconds(last), nanoseconds(staleness)
    if heard is None or limit is None:
        return last + staleness
    return from_nanoseconds(heard + limit)


def _seconds(value: float) -> str:
    return f"{format_seconds(value)} s" if math.isfinite(value) else "ever"


def _is_ros(transport: str) -> bool:
    return transport.strip().startswith(("zenoh:", "dds:"))


def lost_trigger_problems(manifest: AppManifest, transport: str) -> Iterator[SourceError]:
    """``managed_system_lost`` written in ``fallback.when`` where nothing could report it on
    ``transport``: no probe declares a staleness (or, over ROS 2, a publisher), and the
    transport has no presence (only MQTT has). Left to its default, ``when`` names it
    everywhere; where nothing reports a loss it simply never holds."""
    fallback = manifest.fallback
    if fallback is None or "managed_system_lost" not in fallback.when:
        return
    written = (manifest.raw.get("fallback") or {}).get("when")
    if written is None or "managed_system_lost" not in written:
        return
    if can_report_loss(manifest, transport):
        return
    index = list(written).index("managed_system_lost")
    yield SourceError(
        f"fallback trigger managed_system_lost can never fire over {transport}: nothing there "
        "reports the managed system lost. Give a probe a staleness (seconds it may stay "
        "silent)" + (", or a publisher (its ROS 2 node)" if _is_ros(transport) else "")
        + (", or run the managed system as its own process over MQTT (presence)"
           if not _is_ros(transport) else "") + "; or leave the trigger out",
        manifest_location(manifest, ["fallback", "when", index]),
    )


def can_report_loss(manifest: AppManifest, transport: str) -> bool:
    """Whether something can report the managed system lost over ``transport``."""
    if any(probe.staleness is not None for probe in manifest.probes):
        return True
    if _is_ros(transport):
        return any(probe.publisher for probe in manifest.probes)
    return transport.strip().startswith(("mqtt://", "mqtts://"))


def declared_publishers(manifest: AppManifest) -> dict[str, str]:
    """Topic -> the ROS 2 node declared as its publisher (probes and external verdicts)."""
    found = {probe.topic: probe.publisher for probe in manifest.probes if probe.publisher}
    found.update(
        (source.topic, source.publisher)
        for source in manifest.external_verdicts.values()
        if source.publisher
    )
    return found


def publisher_problems(manifest: AppManifest, transport: str) -> Iterator[SourceError]:
    """Over ROS 2 only the declared publisher speaks for an external verdict: a source
    without one is refused there."""
    if not _is_ros(transport):
        return
    for name, source in manifest.external_verdicts.items():
        if source.publisher is None:
            yield SourceError(
                f"external verdict {name}: over ROS 2 only the declared publisher's messages "
                "count; name the node that publishes them (publisher: /namespace/node)",
                manifest_location(manifest, ["trustworthiness", "external_verdicts", name]),
            )
