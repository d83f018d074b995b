"""Knowledge Manager: registering and reading knowledge, gated by the block's mode."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rasm.errors import PlatformError
from rasm.knowledge.base import KnowledgeBase, Sample
from rasm.platform.block import Block

__all__ = ["KnowledgeManager"]


class KnowledgeManager(Block):
    """Knowledge Manager (km): ``register_knowledge`` / ``read_knowledge`` over the store.

    Values are registered only while the block is ``initialized``. A registration does not step
    the block's chart: it happens for every value the managed system sends, and a chart step
    costs more than storing a value.
    """

    chart_name = "knowledge_manager"
    short_name = "km"

    def __init__(self, store: KnowledgeBase, **kw: Any) -> None:
        self.store = store
        super().__init__(**kw)

    def register_knowledge(self, key: str, value: Any, time: float | None = None) -> Sample:
        self.require_mode("initialized")
        return self.store.register_knowledge(key, value, self.clock.time if time is None else time)

    def register_values(
        self, values: Mapping[str, Any], time: float | None = None
    ) -> dict[str, Exception]:
        """Store each of ``values`` as :meth:`register_knowledge` would, one after the other;
        return the refused ones, ``{key: the error}`` (a refused value does not stop the rest).
        """
        try:
            self.require_mode("initialized")
        except PlatformError as exc:
            return dict.fromkeys(values, exc)
        return self.store.register_values(values, self.clock.time if time is None else time)

    def read_knowledge(self, key: str, default: Any = None) -> Any:
        return self.store.read_knowledge(key, default)
