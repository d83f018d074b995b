"""The platform assembled: Core, every building block, the loop, and the managed system.

:class:`Platform` is what ``rasm run`` drives and what :func:`rasm.testing.run_app` uses::

    platform = Platform(load_manifest("examples/hotbox"), clock="simulated", seed=1)
    summary = platform.run(duration=60)

The managing side (Core and the blocks, seed §5) and the managed side (the app's simulator, with
its probes and effectors) meet only on the transport: the simulator publishes on probe topics,
Telegraf digests them into knowledge, and actions reach the simulator only through the
Trustworthiness Checker publishing on an effector topic.
"""

from __future__ import annotations

import gc
import hashlib
import logging
import random
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rasm.errors import Location, PlatformError, RasmError, SourceError, is_interrupt
from rasm.knowledge.base import KnowledgeBase
from rasm.platform.adaptation_manager import AdaptationManager
from rasm.platform.adaptation_orchestrator import AdaptationOrchestrator, LoopStats
from rasm.platform.communication_manager import CommunicationManager
from rasm.platform.components import (
    Action,
    describe_failure,
    load_component,
    missing_stage_method,
)
from rasm.platform.core import Core
from rasm.platform.distribution import Distribution
from rasm.platform.knowledge_manager import KnowledgeManager
from rasm.platform.logging_and_tracking import LoggingAndTracking
from rasm.platform.logs import RepeatedLogs
from rasm.platform.manifest import AppManifest, Effector, load_manifest, manifest_location
from rasm.platform.scheduler import Scheduler
from rasm.platform.signals import check_app
from rasm.platform.state_manager import StateManager
from rasm.platform.storage_manager import StorageManager
from rasm.platform.telegraf import Telegraf
from rasm.platform.trace import TraceWriter
from rasm.platform.trustworthiness_checker import TrustworthinessChecker
from rasm.platform.trustworthiness_manager import TrustworthinessManager
from rasm.properties.outcome import PASSING, PropertyOutcome
from rasm.resources import data_dir
from rasm.statechart import MonotonicClock, SimulatedClock

__all__ = ["Platform", "RunSummary", "STAGES"]

STAGES = ("monitor", "analyse", "plan", "legitimate", "execute")
_log = logging.getLogger("rasm.platform")
_SCALARS = (int, float, bool, str)


@dataclass
class RunSummary:
    """What ``rasm run`` prints at the end."""

    app: str
    clock: str
    duration: float
    stats: LoopStats
    verdicts: dict[str, str]  # property -> satisfied | violated | inconclusive | not judged | error
    violations: dict[str, int]
    timing: dict[str, dict[str, float]]
    records: int
    rejected_data: dict[str, int] = field(default_factory=dict)
    # what the bus brought that was refused: malformed messages, actions the effector gate
    # refused (unsigned, bad signature, replayed), updates refused (only the non-zero counts)
    bus: dict[str, int] = field(default_factory=dict)
    modes: dict[str, str] = field(default_factory=dict)
    trace: str | None = None
    # loop iterations skipped on the wall clock because the loop was still busy when they fell due
    missed_iterations: int = 0
    # what ended the run before its duration (e.g. "SIGTERM"), None if it ran to the end
    stopped_by: str | None = None
    # each failure logged more than once (shown once, then counted): how many times in all
    repeated_failures: dict[str, int] = field(default_factory=dict)
    # every property's verdicts counted: the state, the errors, the signals never seen
    outcomes: dict[str, PropertyOutcome] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """No property violated, in error or not judged (inconclusive alone passes)."""
        return all(state in PASSING for state in self.verdicts.values())

    def properties(self) -> list[dict[str, Any]]:
        """Each property's overall verdict as JSON-able data, in the shape of ``rasm check
        --format json`` (with counts where ``rasm check`` lists the violations)."""
        return [
            {
                "name": o.name,
                "verdict": o.state,
                "violations": o.violations,
                "judged": o.judged,
                "inconclusive": o.inconclusive,
                "errors": o.errors,
                "first_error": o.first_error,
                "missing": list(o.missing),
            }
            for o in self.outcomes.values()
        ]


def _package_name(manifest: AppManifest) -> str:
    """A module package per app folder: two apps of the same name never share modules."""
    digest = hashlib.sha1(str(manifest.folder.resolve()).encode()).hexdigest()[:10]
    return f"rasm_app_{manifest.name.replace('-', '_')}_{digest}"


def _remove_sqlite(path: Path) -> None:
    for suffix in ("", "-wal", "-shm"):
        Path(f"{path}{suffix}").unlink(missing_ok=True)


class Platform:
    """One application's managing system (and, with ``role='all'``, its managed system).

    A property or rule that reads a name no part of the app provides raises
    :class:`~rasm.errors.SourceErrors` here (:func:`rasm.platform.signals.check_app`);
    ``check_signals=False`` runs such an app anyway (its properties are then never judged).
    """

    # The attributes read for every record and loop job are slots: compiled code reads a slot
    # without the instance dict lookup. The blocks are set by build(); before it, reading one
    # raises the same AttributeError as without a slot. ``__dict__`` keeps every other
    # attribute (and a subclass's) as it was.
    __slots__ = (
        "manifest", "clock", "scheduler", "trace", "on_record", "simulator", "twin",
        "_twin_inputs", "_twin_from_batch", "_started_at", "kb", "km", "tg", "cm", "tc", "ao",
        "__dict__", "__weakref__",
    )

    def __init__(
        self,
        manifest: AppManifest,
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
        components: dict[str, Any] | None = None,
        isolate_stages: bool | None = None,
        low_latency: bool = False,
        check_signals: bool = True,
    ) -> None:
        if role not in ("all", "managing", "managed"):
            raise PlatformError(f"unknown role {role!r} (all, managing or managed)")
        if isinstance(manifest, str | Path):
            manifest = load_manifest(manifest)
        elif not isinstance(manifest, AppManifest):
            raise TypeError(
                f"Platform() takes an app folder, its app.yaml or an AppManifest "
                f"(rasm.platform.manifest.load_manifest), not {type(manifest).__name__}"
            )
        if check_signals and role != "managed":
            # a property or rule reading a name nothing provides: refused before anything runs
            check_app(manifest)
        if clock not in (None, "simulated", "wall"):
            raise PlatformError(f"unknown clock {clock!r} (simulated or wall)")
        if components is not None:
            if not isinstance(components, dict):
                raise TypeError(
                    f"components must be a dict {{stage: object}}, not {type(components).__name__}"
                )
            unknown = sorted(set(components) - {*STAGES, "twin"})
            if unknown:
                raise PlatformError(
                    f"components: unknown stage {unknown[0]!r} "
                    f"(the stages are {', '.join(STAGES)}; or twin)"
                )
            for stage, obj in components.items():
                problem = missing_stage_method(stage, obj) if stage in STAGES else None
                if problem:
                    raise PlatformError(f"components[{stage!r}]: {problem}")
        self.manifest = manifest
        self.clock_kind = clock or manifest.clock or "wall"
        self.clock = (
            SimulatedClock() if self.clock_kind == "simulated" else MonotonicClock(running=False)
        )
        self.seed = 0 if seed is None else seed
        self.role = role
        self.scheduler = Scheduler(self.clock)
        self.scheduler.on_error = self._job_failed
        # rotated by size with trace_max_bytes (rasm.platform.trace.TraceWriter)
        self.trace = TraceWriter(trace, max_bytes=trace_max_bytes, keep=trace_keep)
        self.state_dir = Path(state_dir) if state_dir else Path(".rasm") / manifest.name
        self.scenario = manifest.scenario if scenario is None else scenario
        self.transport_url = transport or manifest.transport
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
        self.on_record: list[Callable[[float, dict[str, Any]], Any]] = []
        # every verdict of the online monitors goes to these callables (loop thread); nothing
        # keeps them, so a long run does not grow (the trace file has the records they judge).
        # Append to and remove from this list: the Trustworthiness Checker holds it.
        self.on_verdict: list[Callable[[Any], Any]] = []
        self.simulator: Any = None
        self.core: Core | None = None
        self._built = False
        self._started_at = 0.0
        self._timeline_start = 0.0
        self.twin: Any = None
        self._twin_inputs: frozenset[str] = frozenset()
        self._twin_from_batch = False
        self._effector_gates: dict[str, Any] = {}
        self.stopped_by: str | None = None  # why the run ended early (request_stop)
        # every failure the loop logs per iteration or record: once in full, then counted
        self.logs = RepeatedLogs()

    # ------------------------------------------------------------------ assembly

    def build(self) -> None:
        """Create every block (not started yet: :meth:`start` asks Core to do that)."""
        storage = self._open_knowledge() if self.role in ("all", "managing") else None
        try:
            self._build(storage)
        except BaseException:
            # a platform that cannot be built holds nothing: its knowledge file stays usable
            if storage is not None:
                storage.close()
            close = getattr(getattr(self, "kb", None), "close", None)
            if close is not None:
                close()
            raise

    def _build(self, storage: Any) -> None:
        from rasm.comm import open_transport

        m = self.manifest
        clock = self.clock
        self.dist = Distribution(self)
        self.transport = open_transport(self.transport_url, **self.dist.transport_options())
        log = self.manifest.logging
        self.lt = LoggingAndTracking(
            chart=self._chart("logging_and_tracking"),
            level=logging.getLevelName(log.get("level", "warning").upper()),
            sinks=tuple(log.get("sinks", ("console",))),
            publish=lambda topic, payload: self.transport.publish(topic, payload),
            clock=clock,
        )
        self.sm = StateManager(chart=self._chart("state_manager"), clock=clock, depends_on=("lt",))
        self.cm = CommunicationManager(
            self.transport,
            chart=self._chart("communication_manager"),
            clock=clock,
            depends_on=("lt",),
        )
        blocks: list[Any] = [self.lt, self.sm, self.cm]
        if self.role in ("all", "managing"):
            blocks += self._managing_blocks(storage)
        if self.role in ("all", "managed") and m.simulator:
            self.simulator = load_component(
                m.simulator,
                m.folder,
                package=_package_name(m),
                kwargs={"scenario": self.scenario, "seed": self.seed},
            )
        self.core = Core(blocks, clock=clock)
        for block in blocks:
            self.sm.track(block)
            block.on_deadline = self._schedule_block
            block.logs = self.logs
        self._built = True

    def _open_knowledge(self) -> Any:
        """Open (and restore) the knowledge store; returns its storage, if persistent."""
        from rasm.knowledge import open_knowledge

        url = self.knowledge_url
        if url == "sqlite":
            name = "simulated.sqlite" if self.clock_kind == "simulated" else "knowledge.sqlite"
            url = f"sqlite:{self.state_dir / name}"
        if url.startswith("sqlite:") and self.clock_kind == "simulated":
            # a simulation is a fresh world: no knowledge from an earlier run
            _remove_sqlite(Path(url[len("sqlite:") :]))
        self.kb, storage = open_knowledge(url, base_dir=Path.cwd())
        if url.startswith(("redis://", "rediss://")) and self.clock_kind == "simulated":
            self.kb.clear()  # a simulation is a fresh world here too
        if storage is not None:
            storage.detach()  # the Storage Manager block feeds it (and steps its chart)
        restored = [self.kb.read_sample(k) for k in self.kb.keys()]
        restored = [sample for sample in restored if sample is not None]
        if restored:
            # a restarted managing system continues its timeline after what it restored
            self._timeline_start = max(sample.time for sample in restored)
        for signal in self.manifest.signals.values():
            self.kb.declare(
                signal.key,
                signal.type,
                history=signal.history,
                minimum=signal.minimum,
                maximum=signal.maximum,
            )
        return storage

    def _managing_blocks(self, storage: Any) -> list[Any]:
        from rasm.properties import compile_properties
        from rasm.rules import RuleSet

        m, clock = self.manifest, self.clock
        self.km = KnowledgeManager(
            self.kb, chart=self._chart("knowledge_manager"), clock=clock, depends_on=("lt",)
        )
        self.stom = StorageManager(
            storage, chart=self._chart("storage_manager"), clock=clock, depends_on=("km",)
        )
        if storage is not None:
            # the Storage Manager buffers every update for its storage; without one it has
            # nothing to do with them, so no subscriber call per value stored
            self.kb.subscribe(self.stom.register_knowledge_update)
        self.tg = Telegraf(
            m.probes,
            self._register,
            chart=self._chart("telegraf"),
            clock=clock,
            depends_on=("km", "cm"),
        )
        self.rules = [RuleSet.load(path) for path in m.rules]
        files = [*self._platform_properties(), *m.properties]
        monitors = [compile_properties(p.read_text(encoding="utf-8"), source=str(p)) for p in files]
        defined: dict[str, Path] = {}
        for path, monitor in zip(files, monitors, strict=True):
            for name in monitor.properties:
                if name in defined:  # verdicts are reported by name: two would merge silently
                    raise PlatformError(
                        f"property {name!r} of {path} is already defined in "
                        f"{defined[name]}: rename one of them"
                    )
                defined[name] = path
        self.tc = TrustworthinessChecker(
            chart=self._chart("trustworthiness_checker"),
            monitors=monitors,
            effectors=m.effectors,
            send=self._send_action,
            mode_of=lambda: self.kb.read_knowledge(m.mode_signal) if m.mode_signal else None,
            online=lambda: self.dist.managed_online,
            observers=self.on_verdict,  # the list itself: observers added later are called
            clock=clock,
            depends_on=("sm", "cm"),
        )
        self.tm = TrustworthinessManager(
            chart=self._chart("trustworthiness_manager"),
            rules=self.rules,
            veto_properties=m.veto_properties,
            verdicts=lambda: self.tc.latest,
            waiting_for=lambda name: self.tc.missing(name),
            context=self.kb.snapshot,
            clock=clock,
            depends_on=("sm", "km", "tc"),
        )
        self.am = AdaptationManager(
            self.tm,
            self.tc,
            chart=self._chart("adaptation_manager"),
            clock=clock,
            depends_on=("tm", "tc"),
        )
        package = _package_name(m)
        components = {
            stage: self._component_overrides.get(stage)
            or self._stage_component(stage, ref, package)
            for stage, ref in m.components.items()
        }
        components.update(self._component_overrides)
        self.twin = self._load_twin(package)
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
            isolate_stages=self.isolate_stages,
            clock=clock,
            depends_on=("km", "am", "tm", "tc", "sm", "tg"),
        )
        self.trace.observers.append(self.tc.observe)
        return [self.km, self.stom, self.tg, self.tc, self.tm, self.am, self.ao]

    def _stage_component(self, stage: str, ref: str, package: str) -> Any:
        """The manifest's component for ``stage``; a problem names its place in app.yaml."""
        m = self.manifest
        try:
            component = load_component(ref, m.folder, package=package)
        except PlatformError as exc:
            cause = exc.__cause__
            if isinstance(cause, SyntaxError) and cause.filename and cause.lineno:
                # the place of the mistake is in the Python file, not in app.yaml
                where = Location(cause.filename, cause.lineno, cause.offset or 1)
                raise SourceError(f"{ref}: SyntaxError: {cause.msg}", where) from exc
            raise SourceError(str(exc), manifest_location(m, m.component_path(stage))) from exc
        problem = missing_stage_method(stage, component) if stage in STAGES else None
        if problem:
            raise SourceError(
                f"components.{stage}: {ref}: {problem}, so the {stage} stage would never run it",
                manifest_location(m, m.component_path(stage)),
            )
        return component

    def _load_twin(self, package: str) -> Any:
        """The app's digital twin (manifest ``twin:``), restored from knowledge if it learned
        before a restart."""
        m = self.manifest
        twin = self._component_overrides.get("twin")
        if twin is None and m.twin:
            twin = load_component(m.twin, m.folder, package=package)
        if twin is not None:
            model = self.kb.read_knowledge("twin_model")
            if model:
                try:
                    twin.load(model)
                except BaseException as exc:  # a stale model is relearned, never fatal
                    if is_interrupt(exc):
                        raise
                    _log.warning("the twin's stored model was not restored: %s", exc)
            self._twin_inputs = frozenset(twin.inputs)
            # a store read from memory holds, for an input just stored, the value stored: the
            # batch tells it (register_values' `into`), no read needed
            kind = type(self.kb)
            self._twin_from_batch = (
                kind.read_values is KnowledgeBase.read_values
                and kind.read_knowledge is KnowledgeBase.read_knowledge
            )
        return twin

    def _observe_twin(
        self, time: float, stored: dict[str, Any], batch: dict[str, Any] | None
    ) -> None:
        """Let the twin learn from the latest inputs; register its residual (and add it to
        ``stored``, the trace record of the inputs that produced it), and publish its model and
        drift. ``batch``: the values just stored, as stored, or None."""
        twin = self.twin
        inputs = twin.inputs
        values: dict[str, Any] | None = None
        if batch:
            # a local only ever a dict: compiled, its items are set without a type test
            found: dict[str, Any] = {}
            for key in inputs:
                if key not in batch:  # an input not in this batch: its latest is read
                    break
                found[key] = batch[key]
            else:
                values = found
        if values is None:
            values = self.kb.read_values(inputs)  # one lock for the inputs
        try:
            update = twin.observe(time, values)
            residual = None if update is None else float(update.residual)
        except BaseException as exc:  # a twin fault is logged; learning goes on
            if is_interrupt(exc):
                raise
            self.logs.log(
                _log, logging.ERROR, f"digital twin failed to learn: {describe_failure(exc)}"
            )
            return
        if update is None:
            return
        try:
            self.km.register_knowledge("twin_residual", residual, time)
        except Exception as exc:  # a NaN residual is refused like any bad value
            self._refused("twin_residual", residual, exc)
            residual = None
        if update.model_changed:
            model = twin.model()
            self._register({"twin_model": model}, time)
            self._emit(time, {"twin_model_version": model.get("version")})
        if update.drift:
            self._emit(time, {"drift": True, "explanation": "the digital twin detected drift"})
            self.scheduler.submit(self._drift_detected)
        if residual is not None:
            stored["twin_residual"] = residual

    def _drift_detected(self) -> None:
        # a method, not a lambda in _observe_twin: compiled, a lambda there would make that
        # function allocate a closure on every call (every record), drift or not
        self.ao.send("drift_detected")

    def _chart(self, name: str) -> Path | None:
        """The app's replacement for platform chart ``name`` (manifest ``statecharts:``)."""
        return self.manifest.statecharts.get(name)

    def _platform_properties(self) -> list[Path]:
        return sorted(data_dir("properties").glob("*.rv"))

    # ------------------------------------------------------------------ data paths

    def _register(self, values: dict[str, Any], time: float) -> None:
        """Store values in knowledge (one trace record for the batch, with the twin's residual
        when they were the twin's inputs)."""
        observe = self.twin is not None and not self._twin_inputs.isdisjoint(values)
        # the values as stored, for the twin (None: it reads them back)
        batch: dict[str, Any] | None = {} if observe and self._twin_from_batch else None
        # one call for the batch: a bad value is refused on its own, logged and dropped
        if batch is None:
            refused = self.km.register_values(values, time)
        else:
            refused = self.km.register_values(values, time, into=batch)
        for key, exc in refused.items():
            self._refused(key, values[key], exc)
        # the trace record has the scalars stored (a loop, not a comprehension: no function
        # call); the refused ones are taken out after, in the rare batch that has any
        stored: dict[str, Any] = {}
        for key, value in values.items():
            cls = type(value)  # the exact scalar classes without isinstance's call
            if cls is float or cls is bool or cls is str or cls is int or (
                isinstance(value, _SCALARS)
            ):
                stored[key] = value
        if refused:
            for key in refused:
                stored.pop(key, None)
        if observe:
            self._observe_twin(time, stored, batch)
        if stored:
            self._emit(time, stored)

    def _refused(self, key: str, value: Any, exc: Exception) -> None:
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

    def _send_action(self, effector: Effector, action: Action) -> None:
        payload = {**action.payload, "plan": action.plan, "kind": action.kind}
        self.cm.publish_message(effector.topic, self.dist.seal(effector.topic, payload))

    def _on_probe(self, message: Any) -> None:
        # Delivered on the transport's thread: hand it to the loop thread (digested at the
        # loop's time then).
        topic, payload = message.topic, message.payload
        scheduler = self.scheduler
        digest, now = self.tg.digest, scheduler.now
        scheduler.submit(lambda: digest(topic, payload, now()))

    def _on_effector(self, name: str, message: Any) -> None:
        payload = dict(message.payload)
        gate = self._effector_gates.get(name)
        if gate is None:  # the gate checks signatures when RASM_ACTION_KEY is set
            gate = self._effector_gates[name] = self.dist.effector_gate(
                lambda action, name=name: self._apply_action(name, action), message.topic
            )
        self.scheduler.submit(lambda: gate(payload))

    def _schedule_block(self, block: Any, due: float) -> None:
        self.scheduler.at(due, block.wake)

    def _job_failed(self, exc: BaseException) -> None:
        what = f"a loop job failed: {type(exc).__name__}: {exc}"
        self.logs.log(_log, logging.ERROR, what, exc_info=exc)

    # ------------------------------------------------------------------ running

    def start(self) -> None:
        """Build (if needed) and start every block in dependency order, then wire the loop."""
        if not self._built:
            self.build()
        assert self.core is not None
        if isinstance(self.clock, MonotonicClock):
            # building took time; the run's timeline starts now (or after restored knowledge)
            self.clock.start_at(self._timeline_start)
        self.core.initialize()
        if self.low_latency and not self._gc_frozen:
            gc.collect()
            gc.freeze()
            self._gc_frozen = True
        self._started_at = self.clock.time
        self.dist.start()
        m = self.manifest
        if self.role in ("all", "managing"):
            for probe in m.probes:
                self.cm.subscribe(probe.topic, self._on_probe)
            # a loop that overran skips the iterations it missed (Scheduler.missed)
            self.scheduler.every(
                m.period,
                self.ao.orchestration_loop,
                start=self.clock.time + m.period,
                skip_missed=True,
            )
        if self.simulator is not None:
            for name, effector in m.effectors.items():
                self.cm.subscribe(
                    effector.topic, lambda message, name=name: self._on_effector(name, message)
                )
            self.scheduler.every(m.simulator_period, self._step_simulator)

    def _apply_action(self, effector: str, action: dict[str, Any]) -> None:
        try:
            self.simulator.apply(effector, action, self.clock.time - self._started_at)
        except BaseException as exc:  # the simulator is user code: never fatal
            if is_interrupt(exc):
                raise
            what = f"the simulator's apply({effector!r}) failed: {describe_failure(exc)}"
            self.logs.log(_log, logging.ERROR, what, exc_info=exc)

    def _step_simulator(self) -> None:
        # the simulated world starts at 0 whatever the managing system's restored timeline
        try:
            readings = self.simulator.step(
                self.scheduler.now() - self._started_at, self.manifest.simulator_period
            )
        except BaseException as exc:  # the simulator is user code: never fatal
            if is_interrupt(exc):
                raise
            what = f"the simulator's step failed: {describe_failure(exc)}"
            self.logs.log(_log, logging.ERROR, what, exc_info=exc)
            return
        if readings is not None and not isinstance(readings, dict):
            what = (
                "the simulator's step must return {topic: payload} or None, "
                f"not {type(readings).__name__}"
            )
            self.logs.log(_log, logging.ERROR, what)
            return
        for topic, payload in (readings or {}).items():
            try:
                self.cm.publish_message(topic, payload)
            except RasmError as exc:  # a topic or payload the transport refuses
                what = f"the simulator's reading on {topic!r} was not published: {exc}"
                self.logs.log(_log, logging.ERROR, what)

    def run(self, duration: float | None = None) -> RunSummary:
        """Start, run for ``duration`` seconds of the platform's clock, stop, summarise.

        :meth:`request_stop` ends the run early, in the same order as a normal end.
        """
        random.seed(self.seed)
        self.start()
        length = duration if duration is not None else self.manifest.duration
        try:
            self.scheduler.run_until(self._started_at + length)
            ran = min(length, self.clock.time - self._started_at)
        finally:
            self.stop()
        if ran >= length:  # a stop asked for as the run ended anyway changed nothing
            self.stopped_by = None
        return self.summary(ran)

    def request_stop(self, reason: str = "a stop request") -> None:
        """End :meth:`run` after the job in hand: knowledge persisted, trace closed, summary
        made, as at a normal end. Safe from another thread and from a signal handler (it only
        sets a flag the loop reads); a request before the run starts makes it end at once."""
        self.stopped_by = reason
        self.scheduler.stop()

    def stop(self) -> None:
        self.logs.flush()  # the counts still unreported, while the log sinks are attached
        if self._built:
            self.dist.stop()
        if self.core is not None and self.core.mode != "terminated":
            self.core.deinitialize()
        self.trace.flush()
        if self._gc_frozen:
            gc.unfreeze()
            self._gc_frozen = False

    def _bus_refusals(self) -> dict[str, int]:
        stats = getattr(getattr(self, "transport", None), "stats", None)
        dist = getattr(self, "dist", None)
        updates = getattr(dist, "updates", None)
        counts = {
            "malformed messages": getattr(stats, "malformed", 0),
            "actions refused by the effector gate": getattr(dist, "actions_refused", 0),
            "updates refused": getattr(updates, "refused", 0),
        }
        return {what: n for what, n in counts.items() if n}

    def summary(self, duration: float) -> RunSummary:
        verdicts: dict[str, str] = {}
        violations: dict[str, int] = {}
        timing: dict[str, dict[str, float]] = {}
        stats = LoopStats()
        outcomes: dict[str, PropertyOutcome] = {}
        if self.role in ("all", "managing"):
            self.tc.finish()  # the verdicts still open go to the observers too
            outcomes = dict(self.tc.outcomes)
            verdicts = {name: o.state for name, o in outcomes.items()}
            violations = {name: o.violations for name, o in outcomes.items() if o.violations}
            timing = {
                stage: self.sm.percentiles(stage)
                for stage in STAGES
                if self.sm.stage_timing.get(stage)
            }
            stats = self.ao.stats
        self.trace.close()
        return RunSummary(
            app=self.manifest.name,
            clock=self.clock_kind,
            duration=duration,
            stats=stats,
            verdicts=verdicts,
            violations=violations,
            timing=timing,
            records=self.trace.records,
            rejected_data=dict(self.tg.rejected) if hasattr(self, "tg") else {},
            bus=self._bus_refusals(),
            missed_iterations=self.scheduler.missed,
            modes=self.sm.get_status(),
            trace=str(self.trace.path) if self.trace.path else None,
            stopped_by=self.stopped_by,
            repeated_failures=self.logs.totals,
            outcomes=outcomes,
        )
