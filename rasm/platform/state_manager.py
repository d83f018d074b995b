"""State Manager: the mode of every block and the timing history of every stage."""

from __future__ import annotations

import math
from collections import defaultdict, deque
from typing import Any

from rasm.platform.block import Block

__all__ = ["StateManager"]


class StateManager(Block):
    """State Manager (sm): the mode of every block and the timing history of every stage."""

    chart_name = "state_manager"
    short_name = "sm"

    def __init__(self, *, timing_history: int = 1000, **kw: Any) -> None:
        self.modes: dict[str, str] = {}
        self.nodes: dict[str, str] = {}  # remote node -> online | offline | silent (presence)
        self.stage_timing: dict[str, deque[tuple[float, float]]] = defaultdict(
            lambda: deque(maxlen=timing_history)
        )
        super().__init__(**kw)

    def track(self, block: Block) -> None:
        """Follow ``block``'s mode from now on."""
        self.modes[block.name] = block.mode
        block.add_mode_listener(self._mode_changed)

    def _mode_changed(self, block: Block, mode: str) -> None:
        self.modes[block.name] = mode

    def get_time(self) -> float:
        return self.clock.time

    def get_status(self, name: str | None = None) -> dict[str, str] | str | None:
        """The mode of block ``name``, or of every block."""
        return dict(self.modes) if name is None else self.modes.get(name)

    def set_node(self, node: str, state: str) -> None:
        """Record the presence of remote process ``node``: online, offline or silent."""
        self.nodes[node] = state

    def record_stage(self, stage: str, start: float, duration: float) -> None:
        self.stage_timing[stage].append((start, duration))

    def percentiles(self, stage: str, qs: tuple[float, ...] = (50, 90, 99)) -> dict[str, float]:
        durations = sorted(d for _, d in self.stage_timing.get(stage, ()))
        if not durations:
            return {}
        out = {}
        for q in qs:
            k = max(0, min(len(durations) - 1, math.ceil(q / 100 * len(durations)) - 1))
            out[f"p{q:g}"] = durations[k]
        return out
