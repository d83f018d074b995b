"""The assembly: every part of one platform process, built by one function, :func:`assemble`.

Read :func:`assemble` top to bottom to see where each building block is made and what it is
given; nothing is handed to a block after it is made, and no block holds the platform. What the
blocks report through (values to store, trace records, the managed system's changes) are the
platform's data paths, :class:`DataPaths`, which :class:`~rasm.platform.platform.Platform`
provides and which this module only passes on. The order is the order of need: a block is made
after the blocks it works with, so the dependencies Core starts them by are plain references.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from rasm.comm import Transport, open_transport
from rasm.logs import RepeatedLogs
from rasm.platform.action_outcome import Emit
from rasm.platform.actions_out import ActionSender
from rasm.platform.adaptation_manager import AdaptationManager
from rasm.platform.adaptation_orchestrator import AdaptationOrchestrator
from rasm.platform.app_properties import compile_app_properties
from rasm.platform.block import Block, shared_chart
from rasm.platform.calls import CallEffectors, effector_calls
from rasm.platform.communication_manager import CommunicationManager
from rasm.platform.core import Core
from rasm.platform.corrective import corrective_check
from rasm.platform.distribution import Distribution
from rasm.platform.external_verdicts import ExternalVerdicts
from rasm.platform.fallback import FallbackHold, FallbackSwitch, check_fallback_legitimate
from rasm.platform.knowledge_manager import KnowledgeManager
from rasm.platform.knowledge_store import AppKnowledge, open_app_knowledge
from rasm.platform.liveness import ManagedSystemWatch, declared_publishers
from rasm.platform.loading import load_app_components, load_component, load_twin, package_name
from rasm.platform.logging_and_tracking import LoggingAndTracking
from rasm.platform.managed_system import ManagedSystem
from rasm.platform.manifest import AppManifest
from rasm.platform.modes import ManagedSystemModes, ModesRunner
from rasm.platform.plan_repair import PlanRepair, check_repair_weights
from rasm.platform.ros_wiring import is_ros_transport, ros_options
from rasm.platform.run_options import Clock, RunOptions
from rasm.platform.scheduler import Scheduler
from rasm.platform.simulated_clock import wait_for_own_messages
from rasm.platform.state_manager import StateManager
from rasm.platform.storage_manager import (
    LIVE_FLUSH_PERIOD,
    SIMULATED_FLUSH_PERIOD,
    StorageManager,
)
from rasm.platform.telegraf import Telegraf
from rasm.platform.trace_channels import trace_channels
from rasm.platform.trustworthiness_checker import TrustworthinessChecker
from rasm.platform.trustworthiness_manager import TrustworthinessManager, verdict_veto_reason
from rasm.platform.twin_learning import TwinLearning
from rasm.platform.verdicts_out import VerdictPublisher, publishes_verdicts
from rasm.properties.monitor import Monitor, Verdict
from rasm.properties.vacuity import Vacuity
from rasm.trace import TraceWriter

if TYPE_CHECKING:
    from sismic.clock import Clock as ChartClock

    from rasm.platform.replay import Replay
    from rasm.rules import RuleSet
    from rasm.twin import DigitalTwin

__all__ = ["Assembly", "DataPaths", "ManagingSide", "assemble"]


class DataPaths(Protocol):
    """The platform's data paths, which the blocks report through (all on the loop's thread)."""

    on_verdict: list[Callable[[Verdict], object]]
    """Called with every verdict of the online monitors (the list itself is handed on)."""

    on_record: list[Emit]
    """Called with every trace record once it is written."""

    def register_values(self, values: dict[str, Any], time: float) -> None:
        """Store values in knowledge, and trace them."""

    def emit(self, time: float, record: dict[str, Any]) -> None:
        """Write one trace record."""

    def write_robustness(self, values: dict[str, float], time: float) -> None:
        """Store the properties' robustness (``robustness_<property>``) in knowledge, and
        trace it."""

    def refused(self, key: str, value: object, exc: Exception) -> None:
        """Say that knowledge refused ``value`` for ``key``."""

    def timeline(self, stamp_ns: int) -> float:
        """A message's ``header.stamp`` (integer nanoseconds) on the platform's timeline."""

    def managed_system_mode(self) -> str | frozenset[str] | None:
        """The managed system's mode, by which an effector is applicable or not."""

    def managed_system_changed(self, lost: bool, why: str) -> None:
        """The managed system is lost or back."""

    def stale(self, signals: dict[str, str]) -> None:
        """These signals (name -> why) are stale from now on, the others live."""


@dataclass(frozen=True)
class ManagingSide:
    """The managing side of a process (role ``all`` or ``managing``): knowledge, the loop's
    building blocks, and what they read."""

    knowledge: AppKnowledge
    knowledge_manager: KnowledgeManager
    storage_manager: StorageManager
    telegraf: Telegraf
    rules: list[RuleSet]
    external_verdicts: ExternalVerdicts
    watch: ManagedSystemWatch  # is the managed system there, which readings are live
    modes: ModesRunner | None  # the managed system's modes chart, if the app has one
    verdicts_out: VerdictPublisher | None
    call_effectors: CallEffectors | None  # the calls of service and action effectors, if any
    trustworthiness_checker: TrustworthinessChecker
    twin: DigitalTwin | None
    trustworthiness_manager: TrustworthinessManager
    fallback_hold: FallbackHold | None  # with a fallback: what holds the loop's actions back
    adaptation_manager: AdaptationManager
    adaptation_orchestrator: AdaptationOrchestrator
    twin_learning: TwinLearning | None
    fallback_switch: FallbackSwitch | None


@dataclass(frozen=True)
class Assembly:
    """Every part of one platform process, as :func:`assemble` built it."""

    distribution: Distribution
    transport: Transport
    logging_and_tracking: LoggingAndTracking
    state_manager: StateManager
    communication_manager: CommunicationManager
    managing: ManagingSide | None  # None in a managed-only process
    replay: Replay | None  # a replay's recording, which stands for the managed system
    managed_system: ManagedSystem | None  # the app's simulator, stepped here (role all/managed)
    core: Core  # starts the blocks in dependency order


def assemble(
    manifest: AppManifest,
    options: RunOptions,
    *,
    clock_kind: Clock,
    transport_url: str,
    clock: ChartClock,
    scheduler: Scheduler,
    trace: TraceWriter,
    state_dir: Path,
    logs: RepeatedLogs,
    paths: DataPaths,
) -> Assembly:
    """Build every part of one process (nothing is started: Core does that).

    ``clock_kind`` and ``transport_url`` are the run's, as :func:`check_run` settled them;
    ``clock``, ``scheduler``, ``trace`` and ``logs`` are the platform's, shared by every block.
    A process that cannot be built holds nothing: its knowledge store is closed again.
    """
    knowledge = None
    if options.role.manages:
        knowledge = open_app_knowledge(
            manifest,
            options.knowledge or manifest.knowledge,
            state_dir=state_dir,
            simulated=clock_kind is Clock.SIMULATED,
            claim=options.state_dir is None,
        )
    try:
        return _assemble(
            manifest, options, knowledge, clock_kind=clock_kind, transport_url=transport_url,
            clock=clock, scheduler=scheduler, trace=trace, state_dir=state_dir, logs=logs,
            paths=paths,
        )
    except BaseException:
        if knowledge is not None:  # its file stays usable
            if knowledge.storage is not None:
                knowledge.storage.close()
            knowledge.store.close()
        raise


def _assemble(
    m: AppManifest,
    options: RunOptions,
    knowledge: AppKnowledge | None,
    *,
    clock_kind: Clock,
    transport_url: str,
    clock: ChartClock,
    scheduler: Scheduler,
    trace: TraceWriter,
    state_dir: Path,
    logs: RepeatedLogs,
    paths: DataPaths,
) -> Assembly:
    from rasm.rules import RuleSet

    simulated = clock_kind is Clock.SIMULATED
    replaying = options.replay is not None
    ros = is_ros_transport(transport_url)

    # ---------------------------------------------------------------- the network
    distribution = Distribution(
        app=m.name,
        role=options.role,
        transport_url=transport_url,
        period=m.period,
        timing=m.timing,
        timing_file=state_dir / "timing.lp",
        fresh=simulated,
    )
    transport_options = distribution.transport_options()
    if ros:
        transport_options.update(ros_options(m, transport_url))
    transport = open_transport(transport_url, **transport_options)
    if ros:
        # only the declared publisher's messages count (rasm.ros2.transport.restrict)
        for topic, node in declared_publishers(m).items():
            transport.restrict(topic, node)
    if simulated and not replaying:
        managed_topics = [p.topic for p in m.probes] + [e.topic for e in m.effectors.values()]
        scheduler.settle = wait_for_own_messages(transport, managed_topics)

    def schedule(block: Block, due: float) -> None:
        scheduler.at(due, block.wake)

    def common(chart: str) -> dict[str, Any]:
        """What every block is made with: the clock, the repeated-failure log, the wake-up of
        its chart's timers, and the app's replacement for its chart (``statecharts:``)."""
        return {"clock": clock, "logs": logs, "on_deadline": schedule,
                "chart": m.statecharts.get(chart)}

    # ---------------------------------------------------------------- every process's blocks
    log = m.logging
    logging_and_tracking = LoggingAndTracking(
        level=logging.getLevelName(log.get("level", "warning").upper()),
        sinks=tuple(log.get("sinks", ("console",))),
        publish=transport.publish,
        **common("logging_and_tracking"),
    )
    state_manager = StateManager(depends_on=(logging_and_tracking,), **common("state_manager"))
    communication_manager = CommunicationManager(
        transport, depends_on=(logging_and_tracking,), **common("communication_manager")
    )
    blocks: list[Block] = [logging_and_tracking, state_manager, communication_manager]

    # ---------------------------------------------------------------- the managing side
    managing = None
    if knowledge is not None:
        store = knowledge.store
        knowledge_manager = KnowledgeManager(
            store, depends_on=(logging_and_tracking,), **common("knowledge_manager")
        )
        storage_manager = StorageManager(
            knowledge.storage,
            flush_period=SIMULATED_FLUSH_PERIOD if simulated else LIVE_FLUSH_PERIOD,
            depends_on=(knowledge_manager,),
            **common("storage_manager"),
        )
        if knowledge.storage is not None:
            # the Storage Manager buffers every update for its storage; without one it has
            # nothing to do with them, so no subscriber call per value stored
            store.subscribe_batches(storage_manager.register_knowledge_updates)
        telegraf = Telegraf(
            m.probes,
            paths.register_values,
            timeline=paths.timeline,
            depends_on=(knowledge_manager, communication_manager),
            **common("telegraf"),
        )
        rules = [RuleSet.load(path, plan_fields=m.plan_fields) for path in m.rules]
        check_repair_weights(m, rules)
        monitors: list[Monitor] = compile_app_properties(m)
        vacuity = [Vacuity(monitor.spec) for monitor in monitors]  # before external verdicts
        # who may speak for an external verdict: the signer of RASM_ACTION_KEY over MQTT, the
        # declared publisher over ROS 2 (the transport delivers its messages alone)
        alive = getattr(transport, "node_alive", None) if ros else None
        external = ExternalVerdicts(
            m.external_verdicts,
            check=distribution.verdict_check(
                {name: source.topic for name, source in m.external_verdicts.items()}
            ),
            alive=alive,
            logs=logs,
        )
        published = [name for monitor in monitors for name in monitor.properties]
        if external.sources:
            monitors.append(external)
        # is the managed system there, and which readings are live (probe staleness, the ROS
        # graph, presence)
        watch = ManagedSystemWatch(
            m.probes,
            clock=scheduler.now,
            presence=lambda: distribution.managed_online,
            alive=alive,
            on_change=paths.managed_system_changed,
            on_stale=paths.stale,
        )
        # the managed system's modes chart, stepped by every batch of values stored
        modes = None
        if m.modes:
            modes = ModesRunner(
                ManagedSystemModes(shared_chart(m.modes), store),
                register_values=knowledge_manager.register_values,
                refused=paths.refused,
                emit=paths.emit,
                at=scheduler.at,
                clock=clock,
            )
        verdicts_out = None
        if publishes_verdicts(m, transport_url, replaying=replaying):
            verdicts_out = VerdictPublisher(
                transport, published, ros=ros, skip=external.sources, logs=logs
            )
        # an external verdict is a veto source by being declared
        veto_properties = tuple(dict.fromkeys((*m.veto_properties, *external.sources)))
        # an MCAP trace's typed channels: effector messages and verdicts as ROS 2 messages
        channels = trace_channels(trace, m, scheduler.now)
        # service and action effectors: calls off the loop, their outcomes back as loop jobs; a
        # running goal is cancelled when a veto property stops vouching (its verdict alone
        # says so) or the fallback engages (its record says so). A replay calls nothing.
        call_effectors = None if replaying else effector_calls(
            m.effectors,
            transport,
            submit=scheduler.submit,
            register=paths.register_values,
            emit=paths.emit,
            now=scheduler.now,
            veto_properties=veto_properties,
            veto_reason=verdict_veto_reason,
            logs=logs,
        )
        if call_effectors is not None:
            paths.on_verdict.append(call_effectors.observe_verdict)
            paths.on_record.append(call_effectors.observe_record)
        batch_observers: list[Callable[[list[Verdict]], object]] = []
        if channels is not None:
            batch_observers.append(channels.verdicts)
        if verdicts_out is not None:
            batch_observers.append(verdicts_out.publish_all)
        trustworthiness_checker = TrustworthinessChecker(
            monitors=monitors,
            effectors=m.effectors,
            send=ActionSender(
                m,
                publish=communication_manager.publish_message,
                seal=distribution.seal,
                emit=paths.emit,
                clock=clock,
                replaying=replaying,
                calls=call_effectors,
                sent=channels.effector_message if channels is not None else None,
            ).send,
            mode_of=paths.managed_system_mode,
            online=watch.online,
            observers=paths.on_verdict,  # the list itself: observers added later are called
            batch_observers=batch_observers,
            vacuity=vacuity,
            write_robustness=paths.write_robustness,
            depends_on=(state_manager, communication_manager),
            **common("trustworthiness_checker"),
        )
        trace.observers.append(trustworthiness_checker.observe)  # it judges every record
        # the twin, and with it the corrective check, come before the Trustworthiness Manager
        components, twin_component = load_app_components(m, options.components or {})
        twin = load_twin(twin_component, store.read_knowledge("twin_model"))
        trustworthiness_manager = TrustworthinessManager(
            rules=rules,
            veto_properties=veto_properties,
            checker=trustworthiness_checker,
            context=store.snapshot,
            corrective=corrective_check(m, twin) if m.corrective else None,
            emit=paths.emit,
            depends_on=(state_manager, knowledge_manager, trustworthiness_checker),
            **common("trustworthiness_manager"),
        )
        # what the fallback switch holds back, given to the Adaptation Manager when it is made
        fallback_hold = FallbackHold(trustworthiness_manager) if m.fallback is not None else None
        adaptation_manager = AdaptationManager(
            trustworthiness_manager,
            trustworthiness_checker,
            hold=fallback_hold,
            depends_on=(trustworthiness_manager, trustworthiness_checker),
            **common("adaptation_manager"),
        )
        # live plan ids never repeat across runs; a simulated run's stay reproducible
        plan_prefix = "" if simulated else f"{distribution.run}-"
        adaptation_orchestrator = AdaptationOrchestrator(
            twin=twin,
            twin_properties=[(str(p), p.read_text(encoding="utf-8")) for p in m.properties],
            twin_horizon=m.twin_horizon,
            twin_dt=m.twin_dt,
            components=components,
            knowledge=store,
            rules=rules,
            register=paths.register_values,
            emit=paths.emit,
            adapter=adaptation_manager,
            plans=trustworthiness_manager,
            timer=state_manager,
            stage_budget=m.stage_budget,
            plan_prefix=plan_prefix,
            max_replans=m.max_replans,
            max_actions=m.max_actions,
            repair=PlanRepair(m, rules).repair if m.repair else None,
            # a live run isolates user stages on a worker thread so an overrun can be walked
            # away from; a simulation runs them inline (deterministic and fast)
            isolate_stages=(
                not simulated if options.isolate_stages is None else options.isolate_stages
            ),
            depends_on=(
                knowledge_manager, adaptation_manager, trustworthiness_manager,
                trustworthiness_checker, state_manager, telegraf,
            ),
            **common("adaptation_orchestrator"),
        )
        twin_learning = None
        if twin is not None:
            twin_learning = TwinLearning(
                twin,
                knowledge=store,
                store=knowledge_manager.register_knowledge,
                register=paths.register_values,
                emit=paths.emit,
                refused=paths.refused,
                drift=lambda: scheduler.submit(
                    lambda: adaptation_orchestrator.send("drift_detected")
                ),
                logs=logs,
            )
        blocks += [knowledge_manager, storage_manager, telegraf, trustworthiness_checker,
                   trustworthiness_manager, adaptation_manager, adaptation_orchestrator]
        fallback_switch = None
        if m.fallback is not None and fallback_hold is not None:
            # refused (at the action in app.yaml) unless z3 proved every fallback action
            # legitimate in every context the rules admit
            check_fallback_legitimate(m, rules)
            fallback_switch = FallbackSwitch(
                spec=m.fallback,
                hold=fallback_hold,
                adapter=adaptation_manager,
                plans=trustworthiness_manager,
                vetoes=trustworthiness_manager,
                online=watch.online,
                stats=adaptation_orchestrator.stats,
                emit=paths.emit,
                veto_properties=trustworthiness_manager.veto_properties,
                submit=scheduler.submit,
                plan_prefix=plan_prefix,
                depends_on=(adaptation_manager, trustworthiness_manager, adaptation_orchestrator),
                **common("fallback"),
            )
            paths.on_verdict.append(fallback_switch.watch_verdict)
            blocks.append(fallback_switch)
        managing = ManagingSide(
            knowledge=knowledge,
            knowledge_manager=knowledge_manager,
            storage_manager=storage_manager,
            telegraf=telegraf,
            rules=rules,
            external_verdicts=external,
            watch=watch,
            modes=modes,
            verdicts_out=verdicts_out,
            call_effectors=call_effectors,
            trustworthiness_checker=trustworthiness_checker,
            twin=twin,
            trustworthiness_manager=trustworthiness_manager,
            fallback_hold=fallback_hold,
            adaptation_manager=adaptation_manager,
            adaptation_orchestrator=adaptation_orchestrator,
            twin_learning=twin_learning,
            fallback_switch=fallback_switch,
        )

    # ---------------------------------------------------------------- the managed side
    replay = None
    managed_system = None
    if replaying:
        from rasm.platform.replay import Recording, Replay

        replay = Replay(Recording(Path(options.replay), m.probes, m.types))
    elif options.role.runs_managed_system and m.simulator:
        simulator = load_component(
            m.simulator,
            m.folder,
            package=package_name(m),
            kwargs={"scenario": options.scenario_of(m), "seed": options.seed},
        )
        managed_system = ManagedSystem(
            simulator, period=m.simulator_period, effectors=m.effectors, logs=logs
        )

    core = Core(blocks, clock=clock)
    for block in blocks:
        state_manager.track(block)
    return Assembly(
        distribution=distribution,
        transport=transport,
        logging_and_tracking=logging_and_tracking,
        state_manager=state_manager,
        communication_manager=communication_manager,
        managing=managing,
        replay=replay,
        managed_system=managed_system,
        core=core,
    )
