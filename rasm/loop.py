"""The MAPLE-K loop's vocabulary: its stages, and the keys and events it writes in a trace.

The platform, the report, the architecture models and the signal checks all speak of the loop
with these names; this module is where they are defined, once.
"""

from __future__ import annotations

__all__ = [
    "EVENTS", "LOOP_KEYS", "LOOP_SIGNAL_TYPES", "MEASURED_KEYS", "ROBUSTNESS_PREFIX", "STAGES",
    "reserved_key", "robustness_key",
]

STAGES: tuple[str, ...] = ("monitor", "analyse", "plan", "legitimate", "execute")
"""The MAPLE-K stages, in the order one iteration runs them (Knowledge is shared by all)."""

EVENTS: tuple[str, ...] = (
    "anomaly", "planned", "legitimate", "rejected", "trusted", "executed", "dropped",
)
"""The events of one adaptation, in the order it meets them: each is a trace key set to true
on the record of the moment it happened."""

LOOP_SIGNAL_TYPES: dict[str, str] = {
    "time": "float",
    "stage": "str",
    "duration": "float",
    **{event: "bool" for event in EVENTS},
    "plan": "str",
    "broken_rules": "json",
    "explanation": "str",
    "drift": "bool",
    "recorded_action": "json",  # a replay's action, not sent: effector, topic (or service,
    # action), payload
    "twin_model_version": "int",
    "fallback": "str",  # "engaged" | "released", on the record where the fallback switches
    "repaired_from": "str",  # on a repaired plan's planned record: the rejected plan's id
    "corrective": "bool",  # an action let through a veto as corrective (the twin's prediction)
    "effector_done": "str",  # a service or action effector's call answered: the effector
    "effector_failed": "str",  # ... failed (explanation: why): the effector
}
"""Every key the loop itself writes in trace records, with the type a property reads it as."""

LOOP_KEYS: frozenset[str] = frozenset(LOOP_SIGNAL_TYPES)
"""The keys the loop writes in trace records. A knowledge signal of one of these names would
forge the loop's own events in the trace and in what the monitors see, so probe signals and
Monitor results may not use them."""

ROBUSTNESS_PREFIX = "robustness_"
"""Property ``p``'s robustness (SPEC §12) is the knowledge key and trace signal
``robustness_p``, written by the Trustworthiness Checker."""


def robustness_key(name: str) -> str:
    """The knowledge key and trace signal that hold property ``name``'s robustness."""
    return ROBUSTNESS_PREFIX + name


def reserved_key(name: str) -> str | None:
    """Why an app may not name a signal ``name`` (None: it may). The loop's own keys would
    forge its events; a ``robustness_`` key would forge the margin a stage adapts on."""
    if name in LOOP_KEYS:
        return f"a key the loop writes itself in the trace ({', '.join(sorted(LOOP_KEYS))})"
    if name.startswith(ROBUSTNESS_PREFIX):
        return (f"the Trustworthiness Checker writes {ROBUSTNESS_PREFIX}<property> keys "
                "(a property's robustness)")
    return None


MEASURED_KEYS: frozenset[str] = frozenset({"duration", robustness_key("stage_budget")})
"""The trace keys whose values are measured on the wall clock even in a simulated run: a
stage's duration, and the robustness of the platform's ``stage_budget`` (it reads the duration).
With the simulated clock and a seed, two runs agree on every other key."""
