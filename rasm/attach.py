"""``rasm monitor``: property monitors attached to a live loop from outside, over a message bus.

An :class:`Attachment` subscribes to the topics the properties read, turns every message into
one trace record, steps a compiled monitor and publishes each verdict as
``{"value": true|false, "time": t}`` on ``rasm/verdict/<property>`` (SPEC §10: under ``rasm/``,
so that no verdict lands on an app's effector topic; ``verdict_topic="{property}"`` gives the
public RoboSAPIENS Trustworthiness Checker's topic named after the property). A verdict the
monitor could not evaluate is ``{"value": false, "time": t, "error": "why"}``.

With a ``seal`` (:class:`SignedVerdicts`, what ``rasm monitor`` builds from ``RASM_ACTION_KEY``)
every verdict is signed and bound to the rasm loops on the bus, so that a loop with the key takes
the attachment as an external verdict source (``trustworthiness.external_verdicts``) and nobody
else's messages on its topics. A verdict no loop can be bound to yet is not sent, only counted:
the loop's source stays not judged, which vetoes.

The summary names, like ``rasm run``'s, the properties satisfied only vacuously: those with an
``->`` whose left side never held on a judged record (:mod:`rasm.properties.vacuity`).

Where a signal comes from (a :class:`TopicMap`): by default from a rasm loop's trace topic,
``rasm/trace`` (field ``x`` of each trace record), and from topic ``x`` (the payload's ``value``
field, or, if there is none, its field ``x``). A ``--topics`` YAML file maps signals elsewhere::

    velocity: robot/odometry                 # field "value", else "velocity"
    mode: {topic: robot/state, field: mode}  # an explicit field
    anomaly: {topic: robot/state, field: alarm}  # several signals may share one topic
    "*": rasm/trace                          # every other signal: this topic, field of its name

Every message on the trace topic (``"*"``) is one record, stepped even when it sets none of the
properties' signals (a stage record), exactly as ``rasm check`` reads the trace file. A message's
time is its ``time`` field (seconds), else the sender's envelope timestamp, else the time it
arrived. A message elsewhere that gives no mapped signal, a bad ``time``, or a record the monitor
refuses (time going back, a value of the wrong type) is counted and logged, never fatal.
"""

from __future__ import annotations

import logging
import math
import threading
import time as _time
from collections import defaultdict
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rasm.comm.message import Message
from rasm.comm.presence import PresenceTracker
from rasm.comm.signing import BoundSigner, SignedGate
from rasm.comm.topics import topic_matches, validate_pattern, validate_topic
from rasm.comm.transport import Subscription, Transport
from rasm.errors import CommError, Location, RasmError, SourceError
from rasm.logs import RepeatedLogs
from rasm.properties import Verdict, load_specification
from rasm.properties.monitor import Monitor
from rasm.properties.outcome import PropertyOutcome
from rasm.properties.vacuity import Vacuity
from rasm.times import format_seconds

__all__ = [
    "VERDICT_TOPIC",
    "Attachment",
    "MonitorSummary",
    "Seal",
    "SignedVerdicts",
    "Source",
    "TopicMap",
    "default_topic_map",
    "load_topic_map",
]

_log = logging.getLogger("rasm.attach")


@dataclass(frozen=True)
class Source:
    """Where one signal is read: a topic, and a payload field (None: ``value``, else the
    signal's own name)."""

    signal: str
    topic: str
    field: str | None = None

    def extract(self, payload: Mapping[str, Any]) -> tuple[bool, Any]:
        """``(found, value)`` of this signal in ``payload``."""
        if self.field is not None:
            return (True, payload[self.field]) if self.field in payload else (False, None)
        if "value" in payload:
            return True, payload["value"]
        if self.signal in payload:
            return True, payload[self.signal]
        return False, None


TopicMap = dict[str, Source]
"""Signal name -> :class:`Source`; the key ``*`` names the topic of every unmapped signal."""

ALL = "*"
TRACE_TOPIC = "rasm/trace"  # where a rasm loop on a broker publishes every trace record
VERDICT_TOPIC = "rasm/verdict/{property}"  # where rasm publishes a property's verdicts (SPEC §10)

Seal = Callable[[str, dict[str, Any]], dict[str, Any]]
"""``seal(topic, payload)``: the payload as it goes on ``topic`` (e.g. signed); raises
:class:`CommError` when it cannot be sent yet."""


class SignedVerdicts:
    """A :data:`Seal` for the loops that take verdicts as external verdict sources over MQTT with
    ``RASM_ACTION_KEY``: each verdict is signed with ``key`` and bound (:class:`BoundSigner`) to
    its topic and to the epochs of the managing processes (role ``all`` or ``managing``) that
    introduced themselves with a correctly signed presence message, as those loops require.

    Call :meth:`start` (it follows ``rasm/presence/+``) before the first verdict and :meth:`stop`
    after the last. Until a loop has introduced itself there is nobody to bind to: the seal
    raises :class:`CommError` and the verdict is not sent.
    """

    ROLES = ("all", "managing")

    def __init__(self, transport: Transport, key: bytes) -> None:
        # its own gate only tells signed introductions from forged ones: nobody binds to it
        self.tracker = PresenceTracker(transport, gate=SignedGate(key))
        self.signer = BoundSigner(key)

    def start(self) -> SignedVerdicts:
        self.tracker.start()
        return self

    def stop(self) -> None:
        self.tracker.stop()

    def epochs(self) -> list[str]:
        """The epochs of the loops that introduced themselves and have not gone offline."""
        return sorted({e for role in self.ROLES for e in self.tracker.known_epochs(role=role)})

    def __call__(self, topic: str, payload: dict[str, Any]) -> dict[str, Any]:
        epochs = self.epochs()
        if not epochs:
            raise CommError(
                "no rasm loop has announced its epoch on rasm/presence/ with a signed message "
                "yet: a verdict is bound to the loop that takes it"
            )
        return self.signer.sign(payload, topic=topic, epochs=epochs)


def default_topic_map(signals: list[str]) -> TopicMap:
    """Each signal read from the topic of its own name."""
    return {name: Source(name, name) for name in signals}


def load_topic_map(
    path: str | Path, signals: list[str], *, text: str | None = None
) -> TopicMap:
    """The topic map of a ``--topics`` YAML file, completed with the default for every signal
    it does not name. Raises :class:`SourceError` naming the file (and line) of a problem."""
    from rasm.yamltext import load_yaml, plain

    source = str(path)
    if text is None:
        try:
            text = Path(path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise SourceError(f"cannot read the topic map: {exc}", Location(source)) from None
    data = plain(load_yaml(text, source).data)  # a syntax error or a guard's: at its place
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise SourceError(
            "a topic map is a mapping 'signal: topic' or 'signal: {topic: T, field: F}'",
            Location(source, 1, 1),
        )
    lines = text.splitlines()
    mapping: TopicMap = {}
    for signal, entry in data.items():
        where = _find_line(source, lines, str(signal))
        if signal == ALL:
            if not isinstance(entry, str):
                raise SourceError(
                    f"'{ALL}': write the topic every other signal is read from", where
                )
            try:
                validate_topic(entry)
            except CommError as exc:
                raise SourceError(f"'{ALL}': {exc}", where) from None
            mapping[ALL] = Source(ALL, entry)
            continue
        if signal not in signals:
            known = ", ".join(signals) or "none"
            raise SourceError(
                f"{signal!r} is not a signal the properties read (they read: {known})", where
            )
        if isinstance(entry, str):
            topic, fld = entry, None
        elif isinstance(entry, dict) and set(entry) <= {"topic", "field"} and "topic" in entry:
            topic, fld = entry["topic"], entry.get("field")
        else:
            raise SourceError(
                f"{signal!r}: write a topic, or {{topic: T, field: F}}; got {entry!r}", where
            )
        if not isinstance(topic, str) or (fld is not None and not isinstance(fld, str)):
            raise SourceError(f"{signal!r}: topic and field must be text", where)
        try:
            validate_topic(topic)
        except CommError as exc:
            raise SourceError(f"{signal!r}: {exc}", where) from None
        mapping[signal] = Source(signal, topic, fld)
    for signal in signals:
        mapping.setdefault(signal, _fallback(signal, mapping.get(ALL)))
    return mapping


def _fallback(signal: str, everything: Source | None) -> Source:
    """Where an unmapped signal is read: the ``*`` topic (field of its name), else its own."""
    if everything is not None:
        return Source(signal, everything.topic, signal)
    return Source(signal, signal)


def _find_line(source: str, lines: list[str], key: str) -> Location:
    for number, line in enumerate(lines, 1):
        stripped = line.lstrip()
        if stripped.startswith((f"{key}:", f'"{key}":', f"'{key}':")):
            return Location(source, number, len(line) - len(stripped) + 1)
    return Location(source)


@dataclass
class MonitorSummary:
    """What an attachment saw: messages, records stepped, refusals, and each property's verdicts
    counted in ``outcomes`` (whose state is the property's overall verdict)."""

    messages: int = 0
    records: int = 0
    malformed: int = 0
    rejected: int = 0
    published: int = 0
    unsent: int = 0  # verdicts the seal could not seal (no loop to bind them to yet)
    outcomes: dict[str, PropertyOutcome] = field(default_factory=dict)
    first_violations: dict[str, float] = field(default_factory=dict)
    properties: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def outcome(self, name: str) -> PropertyOutcome:
        """Property ``name``'s outcome (a fresh one for a property not seen before)."""
        if name not in self.outcomes:
            self.outcomes[name] = PropertyOutcome(name)
        return self.outcomes[name]

    @property
    def satisfied(self) -> dict[str, int]:
        """Property -> how many of its verdicts were true (those with any)."""
        counts = {
            name: o.judged - o.violations - o.errors - o.inconclusive
            for name, o in self.outcomes.items()
        }
        return {name: n for name, n in counts.items() if n}

    @property
    def violated(self) -> dict[str, int]:
        """Property -> how many of its verdicts were false (those with any)."""
        return {name: o.violations for name, o in self.outcomes.items() if o.violations}

    @property
    def errors(self) -> dict[str, int]:
        """Property -> at how many records it could not be evaluated (those with any)."""
        return {name: o.errors for name, o in self.outcomes.items() if o.errors}

    @property
    def any_violated(self) -> bool:
        return bool(self.violated)

    @property
    def failed(self) -> list[str]:
        """The properties that do not pass: violated, in error or not judged."""
        return [name for name in self.properties if not self.outcome(name).passed]

    def format(self) -> str:
        """A few lines for a terminal."""
        out = [
            f"{self.messages} message(s), {self.records} record(s) in {self.seconds:.1f} s; "
            f"{self.malformed} malformed, {self.rejected} refused by the monitor; "
            f"{self.published} verdict(s) published"
            + (f", {self.unsent} not sent (no loop to bind them to)" if self.unsent else "")
        ]
        width = max((len(p) for p in self.properties), default=0)
        untested = []
        for name in self.properties:
            o = self.outcome(name)
            true = o.judged - o.violations - o.errors - o.inconclusive
            state = o.state
            if o.passed and o.vacuous:  # passing, but part of it was never put to the test
                untested.append(o)
                state += "*"
            line = (
                f"  {name:<{width}}  {state:<12} {true} true, {o.violations} false, "
                f"{o.inconclusive} inconclusive"
            )
            if o.errors:
                line += f", {o.errors} in error (first: {o.first_error})"
            if name in self.first_violations:
                line += f" (first violation at t={format_seconds(self.first_violations[name])})"
            if o.missing:
                line += f" (no value for {', '.join(o.missing)})"
            out.append(line)
        if untested:  # as rasm run's summary says it
            out.append("* never put to the test:")
            out += [f"  {o.name}: {o.word}" for o in untested]
        return "\n".join(out) + "\n"


class Attachment:
    """Monitors of one property file attached to a transport (see the module doc).

    ``verdict_topic`` is a format string with ``{property}`` (default
    :data:`VERDICT_TOPIC`, ``rasm/verdict/{property}``); a verdict topic the attachment reads
    itself is refused. ``seal`` (e.g. :class:`SignedVerdicts`) turns each verdict's payload
    into what is published. ``on_verdict(verdict)`` is called for every decided verdict, after
    it is published. Call :meth:`start`, then :meth:`stop` (which settles the monitor and
    returns the summary).
    """

    def __init__(
        self,
        text: str,
        transport: Transport,
        *,
        source: str = "<properties>",
        topics: TopicMap | None = None,
        verdict_topic: str = VERDICT_TOPIC,
        seal: Seal | None = None,
        on_verdict: Callable[[Verdict], object] | None = None,
        qos: int = 0,
    ) -> None:
        self.spec = load_specification(text, source=source)
        self.monitor = Monitor(self.spec)
        # watches the antecedents of the properties' ->; a failed watch is kept in _dropped
        self.vacuity: Vacuity | None = Vacuity(self.spec)
        self._dropped: Vacuity | None = None
        self.signals = list(self.spec.signals)
        # no map: a rasm loop's trace topic, and each signal's own topic besides
        self._default = topics is None
        self.topics: TopicMap = dict(topics) if topics is not None else {}
        self._everything = (
            Source(ALL, TRACE_TOPIC) if self._default else self.topics.pop(ALL, None)
        )
        if self._default:
            self.topics = default_topic_map(self.signals)
        for signal in self.signals:
            self.topics.setdefault(signal, _fallback(signal, self._everything))
        self.transport = transport
        self.verdict_topic = verdict_topic
        self.seal = seal
        self.on_verdict = on_verdict
        self.qos = qos
        self.summary = MonitorSummary(properties=self.monitor.properties)
        self._by_topic = self._route(self.signals)
        self._check_verdict_topics(self.monitor.properties, self._by_topic)
        self.logs = RepeatedLogs()
        self._lock = threading.Lock()
        self._publishing = threading.Lock()  # one verdict sealed and sent at a time, in order
        self._subscriptions: dict[str, Subscription] = {}
        self._started = 0.0
        self._transport_malformed: int | None = None  # the transport's count at start()
        self._stopped = False

    def _check_verdict_topics(self, properties: list[str], read: dict[str, list[Source]]) -> None:
        """Each property's verdict topic is a topic, and none the attachment reads (it would
        take its own verdicts for records)."""
        if "{property}" not in self.verdict_topic:
            raise CommError(
                f"the verdict topic {self.verdict_topic!r} must name the property with "
                "{property} (on one topic for all, a verdict would not say whose it is)"
            )
        for name in properties:
            try:
                topic = self.verdict_topic.format(property=name)
            except (KeyError, IndexError, ValueError) as exc:
                raise CommError(
                    f"the verdict topic {self.verdict_topic!r} must be a topic with "
                    f"{{property}} for the property's name ({type(exc).__name__}: {exc})"
                ) from None
            validate_topic(topic)
            for pattern in read:
                if topic_matches(pattern, topic):
                    raise CommError(
                        f"the verdicts of {name} would go on {topic}, which the monitor reads "
                        f"({pattern}): give the verdicts another topic"
                    )

    @property
    def subscribed_topics(self) -> list[str]:
        return sorted(self._by_topic)

    @property
    def trace_topic(self) -> str | None:
        """The topic whose every message is a trace record (``"*"``; ``rasm/trace`` by default)."""
        return self._everything.topic if self._everything is not None else None

    def _route(
        self, signals: list[str], topics: TopicMap | None = None
    ) -> dict[str, list[Source]]:
        """Topic -> the sources of ``signals`` read from it (the trace topic always listed);
        ``topics``: the topic map (default: the attachment's)."""
        topics = self.topics if topics is None else topics
        by_topic: dict[str, list[Source]] = defaultdict(list)
        trace = self.trace_topic
        if trace is not None:
            by_topic[trace] = []
        for signal in signals:
            src = topics[signal]
            by_topic[src.topic].append(src)
            if self._default and src.topic != trace:
                by_topic[trace].append(Source(signal, trace, signal))
        return by_topic

    def start(self) -> Attachment:
        """Subscribe to every mapped topic (returns once the broker confirmed); returns self."""
        self._started = _time.monotonic()
        # messages the transport itself drops (not JSON, not an object, too big) never reach
        # _receive: the summary counts them with the malformed ones from here on
        self._transport_malformed = self._transport_malformed_count()
        self._subscribe(self.subscribed_topics)
        return self

    def _transport_malformed_count(self) -> int:
        return int(getattr(getattr(self.transport, "stats", None), "malformed", 0) or 0)

    def _subscribe(self, topics: list[str]) -> None:
        for topic in topics:
            if topic not in self._subscriptions:
                validate_pattern(topic)
                self._subscriptions[topic] = self.transport.subscribe(
                    topic, self._receive, qos=self.qos
                )

    def replace(self, text: str, *, source: str = "<update>") -> tuple[bool, str]:
        """Replace the properties by those of ``text``; returns ``(accepted, reason)``.

        The public checker's ``reconfig``, reached here through a *signed* update:
        ``UpdateReceiver(transport, key, properties=attachment.replace)``. A file that does not
        load is refused and the properties in force stay. Otherwise the old monitor is settled
        (its decided verdicts published), new signals are read where the topic map says (by
        default the topic of their name) and topics no longer read are left.
        """
        try:
            spec = load_specification(text, source=source)
            monitor = Monitor(spec)
            vacuity = Vacuity(spec)
        except RasmError as exc:
            return False, f"properties kept: the new file does not load: {exc}"
        signals = list(spec.signals)
        topics = dict(self.topics)
        for signal in signals:
            default = Source(signal, signal) if self._default else None
            topics.setdefault(signal, default or _fallback(signal, self._everything))
        by_topic = self._route(signals, topics)
        try:
            self._check_verdict_topics(monitor.properties, by_topic)
        except CommError as exc:
            return False, f"properties kept: {exc}"
        self.topics = topics
        self._subscribe(sorted(by_topic))  # before the swap: no record of the new set is missed
        with self._lock:
            if self._stopped:
                return False, "properties kept: the monitor is stopped"
            settled = self._settle()
            self.spec, self.monitor, self.signals = spec, monitor, signals
            self.vacuity, self._dropped = vacuity, None
            self._by_topic = by_topic
            known = self.summary.properties
            known += [name for name in monitor.properties if name not in known]
        for topic in [t for t in self._subscriptions if t not in by_topic]:
            self._subscriptions.pop(topic).cancel()
        self._publish(settled)
        return True, f"properties replaced by {source}: {', '.join(monitor.properties)}"

    # -- one message ----------------------------------------------------------------------------
    def _malformed(self, message: Message, why: str) -> None:
        self.summary.malformed += 1
        n = self.summary.malformed
        if n <= 10 or n % 1000 == 0:
            _log.warning("message #%d on %r ignored: %s", n, message.topic, why)

    def _receive(self, message: Message) -> None:
        payload = message.payload
        with self._lock:
            if self._stopped:
                return
            self.summary.messages += 1
            record: dict[str, Any] = {}
            for src in self._by_topic.get(message.topic, ()):
                found, value = src.extract(payload)
                if found:
                    record[src.signal] = value
            if not record and message.topic != self.trace_topic:
                self._malformed(message, "it carries none of the mapped signals")
                return
            stamp = payload.get("time", message.timestamp)
            if stamp is None:
                stamp = _time.time()
            if isinstance(stamp, bool) or not isinstance(stamp, int | float) or not math.isfinite(
                stamp
            ):
                self._malformed(message, f"'time' must be a finite number, not {stamp!r}")
                return
            try:
                verdicts = self.monitor.step(float(stamp), record)
            except Exception as exc:  # fail closed: its properties are in error for the record
                verdicts = self._failed(float(stamp), exc)
            if self.monitor.rejected:
                reason = self.monitor.rejected[-1].reason
                self.monitor.rejected.clear()  # counted here: a long run keeps no list
                self.summary.rejected += 1
                if self.summary.rejected <= 10 or self.summary.rejected % 1000 == 0:
                    _log.warning("record from %r refused: %s", message.topic, reason)
                return
            self.summary.records += 1
            self._count(verdicts)
            self._watch(float(stamp), record)
        self._publish(verdicts)

    def _watch(self, time: float, record: dict[str, Any]) -> None:
        """Step the antecedents' watch; one that fails is dropped (logged), and what has not
        held by then is reported vacuous: said, not hidden."""
        if self.vacuity is None:
            return
        try:
            self.vacuity.step(time, record)
        except Exception as exc:
            _log.error("watching the antecedents of %s failed at t=%s: %s: %s; those that have "
                       "not held so far are reported vacuous", self.spec.source,
                       format_seconds(time), type(exc).__name__, exc, exc_info=exc)
            self._dropped, self.vacuity = self.vacuity, None

    def _settle(self) -> list[Verdict]:
        """Finish the monitor: count the verdicts still open, name the signals each property
        never judged waits for and the antecedents that never held. Returns the verdicts to
        publish."""
        verdicts = self.monitor.finish()
        self._count(verdicts)
        vacuity = self.vacuity
        if vacuity is not None:
            try:
                vacuity.finish()
            except Exception as exc:
                _log.error("watching the antecedents of %s failed at the end: %s: %s",
                           self.spec.source, type(exc).__name__, exc, exc_info=exc)
        else:
            vacuity = self._dropped
        for name in self.monitor.properties:
            outcome = self.summary.outcome(name)
            if not outcome.judged:
                outcome.missing = self.monitor.missing(name)
            if vacuity is not None:
                outcome.vacuous = vacuity.vacuous(name)
        return verdicts

    def _failed(self, time: float, exc: Exception) -> list[Verdict]:
        """Every property of the monitor in error for this record (the first failure is logged
        with its traceback; the summary counts them all)."""
        why = f"the monitor raised {type(exc).__name__}: {exc}"
        if not any(o.errors for o in self.summary.outcomes.values()):
            _log.error("monitor failed at t=%s: %s", format_seconds(time), why, exc_info=exc)
        index = self.summary.records
        return [Verdict(name, index, time, False, why) for name in self.monitor.properties]

    def _count(self, verdicts: list[Verdict]) -> None:
        summary = self.summary
        for verdict in verdicts:
            summary.outcome(verdict.property).add(verdict.value, verdict.error)
            if verdict.value is False and verdict.error is None:
                summary.first_violations.setdefault(verdict.property, verdict.time)

    def _publish(self, verdicts: list[Verdict]) -> None:
        for verdict in verdicts:
            if verdict.value is None:
                continue
            topic = self.verdict_topic.format(property=verdict.property)
            payload: dict[str, Any] = {"value": verdict.value, "time": verdict.time}
            if verdict.error is not None:  # value false: the checker could not vouch for it
                payload["error"] = verdict.error
            self._send(verdict.property, topic, payload)
            if self.on_verdict is not None:
                try:
                    self.on_verdict(verdict)
                except Exception:
                    _log.exception("on_verdict raised on %r", verdict)

    def _send(self, name: str, topic: str, payload: dict[str, Any]) -> None:
        # sealed and sent under one lock: a signed verdict's sequence is its order on the bus
        with self._publishing:
            if self.seal is not None:
                try:
                    payload = self.seal(topic, payload)
                except CommError as exc:  # nobody to bind it to yet: the loop's source vetoes
                    with self._lock:
                        self.summary.unsent += 1
                    self.logs.log(_log, logging.WARNING, "verdicts not sent",
                                  "verdict of %s not sent: %s", name, exc)
                    return
            try:
                self.transport.publish(topic, payload, qos=self.qos)
            except CommError as exc:
                _log.warning("verdict of %s not published: %s", name, exc)
                return
        with self._lock:
            self.summary.published += 1

    # -- the end --------------------------------------------------------------------------------
    def stop(self) -> MonitorSummary:
        """Unsubscribe, settle the monitor (publishing the verdicts it decides), return the
        summary (idempotent)."""
        for subscription in list(self._subscriptions.values()):
            subscription.cancel()
        self._subscriptions.clear()
        with self._lock:
            if self._stopped:
                return self.summary
            self._stopped = True
            if self._transport_malformed is not None:
                self.summary.malformed += (
                    self._transport_malformed_count() - self._transport_malformed
                )
            verdicts = self._settle()
            self.summary.seconds = _time.monotonic() - self._started if self._started else 0.0
        self._publish(verdicts)  # a closed transport: logged, not raised
        return self.summary

    def __enter__(self) -> Attachment:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
