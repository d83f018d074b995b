"""What a platform does when its two halves meet over a network.

- **Presence**: over MQTT each process announces itself on ``rasm/presence/<node>``, sends
  heartbeats and leaves a last will, so a crashed node is marked offline by the broker. The
  managing side tracks the managed nodes: when the last one goes offline or silent the
  orchestrator's chart gets ``managed_system_lost`` (it stops starting iterations, and the
  Trustworthiness Checker refuses actions), and ``managed_system_back`` when one returns.
- **Incarnations**: every process draws a random ``epoch`` at start and announces it in its
  presence message, and a random ``run`` id; a live run's plan ids start with the run id, so
  they never repeat across runs (a simulated run keeps ``p1``, ``p2``, …: reproducible).
- **Signed actions**: with ``RASM_ACTION_KEY`` (hex) set, the Trustworthiness Checker signs every
  action (HMAC-SHA256) bound to the announced epochs of the managed processes, its run and a
  growing sequence; the managed side applies only correctly signed actions bound to its own
  epoch and newer than what it applied from that run. Until the managing side has seen a
  managed process's epoch it sends nothing: the action is refused, with the reason in the
  trace.
- **Signed updates**: with ``RASM_UPDATE_KEY`` (hex) set, new rules and properties pushed on
  ``rasm/update/rules`` and ``rasm/update/properties`` replace the running ones only when
  signed, bound to this process's epoch (as actions are) and, for rules, consistent; every
  accepted or refused update is logged and answered on ``rasm/update/result``.
- **Timing**: every trace record (stage timing, adaptation events, verdicts) also goes to InfluxDB
  as line protocol when the manifest names a server (``timing: http://host:8086/db``), to a local
  file otherwise (``.rasm/<app>/timing.lp``, started afresh by a simulated run, appended to by a
  live one); nowhere with ``timing: off``.
- **The trace on the bus**: over MQTT every trace record is published on ``rasm/trace``, so
  ``rasm monitor --topics`` with ``"*": rasm/trace`` checks what the loop saw, from outside.
"""

from __future__ import annotations

import logging
import math
import os
import secrets
import time as _time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rasm.comm import Transport
from rasm.comm.signing import BoundSigner, SignedEffector, SignedGate, new_epoch
from rasm.errors import CommError, PlatformError
from rasm.platform.action_outcome import Emit
from rasm.platform.run_options import Role

if TYPE_CHECKING:
    from rasm.comm import InfluxWriter, Presence, PresenceTracker, UpdateReceiver
    from rasm.properties.monitor import Monitor
    from rasm.rules import RuleSet

__all__ = ["Distribution", "DistributionHooks", "key_from_env"]

_log = logging.getLogger("rasm.platform")

Observers = list[Emit]
"""The trace's observers: each is called with every record (time, record)."""


def key_from_env(name: str) -> bytes | None:
    """A signing key from a hex environment variable, or None when unset."""
    value = os.environ.get(name)
    if not value:
        return None
    try:
        return bytes.fromhex(value.strip())
    except ValueError:
        raise PlatformError(
            f"{name} must be the signing key in hexadecimal (e.g. `openssl rand -hex 32`)"
        ) from None


@dataclass(frozen=True)
class DistributionHooks:
    """What the managing side's network parts tell the loop, as callables.

    ``managed_system(event)``: ``managed_system_lost`` or ``managed_system_back`` (called on a
    transport thread); ``node(name, state)``: a remote process's presence changed;
    ``rules``: the rule sets an update replaces the first of; ``add_monitor(monitor)``: the
    properties of an accepted update (called on a transport thread).
    """

    managed_system: Callable[[str], object]
    node: Callable[[str, str], object]
    rules: list[RuleSet]
    add_monitor: Callable[[Monitor], object]


class Distribution:
    """The network-facing parts of one platform process; each does nothing on the local bus.

    ``timing`` is the manifest's ``timing:`` (``off``, ``file:PATH``, an InfluxDB URL, or None
    for ``timing_file``); a simulated run (``fresh``) starts its timing file afresh.
    """

    def __init__(
        self,
        *,
        app: str,
        role: Role,
        transport_url: str,
        period: float,
        timing: str | None,
        timing_file: Path,
        fresh: bool,
    ) -> None:
        self.app = app
        self.role = role
        self.transport_url = transport_url
        # presence, signed updates and the trace on the bus are MQTT's: a ROS 2 middleware
        # has its own graph, and its topics carry typed messages only
        self.networked = transport_url.strip().startswith(("mqtt://", "mqtts://"))
        self.period = period
        self.timing_target = timing
        self.timing_file = timing_file
        self.fresh = fresh
        self.node = f"{app}-{role}-{os.getpid()}"
        self.action_key = key_from_env("RASM_ACTION_KEY")
        if self.action_key is not None and transport_url.strip().startswith(("zenoh:", "dds:")):
            raise PlatformError(
                "RASM_ACTION_KEY signs actions, which a ROS 2 message has no room for: unset "
                "it, or send the actions over MQTT"
            )
        self.update_key = key_from_env("RASM_UPDATE_KEY")
        self.presence: Presence | None = None
        self.tracker: PresenceTracker | None = None
        self.updates: UpdateReceiver | None = None
        self.timing: InfluxWriter | None = None
        self.gates: list[SignedEffector] = []  # one effector gate per effector topic
        self.managed_nodes: dict[str, str] = {}
        self._epoch = 0.0
        self._started = 0.0  # time.monotonic() at start()
        self._transport: Transport | None = None
        self._hooks: DistributionHooks | None = None
        # this process's incarnation (what actions and updates sent to it must be bound to)
        # and this run of its managing side (the prefix of live plan ids, the signer's run)
        self.epoch = new_epoch()
        self.run = secrets.token_hex(8)
        self.signer = (
            BoundSigner(self.action_key, run=self.run) if self.action_key is not None else None
        )
        self._unbound_logged = False

    @property
    def managing(self) -> bool:
        return self.role.manages

    def transport_options(self) -> dict[str, Any]:
        """Options for ``open_transport``: the last will that marks this node offline, and the
        broker credentials from ``RASM_MQTT_USERNAME``/``RASM_MQTT_PASSWORD``."""
        if not self.networked:
            return {}
        from rasm.comm import presence_will
        from rasm.comm.url import credentials_from_env

        return {
            "will": presence_will(self.node, self.role),
            **credentials_from_env(self.transport_url),
        }

    # ------------------------------------------------------------------ start and stop

    def start(
        self,
        transport: Transport,
        observers: Observers,
        *,
        clock_time: float,
        hooks: DistributionHooks | None = None,
    ) -> None:
        """Start the network parts on ``transport``. ``observers`` are the trace's: the timing
        writer and the trace on the bus join them. ``clock_time`` is the platform clock's time
        now; ``hooks`` (the managing side's) are what presence and updates act on."""
        self._transport = transport
        self._hooks = hooks
        self._epoch = _time.time() - clock_time
        self._started = _time.monotonic()
        if self.managing:
            self._start_timing(observers)
        if not self.networked:
            return
        from rasm.comm import Presence, PresenceTracker, UpdateReceiver

        signed = self.action_key is not None
        if self.managing or signed:
            # with the action key the managed side follows presence too: it binds its own
            # heartbeats to the epochs of the managing processes that introduced themselves
            self.tracker = PresenceTracker(
                transport,
                timeout=3 * max(self.period, 0.5),
                on_change=self._presence_changed if self.managing else None,
                gate=SignedGate(self.action_key, epoch=self.epoch) if signed else None,
            ).start()
        self.presence = Presence(
            transport,
            self.node,
            role=self.role,
            period=max(self.period, 0.5),
            info={"app": self.app, "epoch": self.epoch},
            signer=BoundSigner(self.action_key) if signed else None,
            receivers=self._presence_receivers,
        ).start()
        if self.managing:
            observers.append(self._publish_record)
            if self.update_key is not None:
                self.updates = UpdateReceiver(
                    transport,
                    self.update_key,
                    rules=self._apply_rules,
                    properties=self._apply_properties,
                    epoch=self.epoch,
                ).start()

    def _presence_receivers(self) -> list[str]:
        """Whom this process's signed heartbeats are bound to: the other processes of its app
        that introduced themselves."""
        if self.tracker is None:
            return []
        return [e for e in self.tracker.known_epochs(app=self.app) if e != self.epoch]

    def verdict_check(self, topics: dict[str, str]) -> Callable[[str, Any], str | None] | None:
        """How external verdicts (source name -> topic) are told from an outsider's: over MQTT
        with ``RASM_ACTION_KEY``, each must be signed with it and bound to this process's
        epoch and its topic, and be newer than what came from its sender's run; None where
        nothing can be checked here (no key, or a ROS 2 transport: its own check is the
        declared publisher)."""
        if self.action_key is None or not self.networked:
            return None
        gates = {
            name: SignedGate(self.action_key, epoch=self.epoch, topic=topic)
            for name, topic in topics.items()
        }
        return lambda name, payload: gates[name].check(payload)

    def stop(self) -> None:
        for part in (self.updates, self.tracker, self.presence):
            if part is not None:
                try:
                    part.stop()
                except Exception as exc:  # shutting down goes on
                    _log.warning("stopping %s: %s", type(part).__name__, exc)
        if self.timing is not None:
            self.timing.close()

    def platform_time(self, wall: float) -> float:
        """A wall-clock time (seconds since the epoch) on the platform clock's timeline."""
        return wall - self._epoch

    # ------------------------------------------------------------------ timing

    def _start_timing(self, observers: Observers) -> None:
        from rasm.comm import InfluxWriter

        target = self.timing_target
        if target == "off":
            return
        if target and target.startswith(("http://", "https://")):
            base, _, database = target.rstrip("/").rpartition("/")
            self.timing = InfluxWriter(base, database or "rasm")
        else:
            path = Path(target[len("file:") :]) if target else self.timing_file
            # a simulated run starts afresh, as its knowledge does; a live one continues its
            # timeline (a restarted managing system) and so its file
            self.timing = InfluxWriter.to_file(path, append=not self.fresh)
        observers.append(self._write_timing)

    def _write_timing(self, time: float, record: dict[str, Any]) -> None:
        self.timing.write_record(self._epoch + time, record)

    # ------------------------------------------------------------------ managing side

    def _publish_record(self, time: float, record: dict[str, Any]) -> None:
        # JSON on the wire has no infinities (a robustness decided by booleans alone is ±inf):
        # such a value goes out undefined, as the trace file writes a NaN, never the record lost
        payload = {
            key: None if isinstance(value, float) and not math.isfinite(value) else value
            for key, value in record.items()
        }
        try:
            self._transport.publish("rasm/trace", {"time": time, **payload})
        except Exception:  # the trace on the bus is best effort; the loop never waits for it
            pass

    def _presence_changed(self, node: str, state: str) -> None:
        tracker = self.tracker
        info = tracker.nodes().get(node) if tracker is not None else None
        if info is None or info.role != Role.MANAGED:
            return
        if node not in self.managed_nodes and info.payload.get("app") != self.app:
            return  # another application's managed system on the same broker
        before = any(s == "online" for s in self.managed_nodes.values())
        self.managed_nodes[node] = state
        after = any(s == "online" for s in self.managed_nodes.values())
        self._hooks.node(node, state)
        if before != after:
            event = "managed_system_back" if after else "managed_system_lost"
            log = _log.info if after else _log.warning
            log("managed system %s is %s: %s", node, state, event)
            self._hooks.managed_system(event)

    @property
    def managed_online(self) -> bool:
        """Whether presence says a managed process is there: some managed node of the app
        online, or none heard of yet and either the managed system is this process's own (role
        ``all``) or the start was less than the tracker's timeout ago (a managed process
        announces itself within a period or two: past that, nobody is there). Always True
        where there is no presence (the local bus, ROS 2)."""
        if self.tracker is None or not self.managing:
            return True
        if any(state == "online" for state in self.managed_nodes.values()):
            return True
        if self.managed_nodes:
            return False  # every one seen is offline or silent
        return self.role is Role.ALL or _time.monotonic() < self._started + self.tracker.timeout

    def _apply_rules(self, text: str) -> tuple[bool, str]:
        if not self._hooks.rules:
            return False, "this application has no rules to replace"
        result = self._hooks.rules[0].swap_text(text, source="rasm/update/rules")
        return bool(result.accepted), result.reason

    def _apply_properties(self, text: str) -> tuple[bool, str]:
        from rasm.properties import compile_properties

        try:
            monitor = compile_properties(text, source="rasm/update/properties")
        except Exception as exc:
            return False, f"properties refused: {exc}"
        self._hooks.add_monitor(monitor)
        return True, f"{len(monitor.properties)} properties added to the checker"

    # ------------------------------------------------------------------ actions

    def _managed_epochs(self) -> list[str]:
        """The epochs of the managed processes an action is for: this process's own in role
        ``all``, and those of the online managed processes of this app announced so far."""
        epochs = [self.epoch] if self.role is Role.ALL else []
        if self.tracker is not None:
            found = self.tracker.epochs(role=Role.MANAGED, app=self.app)
            epochs += sorted(found.values())
        return epochs

    def seal(self, topic: str, payload: dict[str, Any]) -> dict[str, Any]:
        """``payload`` as it goes on ``topic``: signed and bound when ``RASM_ACTION_KEY`` is set.

        Raises :class:`CommError` (the checker refuses the action, with this reason) when no
        managed process has announced its epoch yet: an action bound to nobody is not sent.
        """
        if self.signer is None:
            return payload
        epochs = self._managed_epochs()
        if not epochs:
            if not self._unbound_logged:  # once per stretch without an epoch: the trace has each
                _log.warning("no managed process has announced its epoch: actions are not sent")
                self._unbound_logged = True
            raise CommError(
                "not sent: no managed process has announced its epoch yet, and a signed action "
                "is bound to the epoch of the process that applies it"
            )
        self._unbound_logged = False
        return self.signer.sign(payload, topic=topic, epochs=epochs)

    def effector_gate(
        self, apply: Callable[[dict[str, Any]], Any], topic: str
    ) -> Callable[[dict], Any]:
        """What the managed side calls with an action payload received on ``topic``."""
        if self.action_key is None:
            return apply
        gate = SignedEffector(self.action_key, apply, epoch=self.epoch, topic=topic)
        self.gates.append(gate)
        return gate.handle

    @property
    def actions_refused(self) -> int:
        """Actions the effector gates refused (unsigned, bad signature, replayed, unbound)."""
        return sum(gate.refused for gate in self.gates)
