"""The digital-twin interface the runtime drives, and what one learning step reports."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, NamedTuple

from rasm.errors import RasmError

__all__ = ["DigitalTwin", "TwinError", "TwinUpdate"]


class TwinError(RasmError):
    """A twin was misconfigured or given a model it cannot use (``load`` of a damaged model)."""


class TwinUpdate(NamedTuple):
    """What one learning step found.

    * ``residual``: the size of this step's prediction error, in the predicted signal's unit
      (``|measured - predicted|``; each twin documents which prediction).
    * ``drift``: True on the one update where the twin detected that the system changed.
    * ``model_changed``: True when :meth:`DigitalTwin.model` now returns a new version that is
      worth persisting (the runtime registers it as the knowledge key ``twin_model``).
    """

    residual: float
    drift: bool = False
    model_changed: bool = False


class DigitalTwin(ABC):
    """A model of the managed system that learns online and predicts what a plan would do.

    The runtime (``twin:`` in ``app.yaml``) drives it:

    * :meth:`observe` on every knowledge registration of one of :attr:`inputs`, in time order,
      with the latest value of each input: the twin learns;
    * :meth:`simulate` in the Legitimate stage: the records the plan would produce, over which
      the application's properties are checked before anything reaches an effector;
    * :meth:`model` / :meth:`load`: the learned model as a versioned JSON document, persisted
      in knowledge and restored after a restart.

    A twin is plain Python; it never reads the knowledge base itself, so it can be tested on
    recorded or synthetic data alone.
    """

    #: the knowledge keys the twin learns from
    inputs: tuple[str, ...] = ()

    @abstractmethod
    def observe(self, time: float, values: dict[str, Any]) -> TwinUpdate | None:
        """Learn from one record: the latest value of each input at ``time``.

        Called on every registration touching an input, so several calls may carry the same
        ``time`` (one per input of a probe message). Returns None while warming up (and
        whenever this call taught the twin nothing new).
        """

    @abstractmethod
    def simulate(
        self, plan: dict[str, Any], state: dict[str, Any], horizon: float, dt: float
    ) -> list[tuple[float, dict[str, Any]]]:
        """The records the system would produce if ``plan`` were applied now in ``state``.

        ``state`` is the knowledge snapshot (latest value of every key). The records are
        ``(t, signals)`` with ``t`` the offset from now: ``dt, 2 dt, …`` up to ``horizon``.
        """

    @abstractmethod
    def model(self) -> dict[str, Any]:
        """The current model: ``{"version": int, "params": {...}, "learned_at": t,
        "points": n, "rmse": x, ...}``, JSON-able; :meth:`load` takes it back."""

    @abstractmethod
    def load(self, model: dict[str, Any]) -> None:
        """Continue from a model :meth:`model` returned (after a restart); raises
        :class:`TwinError` naming what is wrong with a model it cannot use."""
