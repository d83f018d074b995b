"""The platform: one application's process, built, run and stopped.

:class:`Platform` is what ``rasm run`` drives and what :func:`rasm.testing.run_app` uses::

    platform = Platform("examples/hotbox", RunOptions(clock=Clock.SIMULATED, seed=1))
    summary = platform.run(duration=60)

Every part is built by :func:`rasm.platform.assembly.assemble`, which says where each building
block is made and what it receives (:attr:`Platform.assembly`); this module starts, runs and
stops them, and keeps the data paths the blocks report through (values into knowledge, trace
records, the managed system's changes, external verdicts).

The managing side (Core and the building blocks) and the managed side (the app's simulator,
with its probes and effectors) meet only on the transport: the simulator publishes on probe
topics, Telegraf digests them into knowledge, and actions reach the simulator only through the
Trustworthiness Checker publishing on an effector topic.
"""

from __future__ import annotations

import gc
import logging
import math
import random
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rasm.comm import Message
from rasm.errors import PlatformError
from rasm.logs import RepeatedLogs
from rasm.losses import WriteFailure
from rasm.platform.action_outcome import Emit
from rasm.platform.actions_out import message_types
from rasm.platform.assembly import Assembly, ManagingSide, assemble
from rasm.platform.distribution import DistributionHooks
from rasm.platform.manifest import AppManifest
from rasm.platform.run_options import Clock, RunOptions, check_run
from rasm.platform.scheduler import Scheduler
from rasm.platform.state_dir import default_state_dir
from rasm.platform.summary import RunSummary, bus_refusals, summarise
from rasm.properties.monitor import Monitor, Verdict
from rasm.statechart import MonotonicClock, SimulatedClock
from rasm.times import elapsed_seconds, from_nanoseconds
from rasm.trace import TraceWriter
from rasm.trace_mcap import open_trace_writer

__all__ = ["Platform", "RunSummary"]

_log = logging.getLogger("rasm.platform")
_SCALARS = (int, float, bool, str)


class Platform:
    """One application's managing system (and, with role ``all``, its managed system), run with
    ``options`` (:class:`~rasm.platform.run_options.RunOptions`; the defaults when None).

    A property or rule that reads a name no part of the app provides raises
    :class:`~rasm.errors.SourceErrors` here (:func:`rasm.platform.signals.check_app`);
    ``RunOptions(check_signals=False)`` runs such an app anyway (its properties are then never
    judged).
    """

    def __init__(
        self, manifest: AppManifest | str | Path, options: RunOptions | None = None
    ) -> None:
        options = RunOptions() if options is None else options
        if not isinstance(options, RunOptions):
            raise TypeError(
                f"Platform(app, options) takes a RunOptions, not {type(options).__name__}"
            )
        manifest, self.clock_kind, self.transport_url = check_run(manifest, options)
        self.manifest = manifest
        self.options = options
        self.clock = (
            SimulatedClock() if self.clock_kind is Clock.SIMULATED
            else MonotonicClock(running=False)
        )
        self.scheduler = Scheduler(self.clock, on_error=self._job_failed)
        self.trace: TraceWriter = open_trace_writer(
            options.trace, max_bytes=options.trace_max_bytes, keep=options.trace_keep
        )
        self.state_dir = (
            Path(options.state_dir) if options.state_dir else default_state_dir(manifest)
        )
        self.scenario = options.scenario_of(manifest)
        self.on_record: list[Emit] = []
        # every verdict of the online monitors goes to these callables (loop thread); nothing
        # keeps them, so a long run does not grow (the trace file has the records they judge).
        # Append to and remove from this list: the Trustworthiness Checker holds it.
        self.on_verdict: list[Callable[[Verdict], object]] = []
        # robustness values the checker wrote, for the trace's next record
        self._robustness_due: dict[str, float] = {}
        self.stopped_by: str | None = None  # why the run ended early (request_stop)
        # every failure the loop logs per iteration or record: once in full, then counted
        self.logs = RepeatedLogs()
        self._assembly: Assembly | None = None
        self._started_at = 0.0
        self._gc_frozen = False
        self._external_due: float | None = None  # when the sources are looked at next
        self._watch_due: float | None = None  # when the probes' staleness is looked at next

    # ------------------------------------------------------------------ assembly

    def build(self) -> None:
        """Create every part (not started yet: :meth:`start` asks Core to do that)."""
        self._assembly = assemble(
            self.manifest,
            self.options,
            clock_kind=self.clock_kind,
            transport_url=self.transport_url,
            clock=self.clock,
            scheduler=self.scheduler,
            trace=self.trace,
            state_dir=self.state_dir,
            logs=self.logs,
            paths=self,
        )

    @property
    def built(self) -> bool:
        return self._assembly is not None

    @property
    def assembly(self) -> Assembly:
        """Every part of this process, as :func:`~rasm.platform.assembly.assemble` built it."""
        if self._assembly is None:
            raise PlatformError("the platform is not built yet: call build() or start() first")
        return self._assembly

    @property
    def managing(self) -> ManagingSide:
        """The managing side's parts: knowledge and the loop's blocks."""
        side = self.assembly.managing
        if side is None:
            raise PlatformError(f"a process of role {self.options.role} has no managing side")
        return side

    @property
    def verdicts_published(self) -> int:
        """How many verdicts went out on the transport (see :mod:`rasm.platform.verdicts_out`)."""
        side = self._assembly.managing if self._assembly is not None else None
        if side is None or side.verdicts_out is None:
            return 0
        return side.verdicts_out.published

    @property
    def restored_from(self) -> str | None:
        """The store a live run's timeline continues from (None: it starts at 0)."""
        side = self._assembly.managing if self._assembly is not None else None
        return side.knowledge.restored_from if side is not None else None

    @property
    def timeline_start(self) -> float:
        """Where this run's clock starts: 0, or after the newest sample a live run restored
        from :attr:`restored_from`."""
        side = self._assembly.managing if self._assembly is not None else None
        return side.knowledge.timeline_start if side is not None else 0.0

    @property
    def transport_store(self) -> Any:
        """The app's ROS 2 types (the standard interfaces when it has none of its own)."""
        return message_types(self.manifest)

    def _tick(self) -> None:
        """One loop period: the managed system's witnesses are read (the ROS graph has no
        deadline to wake on), the fallback switch reads its triggers, then the loop runs."""
        side = self.managing
        side.watch.evaluate()
        if side.fallback_switch is not None:
            side.fallback_switch.evaluate()
        side.adaptation_orchestrator.orchestration_loop()

    # ------------------------------------------------------------------ data paths

    def register_values(self, values: dict[str, Any], time: float) -> None:
        """Store values in knowledge (one trace record for the batch, with the twin's residual
        when they were the twin's inputs)."""
        side = self.managing
        # one call for the batch: a bad value is refused on its own, logged and dropped
        refused = side.knowledge_manager.register_values(values, time)
        for key, exc in refused.items():
            self.refused(key, values[key], exc)
        # the trace record has the scalars stored
        stored = {
            key: value
            for key, value in values.items()
            if key not in refused and isinstance(value, _SCALARS)
        }
        learning = side.twin_learning
        if learning is not None and learning.reads(values):
            learning.observe(time, stored)
        if side.modes is not None:
            # a change of the managed system's modes goes in the record that caused it
            change = side.modes.observe(
                time, {key: value for key, value in values.items() if key not in refused}
            )
            if change:
                stored.update(change)
        if stored:
            self.emit(time, stored)

    def refused(self, key: str, value: object, exc: Exception) -> None:
        """Log a value knowledge refused; the same reason again (whatever the value) is counted."""
        reason = str(exc).replace(repr(value), "…")
        self.logs.log(
            _log,
            logging.WARNING,
            f"knowledge {key} refused: {reason}",
            "knowledge %s=%r refused: %s",
            key,
            value,
            exc,
        )

    def write_robustness(self, values: dict[str, float], time: float) -> None:
        """The properties' robustness into knowledge now, and into the trace on the next record
        the loop writes: a record of its own would be judged again and give robustness again."""
        refused = self.managing.knowledge_manager.register_values(values, time)
        for key, exc in refused.items():
            self.refused(key, values[key], exc)
        self._robustness_due.update(values)

    def emit(self, time: float, record: dict[str, Any]) -> None:
        """Write one trace record (and hand it to :attr:`on_record`), with the robustness
        values written since the last one."""
        if self._robustness_due:
            record = {**record, **self._robustness_due}
            self._robustness_due.clear()
        self.trace.emit(time, record)
        for observer in self.on_record:
            observer(time, record)

    def managed_system_mode(self) -> str | frozenset[str] | None:
        """The managed system's mode, by which an effector is applicable or not: the active
        states of the modes chart, or the mode signal's value."""
        side = self.managing
        if side.modes is not None:
            return side.modes.mode
        signal = self.manifest.mode_signal
        return side.knowledge.store.read_knowledge(signal) if signal else None

    def timeline(self, stamp_ns: int) -> float:
        """A message's ``header.stamp`` (wall-clock nanoseconds) on the platform's timeline:
        on the wall clock, where that wall time falls; a replay's timeline starts at the
        recording's first log time (exact to the nanosecond); a simulated run takes stamps as
        they are."""
        parts = self.assembly
        if self.clock_kind is Clock.WALL:
            return parts.distribution.platform_time(stamp_ns / 10**9)
        origin = parts.replay.origin_ns if parts.replay is not None else 0
        return from_nanoseconds(stamp_ns - origin)

    def stale(self, signals: dict[str, str]) -> None:
        """Probe signals (name -> why) gone stale: the properties reading them are in error."""
        self.managing.trustworthiness_checker.set_stale(signals, self.scheduler.now())

    def _on_external_verdict(self, name: str, message: Message) -> None:
        # on the transport's thread: the verdict is taken on the loop's, at the loop's time
        payload = message.payload
        self.scheduler.submit(lambda: self._take_external(name, payload))

    def _take_external(self, name: str, payload: Any) -> None:
        side = self.managing
        verdict = side.external_verdicts.receive(name, payload, self.scheduler.now())
        if verdict is not None:
            side.trustworthiness_checker.take(verdict)
        self._external_wake()

    def _external_wake(self) -> None:
        """Have the external sources looked at when time alone changes one (a false leaving
        its window, a source going stale), not only at the next record."""
        now = self.scheduler.now()
        due = self.managing.external_verdicts.next_change(now)
        if due is not None and (self._external_due is None or due < self._external_due
                                or self._external_due <= now):
            self._external_due = due
            self.scheduler.at(due, self._external_tick)

    def _external_tick(self) -> None:
        self._external_due = None
        side = self.managing
        for verdict in side.external_verdicts.step(self.scheduler.now(), {}):
            side.trustworthiness_checker.take(verdict)
        self._external_wake()

    def _on_probe(self, message: Message) -> None:
        # delivered on the transport's thread: digested on the loop's, at the loop's time then
        topic, payload = message.topic, message.payload
        self.scheduler.submit(lambda: self._digest(topic, payload, self.scheduler.now()))

    def _digest(self, topic: str, payload: Any, time: float) -> dict[str, Any]:
        """One probe message into knowledge; a probe that stored values is live."""
        side = self.managing
        stored = side.telegraf.digest(topic, payload, time)
        if stored:
            side.watch.heard(topic, time)
            if self._watch_due is None:
                self._watch_schedule()
        return stored

    def _watch_schedule(self) -> None:
        """Have the managed system's witnesses read when a probe would go stale (one wake
        pending at a time; a probe heard meanwhile moves the next one on)."""
        due = self.managing.watch.next_deadline()
        self._watch_due = due
        if due is not None:
            self.scheduler.at(due, self._watch_tick)

    def _watch_tick(self) -> None:
        self.managing.watch.evaluate()
        self._watch_schedule()

    def managed_system_changed(self, lost: bool, why: str) -> None:
        """The managed system is lost or back (loop thread): traced, told to the orchestrator,
        and the fallback's triggers read at once."""
        side = self.managing
        event = "managed_system_lost" if lost else "managed_system_back"
        (_log.warning if lost else _log.info)("%s: %s", event, why or "every witness is back")
        self.emit(self.scheduler.now(), {"explanation": f"{event}: {why}" if lost else event})
        if side.adaptation_orchestrator.mode == "initialized":
            side.adaptation_orchestrator.send(event)
        if side.fallback_switch is not None:
            side.fallback_switch.evaluate()

    def _job_failed(self, exc: BaseException) -> None:
        what = f"a loop job failed: {type(exc).__name__}: {exc}"
        self.logs.log(_log, logging.ERROR, what, exc_info=exc)

    def _hooks(self) -> DistributionHooks:
        """What presence and updates from the network act on (called on a transport thread,
        so what touches the loop is handed to the loop thread)."""
        side = self.managing

        def managed_system(event: str) -> None:
            # presence is one witness of the managed system's: the watch says what changed
            self.scheduler.submit(side.watch.evaluate)

        def add_monitor(monitor: Monitor) -> None:
            self.scheduler.submit(lambda: side.trustworthiness_checker.add_monitor(monitor))

        return DistributionHooks(
            managed_system=managed_system,
            node=self.assembly.state_manager.set_node,
            rules=side.rules,
            add_monitor=add_monitor,
        )

    # ------------------------------------------------------------------ running

    def start(self) -> None:
        """Build (if needed) and start every block in dependency order, then wire the loop."""
        if self._assembly is None:
            self.build()
        parts = self.assembly
        side = parts.managing
        if isinstance(self.clock, MonotonicClock):
            # building took time; the run's timeline starts now (or after restored knowledge)
            self.clock.start_at(self.timeline_start)
        elif parts.replay is not None and parts.replay.first_time is not None:
            # a replay runs on the recording's time: its trace has the recording's times
            self.clock.time = max(self.clock.time, parts.replay.first_time)
        parts.core.initialize()
        if side is not None and side.modes is not None:
            side.modes.start(self.clock.time)
        if self.options.low_latency and not self._gc_frozen:
            # the process is the loop's own: what was built is moved out of the collector's
            # reach, so a full collection cannot pause the loop (docs/runtime.md)
            gc.collect()
            gc.freeze()
            self._gc_frozen = True
        self._started_at = self.clock.time
        parts.distribution.start(
            parts.transport,
            self.trace.observers,
            clock_time=self.clock.time,
            hooks=self._hooks() if side is not None else None,
        )
        m = self.manifest
        communication = parts.communication_manager
        if parts.replay is not None:
            parts.replay.start(self.scheduler, self._digest, tail=m.period)
        elif side is not None:
            for probe in m.probes:
                communication.subscribe(probe.topic, self._on_probe)
        if side is not None:
            for name, source in m.external_verdicts.items():
                communication.subscribe(
                    source.topic,
                    lambda message, name=name: self._on_external_verdict(name, message),
                )
            # a loop that overran skips the iterations it missed (Scheduler.missed)
            self.scheduler.every(
                m.period, self._tick, start=self.clock.time + m.period, skip_missed=True
            )
            side.watch.begin()
            self._watch_tick()
        if parts.managed_system is not None:
            parts.managed_system.start(
                communication, self.scheduler, started_at=self._started_at,
                gate=parts.distribution.effector_gate,
            )

    def run(self, duration: float | None = None) -> RunSummary:
        """Start, run for ``duration`` seconds of the platform's clock, stop, summarise.

        :meth:`request_stop` ends the run early, in the same order as a normal end.
        """
        random.seed(self.options.seed)
        self.start()
        length = duration if duration is not None else self.manifest.duration
        if self.assembly.replay is not None and duration is None:
            length = math.inf  # to the end of the recording (the replay stops the scheduler)
        try:
            self.scheduler.run_until(self._started_at + length if length < math.inf else None)
            # exactly: a replay's clock reads epoch seconds, where a float difference has noise
            ran = min(length, elapsed_seconds(self._started_at, self.clock.time))
        finally:
            self.stop()
        if ran >= length:  # a stop asked for as the run ended anyway changed nothing
            self.stopped_by = None
        side = self.assembly.managing
        if side is not None:
            side.trustworthiness_checker.finish()  # the verdicts still open go to observers too
        self.trace.close()
        return self.summary(ran)

    def request_stop(self, reason: str = "a stop request") -> None:
        """End :meth:`run` after the job in hand: knowledge persisted, trace closed, summary
        made, as at a normal end. Safe from another thread and from a signal handler (it only
        sets a flag the loop reads); a request before the run starts makes it end at once."""
        self.stopped_by = reason
        self.scheduler.stop()

    def stop(self) -> None:
        parts = self._assembly
        side = parts.managing if parts is not None else None
        if side is not None and side.call_effectors is not None:
            side.call_effectors.close()  # goals cancelled while the transport is still there
        self.logs.flush()  # the counts still unreported, while the log sinks are attached
        if parts is not None:
            parts.distribution.stop()
            if parts.core.mode != "terminated":
                parts.core.deinitialize()
        self.trace.flush()
        if self._gc_frozen:
            gc.unfreeze()
            self._gc_frozen = False

    def summary(self, duration: float) -> RunSummary:
        """The run so far, read from the blocks (nothing is changed)."""
        parts = self.assembly
        side = parts.managing
        return summarise(
            self.manifest.name,
            self.clock_kind,
            duration,
            state=parts.state_manager,
            checker=side.trustworthiness_checker if side is not None else None,
            orchestrator=side.adaptation_orchestrator if side is not None else None,
            telegraf=side.telegraf if side is not None else None,
            trace=self.trace,
            bus=bus_refusals(
                parts.transport,
                parts.distribution,
                sum(side.external_verdicts.refused.values()) if side is not None else 0,
            ),
            missed_iterations=self.scheduler.missed,
            stopped_by=self.stopped_by,
            repeated_failures=self.logs.totals,
            fallback=side.fallback_switch if side is not None else None,
            write_failures=self.write_failures(),
            damage=parts.replay.damage if parts.replay is not None else [],
            calls=(side.call_effectors.counts
                   if side is not None and side.call_effectors is not None else {}),
            role=self.options.role,
            managed=parts.managed_system,
            off=tuple(name for name, limits in self.manifest.platform_properties.items()
                      if limits is None) if side is not None else (),
        )

    def write_failures(self) -> list[WriteFailure]:
        """The files (or servers) that refused writes so far: the trace, the knowledge store,
        the timing file or server, the log files."""
        found = [self.trace.failure]
        parts = self._assembly
        if parts is not None:
            found += parts.logging_and_tracking.failures
            if parts.managing is not None:
                found.append(parts.managing.storage_manager.failure)
            timing = parts.distribution.timing
            found.append(timing.failure if timing is not None else None)
        return [f for f in found if f is not None]
