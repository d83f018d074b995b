"""Knowledge Manager: registering and reading knowledge, gated by the block's mode."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rasm.errors import PlatformError
from rasm.knowledge.base import register_each
from rasm.platform.block import Block

__all__ = ["KnowledgeManager"]


class KnowledgeManager(Block):
    """Knowledge Manager (km): ``register_knowledge`` / ``read_knowledge`` over the store."""

    __slots__ = ("store",)  # a slot, as Block's (read for every record)

    chart_name = "knowledge_manager"
    short_name = "km"

    def __init__(self, store: Any, **kw: Any) -> None:
        self.store = store
        super().__init__(**kw)

    def register_knowledge(self, key: str, value: Any, time: float | None = None) -> Any:
        if self._mode != "initialized":  # tested inline: this runs for every value stored
            self.require_mode("initialized")
        return self.store.register_knowledge(key, value, self.clock.time if time is None else time)

    def register_values(
        self,
        values: Mapping[str, Any],
        time: float | None = None,
        *,
        into: dict[str, Any] | None = None,
    ) -> dict[str, Exception]:
        """Store each of ``values`` as :meth:`register_knowledge` would, one after the other;
        return the refused ones, ``{key: the error}`` (a refused value does not stop the rest).
        With ``into``, each value stored is put there too, as stored (see
        :meth:`~rasm.knowledge.base.KnowledgeBase.register_values`).
        """
        if self._mode != "initialized":
            try:
                self.require_mode("initialized")
            except PlatformError as exc:
                return dict.fromkeys(values, exc)
        if time is None:
            time = self.clock.time
        store = self.store
        batch = getattr(store, "register_values", None)
        if batch is not None:  # one lock for the batch (KnowledgeBase)
            # a store's own register_values may not know `into`: asked without it when unused
            return batch(values, time) if into is None else batch(values, time, into=into)
        return register_each(store.register_knowledge, values, time, into)

    def read_knowledge(self, key: str, default: Any = None) -> Any:
        return self.store.read_knowledge(key, default)
