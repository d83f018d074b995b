"""The digital twin learning online from what the loop stores in knowledge.

Each batch of values stored that holds one of the twin's inputs is shown to the twin, with the
latest of all its inputs. What it learned goes back: its residual into knowledge and into the
trace record of that batch, a new model into knowledge and the trace, a detected drift to the
orchestrator (whose chart starts an adaptation). A twin that fails is logged, and the loop goes
on without what it would have learned from that batch.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Collection, Iterable
from typing import Any, Protocol

from rasm.errors import is_interrupt
from rasm.logs import RepeatedLogs
from rasm.platform.action_outcome import Emit
from rasm.platform.components import describe_failure
from rasm.twin import DigitalTwin

__all__ = ["TwinLearning"]

_log = logging.getLogger("rasm.platform")


class Knowledge(Protocol):
    """Where the twin's inputs are read: the knowledge store."""

    def read_values(self, keys: Iterable[str], default: Any = None) -> dict[str, Any]: ...


class TwinLearning:
    """Shows the twin each batch of its inputs (:meth:`observe`) and passes on what it learned.

    ``store(key, value, time)`` puts the residual in knowledge (raising when it is refused);
    ``register(values, time)`` stores and traces a new model; ``emit(time, record)`` writes a
    trace record; ``refused(key, value, exc)`` logs a refused residual; ``drift()`` tells the
    orchestrator.
    """

    def __init__(
        self,
        twin: DigitalTwin,
        *,
        knowledge: Knowledge,
        store: Callable[[str, Any, float], object],
        register: Callable[[dict[str, Any], float], object],
        emit: Emit,
        refused: Callable[[str, object, Exception], object],
        drift: Callable[[], object],
        logs: RepeatedLogs,
    ) -> None:
        self.twin = twin
        self.inputs = frozenset(twin.inputs)
        self.knowledge = knowledge
        self.store = store
        self.register = register
        self.emit = emit
        self.refused = refused
        self.drift = drift
        self.logs = logs

    def reads(self, keys: Collection[str]) -> bool:
        """Whether a batch of these keys holds one of the twin's inputs."""
        return not self.inputs.isdisjoint(keys)

    def observe(self, time: float, stored: dict[str, Any]) -> None:
        """Let the twin learn from the latest inputs; register its residual (and add it to
        ``stored``, the trace record of the inputs that produced it), and publish its model and
        drift."""
        twin = self.twin
        try:
            update = twin.observe(time, self.knowledge.read_values(twin.inputs))
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
            self.store("twin_residual", residual, time)
        except Exception as exc:  # a residual knowledge refuses is logged like any bad value
            self.refused("twin_residual", residual, exc)
            residual = None
        if update.model_changed:
            model = twin.model()
            self.register({"twin_model": model}, time)
            self.emit(time, {"twin_model_version": model.get("version")})
        if update.drift:
            self.emit(time, {"drift": True, "explanation": "the digital twin detected drift"})
            self.drift()
        if residual is not None:
            stored["twin_residual"] = residual
