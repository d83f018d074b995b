"""The topics the platform publishes itself, and the app topics that must not be one of them.

An effector on a topic the platform publishes would take every message there as an action (a
verdict, a trace record, a heartbeat), and a probe or an external verdict source on one would
read the platform's own output as the managed system's or a monitor's. So no probe, effector
or external verdict topic may be one the platform publishes (SPEC §10), on any transport the
app may be run over (``--transport`` can move an MQTT app to ROS 2 and back):

- each property's verdict: ``rasm/verdict/<property>``, over ROS 2 ``/rasm/verdict/<property>``
  (the app's and the platform's properties; an external source's verdicts are not published
  again, so its topic may be another rasm's ``rasm/verdict/<name>``);
- over MQTT: ``rasm/trace``, ``rasm/presence/<node>``, ``rasm/update/result``;
- the ``bus:TOPIC`` log sinks of ``logging.sinks``.

A probe's topic may be a pattern (``robot/+``): it clashes when it matches one of them.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from rasm.comm.presence import PRESENCE_PREFIX
from rasm.comm.topics import topic_matches
from rasm.errors import SourceError
from rasm.platform.manifest import AppManifest, manifest_location
from rasm.platform.verdicts_out import verdict_topic

__all__ = ["own_topic_problems", "own_topics"]

_PLACEHOLDER_NODE = "node"  # stands for any node's presence topic when matching patterns


def own_topics(manifest: AppManifest, properties: Iterable[str]) -> dict[str, str]:
    """Every topic the platform may publish for ``manifest``, with what it carries."""
    found: dict[str, str] = {}
    for name in properties:
        for ros in (False, True):
            found[verdict_topic(name, ros=ros)] = f"the verdicts of {name}"
    found["rasm/trace"] = "the adaptation trace"
    found[f"{PRESENCE_PREFIX}/{_PLACEHOLDER_NODE}"] = "the processes' presence"
    found["rasm/update/result"] = "the outcomes of run-time updates"
    for sink in manifest.logging.get("sinks", ()) or ():
        kind, _, target = str(sink).partition(":")
        if kind == "bus" and target:
            found[target] = "the log (logging.sinks)"
    return found


def _clash(topic: str, own: dict[str, str]) -> str | None:
    if topic in own:
        return own[topic]
    if topic.startswith(f"{PRESENCE_PREFIX}/") and topic.count("/") == 2:
        return own[f"{PRESENCE_PREFIX}/{_PLACEHOLDER_NODE}"]
    for published, what in own.items():
        if topic_matches(topic, published):  # a probe's pattern
            return what
    return None


def own_topic_problems(manifest: AppManifest, properties: Iterable[str]) -> Iterator[SourceError]:
    """A probe, effector or external verdict topic that is one the platform publishes
    (``properties``: the names of the app's and the platform's properties), at its place in
    app.yaml."""
    # an external source's verdicts are not published again: its topic is the other monitor's
    own = own_topics(manifest, properties)
    places: list[tuple[str, str, list]] = [
        (probe.topic, f"probe {probe.topic}", ["probes", i, "topic"])
        for i, probe in enumerate(manifest.probes)
    ]
    places += [
        (effector.topic, f"effector {name}", ["effectors", name, "topic"])
        for name, effector in manifest.effectors.items()
    ]
    places += [
        (source.topic, f"external verdict {name}",
         ["trustworthiness", "external_verdicts", name, "topic"])
        for name, source in manifest.external_verdicts.items()
    ]
    for topic, what, path in places:
        carried = _clash(topic, own)
        if carried is not None:
            yield SourceError(
                f"{what}: {topic} is a topic the platform publishes itself ({carried}); give "
                "it another topic (the platform's own are under rasm/ and /rasm/)",
                manifest_location(manifest, path),
            )
