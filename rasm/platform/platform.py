"""The platform assembled: Core, every building block, the loop, and the managed system.

:class:`Platform` is what ``rasm run`` drives and what :func:`rasm.testing.run_app` uses::

    platform = Platform("examples/hotbox", clock="simulated", seed=1)
    summary = platform.run(duration=60)

The managing side (Core and the building blocks) and the managed side (the app's simulator,
with its probes and effectors) meet only on the transport: the simulator publishes on probe
topics, Telegraf digests them into knowledge, and actions reach the simulator only through the
Trustworthiness Checker publishing on an effector topic.

Each block receives what it works with when it is built (the knowledge store, the rules, the
callables it reports through); none receives the platform.
"""

from __future__ import annotations

import gc
import logging
import math
import random
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rasm.comm import Message, Transport
from rasm.knowledge.base import KnowledgeBase
from rasm.knowledge.storage import Storage
from rasm.logs import RepeatedLogs
from rasm.losses import WriteFailure
from rasm.platform.actions_out import ActionSender, message_types
from rasm.platform.adaptation_manager import AdaptationManager
from rasm.platform.adaptation_orchestrator import AdaptationOrchestrator
from rasm.platform.app_properties import compile_app_properties
from rasm.platform.block import Block, shared_chart
from rasm.platform.calls import CallEffectors, effector_calls
from rasm.platform.communication_manager import CommunicationManager
from rasm.platform.core import Core
from rasm.platform.corrective import corrective_check
from rasm.platform.distribution import Distribution, DistributionHooks
from rasm.platform.external_verdicts import ExternalVerdicts
from rasm.platform.fallback import FallbackSwitch, check_fallback_legitimate
from rasm.platform.knowledge_manager import KnowledgeManager
from rasm.platform.knowledge_store import open_app_knowledge
from rasm.platform.liveness import ManagedSystemWatch, declared_publishers
from rasm.platform.loading import (
    load_app_components,
    load_component,
    load_twin,
    package_name,
)
from rasm.platform.logging_and_tracking import LoggingAndTracking
from rasm.platform.managed_system import ManagedSystem, Simulator
from rasm.platform.manifest import AppManifest
from rasm.platform.modes import ManagedSystemModes, ModesRunner
from rasm.platform.plan_repair import PlanRepair, check_repair_weights
from rasm.platform.ros_wiring import is_ros_transport, ros_options
from rasm.platform.run_options import check_run
from rasm.platform.scheduler import Scheduler
from rasm.platform.simulated_clock import wait_for_own_messages
from rasm.platform.state_dir import default_state_dir
from rasm.platform.state_manager import StateManager
from rasm.platform.storage_manager import (
    LIVE_FLUSH_PERIOD,
    SIMULATED_FLUSH_PERIOD,
    StorageManager,
)
from rasm.platform.summary import RunSummary, bus_refusals, summarise
from rasm.platform.telegraf import Telegraf
from rasm.platform.trace_channels import trace_channels
from rasm.platform.trustworthiness_checker import TrustworthinessChecker
from rasm.platform.trustworthiness_manager import TrustworthinessManager
from rasm.platform.twin_learning import TwinLearning
from rasm.platform.verdicts_out import VerdictPublisher, publishes_verdicts
from rasm.properties.monitor import Monitor, Verdict
from rasm.properties.vacuity import Vacuity
from rasm.statechart import MonotonicClock, SimulatedClock
from rasm.times import elapsed_seconds, from_nanoseconds
from rasm.trace import TraceWriter, open_trace_writer
from rasm.twin import DigitalTwin

if TYPE_CHECKING:
    from rasm.platform.replay import Replay

__all__ = ["Platform", "RunSummary"]

_log = logging.getLogger("rasm.platform")
_SCALARS = (int, float, bool, str)


class Platform:
    """One application's managing system (and, with ``role='all'``, its managed system).

    A property or rule that reads a name no part of the app provides raises
    :class:`~rasm.errors.SourceErrors` here (:func:`rasm.platform.signals.check_app`);
    ``check_signals=False`` runs such an app anyway (its properties are then never judged).
    """

    def __init__(
        self,
        manifest: AppManifest | str | Path,
        *,
        clock: str | None = None,
        seed: int | None = None,
        transport: str | None = None,
        trace: str | Path | None = None,
        trace_max_bytes: int | None = None,
        trace_keep: int = 4,
        role: str = "all",
        knowledge: str | None = None,
        state_dir: str | Path | None = None,
        scenario: dict[str, Any] | None = None,
        components: dict[str, object] | None = None,
        isolate_stages: bool | None = None,
        low_latency: bool = False,
        check_signals: bool = True,
        replay: str | Path | None = None,
    ) -> None:
        manifest, self.clock_kind, self.transport_url = check_run(
            manifest,
            role=role,
            clock=clock,
            transport=transport,
            replay=replay,
            components=components,
            check_signals=check_signals,
        )
        self.manifest = manifest
        self.clock = (
            SimulatedClock() if self.clock_kind == "simulated" else MonotonicClock(running=False)
        )
        self.seed = 0 if seed is None else seed
        self.role = role
        self.managing = role in ("all", "managing")
        self.scheduler = Scheduler(self.clock)
        self.scheduler.on_error = self._job_failed
        self.trace: TraceWriter = open_trace_writer(
            trace, max_bytes=trace_max_bytes, keep=trace_keep
        )
        self.state_dir = Path(state_dir) if state_dir else default_state_dir(manifest)
        self._claims_state_dir = not state_dir
        self.scenario = manifest.scenario if scenario is None else scenario
        self.replay_path = Path(replay) if replay is not None else None
        self.replay: Replay | None = None
        self.ros = is_ros_transport(self.transport_url)
        self.external = ExternalVerdicts(manifest.external_verdicts)  # built with the checker
        self._external_due: float | None = None  # when the sources are looked at next
        self._watch_due: float | None = None  # when the probes' staleness is looked at next
        self.verdicts_out: VerdictPublisher | None = None
        self.knowledge_url = knowledge or manifest.knowledge
        self._component_overrides = components or {}
        # live runs isolate user stages on a worker thread so an overrun can be walked away
        # from; simulations run them inline (deterministic and fast) and discard overruns
        self.isolate_stages = (
            self.clock_kind != "simulated" if isolate_stages is None else isolate_stages
        )
        # the process is the loop's own (`rasm run`): the objects built before the run are moved
        # out of the collector's reach, so a full collection cannot pause the loop for tens of
        # milliseconds (docs/runtime.md)
        self.low_latency = low_latency
        self._gc_frozen = False
        self.on_record: list[Callable[[float, dict[str, Any]], object]] = []
        # every verdict of the online monitors goes to these callables (loop thread); nothing
        # keeps them, so a long run does not grow (the trace file has the records they judge).
        # Append to and remove from this list: the Trustworthiness Checker holds it.
        self.on_verdict: list[Callable[[Verdict], object]] = []
        self.simulator: Simulator | None = None  # the app's simulator (role all or managed)
        self.managed: ManagedSystem | None = None
        self.core: Core | None = None
        self._built = False
        self._started_at = 0.0
        self._timeline_start = 0.0
        # the store a live run's timeline continues from (None: it starts at 0)
        self.restored_from: str | None = None
        self.twin: DigitalTwin | None = None
        self.modes: ModesRunner | None = None  # the app's modes chart, if it has one
        self.fb: FallbackSwitch | None = None  # the fallback switch, when the app declares one
        self.calls: CallEffectors | None = None  # the service and action effectors' calls
        self.learning: TwinLearning | None = None  # the twin's online learning, with a twin
        self.stopped_by: str | None = None  # why the run ended early (request_stop)
        # every failure the loop logs per iteration or record: once in full, then counted
        self.logs = RepeatedLogs()

    # ------------------------------------------------------------------ assembly

    def build(self) -> None:
        """Create every block (not started yet: :meth:`start` asks Core to do that)."""
        storage = self._open_knowledge() if self.managing else None
        try:
            self._build(storage)
        except BaseException:
            # a platform that cannot be built holds nothing: its knowledge file stays usable
            if storage is not None:
                storage.close()
            if self.managing:
                self.kb.close()
            raise

    def _build(self, storage: Storage | None) -> None:
        from rasm.comm import open_transport

        m = self.manifest
        self.dist = Distribution(
            app=m.name,
            role=self.role,
            transport_url=self.transport_url,
            period=m.period,
            timing=m.timing,
            timing_file=self.state_dir / "timing.lp",
            fresh=self.clock_kind == "simulated",
        )
        options = self.dist.transport_options()
        if self.ros:
            options.update(ros_options(m, self.transport_url))
        self.transport: Transport = open_transport(self.transport_url, **options)
        if self.ros:
            # only the declared publisher's messages count (rasm.ros2.transport.restrict)
            for topic, node in declared_publishers(m).items():
                self.transport.restrict(topic, node)
        if self.clock_kind == "simulated" and self.replay_path is None:
            managed_topics = [p.topic for p in m.probes] + [e.topic for e in m.effectors.values()]
            self.scheduler.settle = wait_for_own_messages(self.transport, managed_topics)
        log = m.logging
        self.lt = LoggingAndTracking(
            chart=self._chart("logging_and_tracking"),
            level=logging.getLevelName(log.get("level", "warning").upper()),
            sinks=tuple(log.get("sinks", ("console",))),
            publish=self.transport.publish,
            clock=self.clock,
        )
        self.sm = StateManager(
            chart=self._chart("state_manager"), clock=self.clock, depends_on=("lt",)
        )
        self.cm = CommunicationManager(
            self.transport,
            chart=self._chart("communication_manager"),
            clock=self.clock,
            depends_on=("lt",),
        )
        blocks: list[Block] = [self.lt, self.sm, self.cm]
        if self.managing:
            blocks += self._managing_blocks(storage)
        if self.replay_path is not None:
            from rasm.platform.replay import Recording, Replay

            self.replay = Replay(Recording(self.replay_path, m.probes, m.types))
        elif self.role in ("all", "managed") and m.simulator:
            self.simulator = load_component(
                m.simulator,
                m.folder,
                package=package_name(m),
                kwargs={"scenario": self.scenario, "seed": self.seed},
            )
            self.managed = ManagedSystem(
                self.simulator, period=m.simulator_period, effectors=m.effectors, logs=self.logs
            )
        self.core = Core(blocks, clock=self.clock)
        for block in blocks:
            self.sm.track(block)
            block.on_deadline = self._schedule_block
            block.logs = self.logs
        self._built = True

    @property
    def verdicts_published(self) -> int:
        """How many verdicts went out on the transport (see :mod:`rasm.platform.verdicts_out`)."""
        return 0 if self.verdicts_out is None else self.verdicts_out.published

    @property
    def timeline_start(self) -> float:
        """Where this run's clock starts: 0, or after the newest sample a live run restored
        from :attr:`restored_from`."""
        return self._timeline_start

    def _open_knowledge(self) -> Storage | None:
        """Open (and restore) the knowledge store; returns its storage, if persistent."""
        opened = open_app_knowledge(
            self.manifest,
            self.knowledge_url,
            state_dir=self.state_dir,
            simulated=self.clock_kind == "simulated",
            claim=self._claims_state_dir,
        )
        self.kb: KnowledgeBase = opened.store
        self.restored_from = opened.restored_from
        self._timeline_start = opened.timeline_start
        return opened.storage

    def _managing_blocks(self, storage: Storage | None) -> list[Block]:
        from rasm.rules import RuleSet

        m, clock = self.manifest, self.clock
        self.km = KnowledgeManager(
            self.kb, chart=self._chart("knowledge_manager"), clock=clock, depends_on=("lt",)
        )
        self.stom = StorageManager(
            storage,
            flush_period=(
                SIMULATED_FLUSH_PERIOD if self.clock_kind == "simulated" else LIVE_FLUSH_PERIOD
            ),
            chart=self._chart("storage_manager"),
            clock=clock,
            depends_on=("km",),
        )
        if storage is not None:
            # the Storage Manager buffers every update for its storage; without one it has
            # nothing to do with them, so no subscriber call per value stored
            self.kb.subscribe_batches(self.stom.register_knowledge_updates)
        self.tg = Telegraf(
            m.probes,
            self._register,
            timeline=self._timeline,
            chart=self._chart("telegraf"),
            clock=clock,
            depends_on=("km", "cm"),
        )
        self.rules = [RuleSet.load(path, plan_fields=m.plan_fields) for path in m.rules]
        check_repair_weights(m, self.rules)
        monitors: list[Monitor] = compile_app_properties(m)
        vacuity = [Vacuity(monitor.spec) for monitor in monitors]  # before external verdicts
        # who may speak for an external verdict: the signer of RASM_ACTION_KEY over MQTT, the
        # declared publisher over ROS 2 (the transport delivers its messages alone)
        self.external = ExternalVerdicts(
            m.external_verdicts,
            check=self.dist.verdict_check(
                {name: source.topic for name, source in m.external_verdicts.items()}
            ),
            alive=getattr(self.transport, "node_alive", None) if self.ros else None,
            logs=self.logs,
        )
        if self.external.sources:
            monitors.append(self.external)
        # is the managed system there, and which readings are live (probe staleness, the ROS
        # graph, presence)
        self.watch = ManagedSystemWatch(
            m.probes,
            clock=self.scheduler.now,
            presence=lambda: self.dist.managed_online,
            alive=getattr(self.transport, "node_alive", None) if self.ros else None,
            on_change=self._managed_system_changed,
            on_stale=lambda stale: self.tc.set_stale(stale, self.scheduler.now()),
        )
        # the managed system's modes chart, stepped by every batch of values stored
        if m.modes:
            self.modes = ModesRunner(
                ManagedSystemModes(shared_chart(m.modes), self.kb),
                register_values=self.km.register_values,
                refused=self._refused,
                emit=self._emit,
                at=self.scheduler.at,
                clock=clock,
            )
        # an MCAP trace's typed channels: effector messages and verdicts as ROS 2 messages
        channels = trace_channels(self.trace, m, self.scheduler.now)
        # service and action effectors: calls off the loop, their outcomes back as jobs
        self.calls = None if self.replay_path is not None else effector_calls(
            m.effectors, self.transport, submit=self.scheduler.submit, register=self._register,
            emit=self._emit, now=self.scheduler.now,
            veto_reason=lambda name, verdict: self.tm.veto_reason(name, verdict),
            logs=self.logs,
        )
        self.tc = TrustworthinessChecker(
            chart=self._chart("trustworthiness_checker"),
            monitors=monitors,
            effectors=m.effectors,
            send=ActionSender(
                m,
                publish=self.cm.publish_message,
                seal=self.dist.seal,
                emit=self._emit,
                clock=clock,
                replaying=self.replay_path is not None,
                calls=self.calls,
                sent=channels.effector_message if channels is not None else None,
            ).send,
            mode_of=self._managed_system_mode,
            online=self.watch.online,
            observers=self.on_verdict,  # the list itself: observers added later are called
            vacuity=vacuity,
            clock=clock,
            depends_on=("sm", "cm"),
        )
        self.tm = TrustworthinessManager(
            chart=self._chart("trustworthiness_manager"),
            rules=self.rules,
            # an external verdict is a veto source by being declared
            veto_properties=tuple(dict.fromkeys((*m.veto_properties, *self.external.sources))),
            checker=self.tc,
            context=self.kb.snapshot,
            emit=self._emit,
            clock=clock,
            depends_on=("sm", "km", "tc"),
        )
        if self.calls is not None:  # a goal is cancelled when a veto closes, or on fallback
            self.calls.veto_properties = self.tm.veto_properties
            self.on_verdict.append(self.calls.observe_verdict)
            self.on_record.append(self.calls.observe_record)
        self.am = AdaptationManager(
            self.tm,
            self.tc,
            chart=self._chart("adaptation_manager"),
            clock=clock,
            depends_on=("tm", "tc"),
        )
        components, twin = load_app_components(m, self._component_overrides)
        self.twin = load_twin(twin, self.kb.read_knowledge("twin_model"))
        if self.twin is not None:
            self.learning = TwinLearning(
                self.twin,
                knowledge=self.kb,
                store=self.km.register_knowledge,
                register=self._register,
                emit=self._emit,
                refused=self._refused,
                drift=lambda: self.scheduler.submit(lambda: self.ao.send("drift_detected")),
                logs=self.logs,
            )
        if m.corrective:
            self.tm.corrective = corrective_check(m, self.twin)
        self.ao = AdaptationOrchestrator(
            chart=self._chart("adaptation_orchestrator"),
            twin=self.twin,
            twin_properties=[(str(p), p.read_text(encoding="utf-8")) for p in m.properties],
            twin_horizon=m.twin_horizon,
            twin_dt=m.twin_dt,
            components=components,
            knowledge=self.kb,
            rules=self.rules,
            register=self._register,
            emit=self._emit,
            am=self.am,
            tm=self.tm,
            sm=self.sm,
            stage_budget=m.stage_budget,
            # live plan ids never repeat across runs; a simulated run's stay reproducible
            plan_prefix="" if self.clock_kind == "simulated" else f"{self.dist.run}-",
            max_replans=m.max_replans,
            max_actions=m.max_actions,
            repair=PlanRepair(m, self.rules).repair if m.repair else None,
            isolate_stages=self.isolate_stages,
            clock=clock,
            depends_on=("km", "am", "tm", "tc", "sm", "tg"),
        )
        self.trace.observers.append(self.tc.observe)
        if channels is not None:
            self.tc.batch_observers.append(channels.verdicts)
        blocks: list[Block] = [self.km, self.stom, self.tg, self.tc, self.tm, self.am, self.ao]
        if m.fallback is not None:
            blocks.append(self._fallback_switch())
        if publishes_verdicts(m, self.transport_url, replaying=self.replay_path is not None):
            names = [n for mon in monitors if mon is not self.external for n in mon.properties]
            self.verdicts_out = VerdictPublisher(
                self.transport, names, ros=self.ros, skip=self.external.sources, logs=self.logs
            )
            self.tc.batch_observers.append(self.verdicts_out.publish_all)
        return blocks

    def _fallback_switch(self) -> FallbackSwitch:
        """The fallback switch, once z3 proved every fallback action legitimate in every context
        the rules admit (else the app is refused, at the action in app.yaml)."""
        m = self.manifest
        check_fallback_legitimate(m, self.rules)
        self.fb = FallbackSwitch(
            spec=m.fallback,
            am=self.am,
            tm=self.tm,
            online=self.watch.online,
            stats=lambda: self.ao.stats,
            emit=self._emit,
            veto_properties=self.tm.veto_properties,
            submit=self.scheduler.submit,
            plan_prefix="" if self.clock_kind == "simulated" else f"{self.dist.run}-",
            chart=self._chart("fallback"),
            clock=self.clock,
            depends_on=("am", "tm", "ao"),
        )
        self.am.hold = self.fb
        self.on_verdict.append(self.fb.watch_verdict)
        return self.fb

    def _tick(self) -> None:
        """One loop period: the managed system's witnesses are read (the ROS graph has no
        deadline to wake on), the fallback switch reads its triggers, then the loop runs."""
        self.watch.evaluate()
        if self.fb is not None:
            self.fb.evaluate()
        self.ao.orchestration_loop()

    def _chart(self, name: str) -> Path | None:
        """The app's replacement for platform chart ``name`` (manifest ``statecharts:``)."""
        return self.manifest.statecharts.get(name)

    # ------------------------------------------------------------------ data paths

    def _register(self, values: dict[str, Any], time: float) -> None:
        """Store values in knowledge (one trace record for the batch, with the twin's residual
        when they were the twin's inputs)."""
        # one call for the batch: a bad value is refused on its own, logged and dropped
        refused = self.km.register_values(values, time)
        for key, exc in refused.items():
            self._refused(key, values[key], exc)
        # the trace record has the scalars stored
        stored = {
            key: value
            for key, value in values.items()
            if key not in refused and isinstance(value, _SCALARS)
        }
        if self.learning is not None and self.learning.reads(values):
            self.learning.observe(time, stored)
        if self.modes is not None:
            # a change of the managed system's modes goes in the record that caused it
            change = self.modes.observe(
                time, {key: value for key, value in values.items() if key not in refused}
            )
            if change:
                stored.update(change)
        if stored:
            self._emit(time, stored)

    def _refused(self, key: str, value: object, exc: Exception) -> None:
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

    def _emit(self, time: float, record: dict[str, Any]) -> None:
        self.trace.emit(time, record)
        for observer in self.on_record:
            observer(time, record)

    def _managed_system_mode(self) -> str | frozenset[str] | None:
        """The managed system's mode, by which an effector is applicable or not: the active
        states of the modes chart, or the mode signal's value."""
        if self.modes is not None:
            return self.modes.mode
        signal = self.manifest.mode_signal
        return self.kb.read_knowledge(signal) if signal else None

    @property
    def transport_store(self) -> Any:
        """The app's ROS 2 types (the standard interfaces when it has none of its own)."""
        return message_types(self.manifest)

    def _timeline(self, stamp_ns: int) -> float:
        """A message's ``header.stamp`` (wall-clock nanoseconds) on the platform's timeline:
        on the wall clock, where that wall time falls; a replay's timeline starts at the
        recording's first log time (exact to the nanosecond); a simulated run takes stamps as
        they are."""
        if self.clock_kind == "wall":
            return self.dist.platform_time(stamp_ns / 10**9)
        origin = self.replay.origin_ns if self.replay is not None else 0
        return from_nanoseconds(stamp_ns - origin)

    def _on_external_verdict(self, name: str, message: Message) -> None:
        # on the transport's thread: the verdict is taken on the loop's, at the loop's time
        payload = message.payload
        self.scheduler.submit(lambda: self._take_external(name, payload))

    def _take_external(self, name: str, payload: Any) -> None:
        verdict = self.external.receive(name, payload, self.scheduler.now())
        if verdict is not None:
            self.tc.take(verdict)
        self._external_wake()

    def _external_wake(self) -> None:
        """Have the external sources looked at when time alone changes one (a false leaving
        its window, a source going stale), not only at the next record."""
        now = self.scheduler.now()
        due = self.external.next_change(now)
        if due is not None and (self._external_due is None or due < self._external_due
                                or self._external_due <= now):
            self._external_due = due
            self.scheduler.at(due, self._external_tick)

    def _external_tick(self) -> None:
        self._external_due = None
        for verdict in self.external.step(self.scheduler.now(), {}):
            self.tc.take(verdict)
        self._external_wake()

    def _on_probe(self, message: Message) -> None:
        # delivered on the transport's thread: digested on the loop's, at the loop's time then
        topic, payload = message.topic, message.payload
        self.scheduler.submit(lambda: self._digest(topic, payload, self.scheduler.now()))

    def _digest(self, topic: str, payload: Any, time: float) -> dict[str, Any]:
        """One probe message into knowledge; a probe that stored values is live."""
        stored = self.tg.digest(topic, payload, time)
        if stored:
            self.watch.heard(topic, time)
            if self._watch_due is None:
                self._watch_schedule()
        return stored

    def _watch_schedule(self) -> None:
        """Have the managed system's witnesses read when a probe would go stale (one wake
        pending at a time; a probe heard meanwhile moves the next one on)."""
        due = self.watch.next_deadline()
        self._watch_due = due
        if due is not None:
            self.scheduler.at(due, self._watch_tick)

    def _watch_tick(self) -> None:
        self.watch.evaluate()
        self._watch_schedule()

    def _managed_system_changed(self, lost: bool, why: str) -> None:
        """The managed system is lost or back (loop thread): traced, told to the orchestrator,
        and the fallback's triggers read at once."""
        event = "managed_system_lost" if lost else "managed_system_back"
        (_log.warning if lost else _log.info)("%s: %s", event, why or "every witness is back")
        self._emit(self.scheduler.now(), {"explanation": f"{event}: {why}" if lost else event})
        if self.ao.mode == "initialized":
            self.ao.send(event)
        if self.fb is not None:
            self.fb.evaluate()

    def _schedule_block(self, block: Block, due: float) -> None:
        self.scheduler.at(due, block.wake)

    def _job_failed(self, exc: BaseException) -> None:
        what = f"a loop job failed: {type(exc).__name__}: {exc}"
        self.logs.log(_log, logging.ERROR, what, exc_info=exc)

    def _hooks(self) -> DistributionHooks:
        """What presence and updates from the network act on (called on a transport thread,
        so what touches the loop is handed to the loop thread)."""

        def managed_system(event: str) -> None:
            # presence is one witness of the managed system's: the watch says what changed
            self.scheduler.submit(self.watch.evaluate)

        def add_monitor(monitor: Monitor) -> None:
            self.scheduler.submit(lambda: self.tc.add_monitor(monitor))

        return DistributionHooks(
            managed_system=managed_system,
            node=self.sm.set_node,
            rules=self.rules,
            add_monitor=add_monitor,
        )

    # ------------------------------------------------------------------ running

    def start(self) -> None:
        """Build (if needed) and start every block in dependency order, then wire the loop."""
        if not self._built:
            self.build()
        assert self.core is not None
        if isinstance(self.clock, MonotonicClock):
            # building took time; the run's timeline starts now (or after restored knowledge)
            self.clock.start_at(self._timeline_start)
        elif self.replay is not None and self.replay.first_time is not None:
            # a replay runs on the recording's time: its trace has the recording's times
            self.clock.time = max(self.clock.time, self.replay.first_time)
        self.core.initialize()
        if self.managing and self.modes is not None:
            self.modes.start(self.clock.time)
        if self.low_latency and not self._gc_frozen:
            gc.collect()
            gc.freeze()
            self._gc_frozen = True
        self._started_at = self.clock.time
        self.dist.start(
            self.transport,
            self.trace.observers,
            clock_time=self.clock.time,
            hooks=self._hooks() if self.managing else None,
        )
        m = self.manifest
        if self.replay is not None:
            self.replay.start(self.scheduler, self._digest, tail=m.period)
        elif self.managing:
            for probe in m.probes:
                self.cm.subscribe(probe.topic, self._on_probe)
        if self.managing:
            for name, source in m.external_verdicts.items():
                self.cm.subscribe(
                    source.topic,
                    lambda message, name=name: self._on_external_verdict(name, message),
                )
            # a loop that overran skips the iterations it missed (Scheduler.missed)
            self.scheduler.every(
                m.period, self._tick, start=self.clock.time + m.period, skip_missed=True
            )
            self.watch.begin()
            self._watch_tick()
        if self.managed is not None:
            self.managed.start(
                self.cm, self.scheduler, started_at=self._started_at, gate=self.dist.effector_gate
            )

    def run(self, duration: float | None = None) -> RunSummary:
        """Start, run for ``duration`` seconds of the platform's clock, stop, summarise.

        :meth:`request_stop` ends the run early, in the same order as a normal end.
        """
        random.seed(self.seed)
        self.start()
        length = duration if duration is not None else self.manifest.duration
        if self.replay is not None and duration is None:
            length = math.inf  # to the end of the recording (the replay stops the scheduler)
        try:
            self.scheduler.run_until(self._started_at + length if length < math.inf else None)
            # exactly: a replay's clock reads epoch seconds, where a float difference has noise
            ran = min(length, elapsed_seconds(self._started_at, self.clock.time))
        finally:
            self.stop()
        if ran >= length:  # a stop asked for as the run ended anyway changed nothing
            self.stopped_by = None
        if self.managing:
            self.tc.finish()  # the verdicts still open go to the observers too
        self.trace.close()
        return self.summary(ran)

    def request_stop(self, reason: str = "a stop request") -> None:
        """End :meth:`run` after the job in hand: knowledge persisted, trace closed, summary
        made, as at a normal end. Safe from another thread and from a signal handler (it only
        sets a flag the loop reads); a request before the run starts makes it end at once."""
        self.stopped_by = reason
        self.scheduler.stop()

    def stop(self) -> None:
        if self.calls is not None:  # goals cancelled while the transport is still there
            self.calls.close()
        self.logs.flush()  # the counts still unreported, while the log sinks are attached
        if self._built:
            self.dist.stop()
        if self.core is not None and self.core.mode != "terminated":
            self.core.deinitialize()
        self.trace.flush()
        if self._gc_frozen:
            gc.unfreeze()
            self._gc_frozen = False

    def summary(self, duration: float) -> RunSummary:
        """The run so far, read from the blocks (nothing is changed)."""
        return summarise(
            self.manifest.name,
            self.clock_kind,
            duration,
            state=self.sm,
            checker=self.tc if self.managing else None,
            orchestrator=self.ao if self.managing else None,
            telegraf=self.tg if self.managing else None,
            trace=self.trace,
            bus=bus_refusals(
                self.transport, self.dist, sum(self.external.refused.values())
            ),
            missed_iterations=self.scheduler.missed,
            stopped_by=self.stopped_by,
            repeated_failures=self.logs.totals,
            fallback=self.fb,
            write_failures=self.write_failures(),
            damage=self.replay.damage if self.replay is not None else [],
            calls=self.calls.counts if self.calls is not None else {},
            role=self.role,
            managed=self.managed,
            off=tuple(name for name, limits in self.manifest.platform_properties.items()
                      if limits is None) if self.managing else (),
        )

    def write_failures(self) -> list[WriteFailure]:
        """The files (or servers) that refused writes so far: the trace, the knowledge store,
        the timing file or server, the log files."""
        found = [self.trace.failure]
        if self._built:
            found += self.lt.failures
            if self.managing:
                found.append(self.stom.failure)
            timing = self.dist.timing
            found.append(timing.failure if timing is not None else None)
        return [f for f in found if f is not None]
