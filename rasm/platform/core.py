"""Core: brings every building block up and down.

Core is a block itself, driven by ``statecharts/core.yaml``. Inside its ``initialized`` mode it
starts the other blocks in dependency order (``starting_blocks``), and on shutdown stops them in
the reverse order (``stopping_blocks``). A block that fails to initialise aborts start-up cleanly:
the blocks already started are terminated again, newest first, and :meth:`Core.initialize` raises
:class:`StartupError` naming the block and its reason.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable

from sismic.clock import Clock

from rasm.errors import PlatformError
from rasm.platform.block import Block

__all__ = ["Core", "StartupError", "PlatformAborted", "start_order"]

_log = logging.getLogger("rasm.platform.core")


class StartupError(PlatformError):
    """A block failed to initialise; the blocks started before it were shut down again."""

    def __init__(self, block: str, reason: str | None) -> None:
        super().__init__(f"building block {block!r} failed to initialise: {reason}")
        self.block = block
        self.reason = reason


class PlatformAborted(PlatformError):
    """Raised by the default abort handler after the platform was shut down."""


def start_order(blocks: Iterable[Block]) -> list[Block]:
    """Blocks sorted so that each comes after the blocks it depends on (stable otherwise)."""
    blocks = list(blocks)
    names: set[str] = set()
    for block in blocks:
        if block.name in names:
            raise PlatformError(f"two building blocks are named {block.name!r}")
        names.add(block.name)
    known = {id(block) for block in blocks}
    for block in blocks:
        for dep in block.depends_on:
            if id(dep) not in known:
                raise PlatformError(
                    f"{block.name!r} depends on block {dep.name!r}, which is not started here"
                )
    order: list[Block] = []
    state: dict[int, str] = {}

    def visit(block: Block, path: list[str]) -> None:
        mark = state.get(id(block))
        if mark == "done":
            return
        if mark == "visiting":
            cycle = " -> ".join([*path[path.index(block.name) :], block.name])
            raise PlatformError(f"building blocks depend on each other in a cycle: {cycle}")
        state[id(block)] = "visiting"
        for dep in block.depends_on:
            visit(dep, [*path, block.name])
        state[id(block)] = "done"
        order.append(block)

    for block in blocks:
        visit(block, [])
    return order


class Core(Block):
    """The platform's entry point: ``initialize``, ``deinitialize``, ``abort``,
    ``set_abort_handler`` (the RoboSAPIENS design's interface, in snake_case)."""

    chart_name = "core"
    short_name = "core"

    def __init__(self, blocks: Iterable[Block] = (), *, clock: Clock | None = None) -> None:
        self.blocks = list(blocks)
        self.started: list[Block] = []
        self._order: list[Block] = []
        self._startup_failure: StartupError | None = None
        self._abort_handler: Callable[[str], object] | None = None
        super().__init__("core", clock=clock)

    # ---------------------------------------------------- the RoboSAPIENS design's interface

    def initialize(self) -> None:
        """Start every block, in dependency order; raise :class:`StartupError` on failure."""
        self.require_mode("instantiated")
        self._startup_failure = None
        self.send("configure")
        if self._startup_failure is not None:
            raise self._startup_failure
        if self.mode == "fault":
            raise StartupError(self.name, self.failure_reason)

    def deinitialize(self) -> None:
        """Stop every started block in reverse order, then terminate Core itself."""
        if self.mode == "terminated":
            return
        if self.mode == "initialized":
            self.send("shutdown_requested")
        self._stop_blocks()  # in any other mode, whatever was started still has to stop
        self.send("terminate")

    def abort(self, reason: str = "aborted") -> None:
        """Abort the platform: the handler set by :meth:`set_abort_handler`, or the default one,
        which shuts everything down and raises :class:`PlatformAborted`."""
        _log.error("platform abort: %s", reason)
        if self._abort_handler is not None:
            self._abort_handler(reason)
            return
        self.deinitialize()
        raise PlatformAborted(reason)

    def set_abort_handler(self, handler: Callable[[str], object] | None) -> None:
        """Replace the global abort handler (``None`` restores the default)."""
        self._abort_handler = handler

    # ------------------------------------------------------------------ chart hooks

    def on_configuration(self) -> None:
        self._order = start_order(self.blocks)

    def on_enter_starting_blocks(self) -> None:
        for block in self._order:
            block.send("configure")
            if block.mode != "initialized":
                reason = block.failure_reason or f"stopped in mode {block.mode!r}"
                self._startup_failure = StartupError(block.name, reason)
                if block.mode != "terminated":
                    block.send("terminate")
                self._stop_blocks()
                self.post("failed", reason=str(self._startup_failure))
                return
            self.started.append(block)
        self.post("blocks_started")

    def on_enter_stopping_blocks(self) -> None:
        self._stop_blocks()
        self.post("blocks_stopped")

    def _stop_blocks(self) -> None:
        while self.started:
            block = self.started.pop()
            if block.mode != "terminated":
                block.send("terminate")
