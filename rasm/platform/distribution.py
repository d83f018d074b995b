"""What a platform does when its two halves meet over a network (seed §4.1, §6.1, ID_RAP_03).

- **Presence**: over MQTT each process announces itself on ``rasm/presence/<node>``, sends
  heartbeats and leaves a last will, so a crashed node is marked offline by the broker. The
  managing side tracks the managed nodes: when the last one goes offline or silent the
  orchestrator's chart gets ``managed_system_lost`` (it stops starting iterations, and the
  Trustworthiness Checker refuses actions), and ``managed_system_back`` when one returns.
- **Signed actions**: with ``RASM_ACTION_KEY`` (hex) set, the Trustworthiness Checker signs every
  action (HMAC-SHA256) and the managed side applies only correctly signed, never replayed ones.
- **Signed updates**: with ``RASM_UPDATE_KEY`` (hex) set, new rules and properties pushed on
  ``rasm/update/rules`` and ``rasm/update/properties`` replace the running ones only when signed
  and, for rules, consistent; every accepted or refused update is logged and answered on
  ``rasm/update/result``.
- **Timing**: every trace record (stage timing, adaptation events, verdicts) also goes to InfluxDB
  as line protocol when the manifest names a server (``timing: http://host:8086/db``), to a local
  file otherwise (``.rasm/<app>/timing.lp``, started afresh by a simulated run, appended to by a
  live one); nowhere with ``timing: off``.
- **The trace on the bus**: over MQTT every trace record is published on ``rasm/trace``, so
  ``rasm monitor --topics`` with ``"*": rasm/trace`` checks what the loop saw, from outside.
"""

from __future__ import annotations

import logging
import os
import time as _time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rasm.errors import PlatformError

__all__ = ["Distribution", "key_from_env"]

_log = logging.getLogger("rasm.platform")


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


class Distribution:
    """The network-facing parts of one platform process; each does nothing on the local bus."""

    def __init__(self, platform: Any) -> None:
        self.platform = platform
        self.networked = platform.transport_url != "local"
        role = platform.role
        self.node = f"{platform.manifest.name}-{role}-{os.getpid()}"
        self.action_key = key_from_env("RASM_ACTION_KEY")
        self.update_key = key_from_env("RASM_UPDATE_KEY")
        self.presence: Any = None
        self.tracker: Any = None
        self.updates: Any = None
        self.timing: Any = None
        self.gate: Any = None
        self.managed_nodes: dict[str, str] = {}
        self._epoch = 0.0

    def transport_options(self) -> dict[str, Any]:
        """Options for ``open_transport``: the last will that marks this node offline, and the
        broker credentials from ``RASM_MQTT_USERNAME``/``RASM_MQTT_PASSWORD``."""
        if not self.networked:
            return {}
        from rasm.comm import credentials_from_env, presence_will

        return {
            "will": presence_will(self.node, self.platform.role),
            **credentials_from_env(self.platform.transport_url),
        }

    # ------------------------------------------------------------------ start and stop

    def start(self) -> None:
        p = self.platform
        self._epoch = _time.time() - p.clock.time
        self._start_timing()
        if not self.networked:
            return
        from rasm.comm import Presence, PresenceTracker, UpdateReceiver

        self.presence = Presence(
            p.transport, self.node, role=p.role, period=max(p.manifest.period, 0.5)
        ).start()
        if p.role in ("all", "managing"):
            p.trace.observers.append(self._publish_record)
            self.tracker = PresenceTracker(
                p.transport,
                timeout=3 * max(p.manifest.period, 0.5),
                on_change=self._presence_changed,
            ).start()
            if self.update_key is not None:
                self.updates = UpdateReceiver(
                    p.transport,
                    self.update_key,
                    rules=self._apply_rules,
                    properties=self._apply_properties,
                ).start()

    def stop(self) -> None:
        for part in (self.updates, self.tracker, self.presence):
            if part is not None:
                try:
                    part.stop()
                except Exception as exc:  # shutting down goes on
                    _log.warning("stopping %s: %s", type(part).__name__, exc)
        if self.timing is not None:
            self.timing.close()

    # ------------------------------------------------------------------ timing

    def _start_timing(self) -> None:
        p = self.platform
        if p.role == "managed":
            return
        from rasm.comm import InfluxWriter

        target = p.manifest.timing
        if target == "off":
            return
        if target and target.startswith(("http://", "https://")):
            base, _, database = target.rstrip("/").rpartition("/")
            self.timing = InfluxWriter(base, database or "rasm")
        else:
            path = Path(target[len("file:") :]) if target else p.state_dir / "timing.lp"
            # a simulated run starts afresh, as its knowledge does; a live one continues its
            # timeline (a restarted managing system) and so its file
            self.timing = InfluxWriter.to_file(path, append=p.clock_kind != "simulated")
        p.trace.observers.append(
            lambda t, record: self.timing.write_record(self._epoch + t, record)
        )

    # ------------------------------------------------------------------ managing side

    def _publish_record(self, time: float, record: dict[str, Any]) -> None:
        try:
            self.platform.transport.publish("rasm/trace", {"time": time, **record})
        except Exception:  # the trace on the bus is best effort; the loop never waits for it
            pass

    def _presence_changed(self, node: str, state: str) -> None:
        tracker = self.tracker
        info = tracker.nodes().get(node) if tracker is not None else None
        if info is None or info.role != "managed":
            return
        before = any(s == "online" for s in self.managed_nodes.values())
        self.managed_nodes[node] = state
        after = any(s == "online" for s in self.managed_nodes.values())
        self.platform.sm.nodes[node] = state
        if before != after:
            event = "managed_system_back" if after else "managed_system_lost"
            log = _log.info if after else _log.warning
            log("managed system %s is %s: %s", node, state, event)
            self.platform.scheduler.submit(lambda: self.platform.ao.send(event))

    @property
    def managed_online(self) -> bool:
        """False when every managed node known to the tracker is offline or silent."""
        if not self.managed_nodes:
            return True  # none seen yet (or the local bus): nothing to refuse
        return any(state == "online" for state in self.managed_nodes.values())

    def _apply_rules(self, text: str) -> tuple[bool, str]:
        if not self.platform.rules:
            return False, "this application has no rules to replace"
        result = self.platform.rules[0].swap_text(text, source="rasm/update/rules")
        return bool(result.accepted), result.reason

    def _apply_properties(self, text: str) -> tuple[bool, str]:
        from rasm.spec import compile as compile_properties

        try:
            monitor = compile_properties(text, source="rasm/update/properties")
        except Exception as exc:
            return False, f"properties refused: {exc}"
        self.platform.scheduler.submit(lambda: self.platform.tc.monitors.append(monitor))
        return True, f"{len(monitor.properties)} properties added to the checker"

    # ------------------------------------------------------------------ actions

    def sign(self, payload: dict[str, Any]) -> dict[str, Any]:
        if self.action_key is None:
            return payload
        from rasm.comm import sign

        return sign(payload, self.action_key)

    def effector_gate(self, apply: Callable[[dict[str, Any]], Any]) -> Callable[[dict], Any]:
        """What the managed side calls with an incoming action payload."""
        if self.action_key is None:
            return apply
        from rasm.comm import SignedEffector

        self.gate = SignedEffector(self.action_key, apply)
        return self.gate.handle
