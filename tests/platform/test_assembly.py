"""One function builds every part of a process: each block is made with what it works with, its
dependencies are blocks of the same process, and no block holds the platform or a block that
holds it back."""

from __future__ import annotations

import pytest

from rasm import Platform, RunOptions
from rasm.errors import PlatformError
from rasm.platform.block import Block
from rasm.platform.fallback import FallbackHold, FallbackSwitch

from .conftest import HOTBOX

FALLBACK = HOTBOX / "app.fallback.yaml"


def _built(app, **options) -> Platform:
    platform = Platform(app, RunOptions(clock="simulated", knowledge="memory", **options))
    platform.build()
    return platform


def _referenced(obj: object) -> list[object]:
    """What an object's attributes hold: the values, and the items of lists and tuples."""
    found: list[object] = []
    for value in vars(obj).values():
        found.extend(value if isinstance(value, list | tuple) else [value])
    return found


def test_every_block_depends_on_blocks_of_its_process_as_documented():
    parts = _built(FALLBACK).assembly
    blocks = parts.core.blocks
    assert all(dep in blocks for block in blocks for dep in block.depends_on)
    depends = {block.name: {dep.name for dep in block.depends_on} for block in blocks}
    assert depends == {
        "lt": set(),
        "sm": {"lt"},
        "cm": {"lt"},
        "km": {"lt"},
        "stom": {"km"},
        "tg": {"km", "cm"},
        "tc": {"sm", "cm"},
        "tm": {"sm", "km", "tc"},
        "am": {"tm", "tc"},
        "ao": {"km", "am", "tm", "tc", "sm", "tg"},
        "fb": {"am", "tm", "ao"},
    }


def test_no_block_holds_the_platform_and_block_references_run_one_way():
    platform = _built(FALLBACK)
    blocks = platform.assembly.core.blocks
    edges = {
        id(block): {id(v) for v in _referenced(block) if isinstance(v, Block)} for block in blocks
    }
    for block in blocks:
        assert all(value is not platform for value in _referenced(block)), block
    # a reference back (the Adaptation Manager holding the switch that holds it) is a cycle
    done: set[int] = set()

    def visit(node: int, path: tuple[int, ...]) -> None:
        assert node not in path, "blocks reference each other in a cycle"
        if node not in done:
            for target in edges.get(node, ()):
                visit(target, (*path, node))
            done.add(node)

    for block in blocks:
        visit(id(block), ())


def test_the_hold_is_made_before_and_shared_by_the_adaptation_manager_and_the_switch():
    side = _built(FALLBACK).managing
    hold = side.fallback_hold
    assert isinstance(hold, FallbackHold)
    assert side.adaptation_manager.hold is hold and side.fallback_switch.hold is hold
    assert not any(
        isinstance(value, FallbackSwitch | type(side.adaptation_manager))
        for value in _referenced(hold)
    )
    assert hold.state == "instantiated"  # the switch's mode until Core starts it


def test_an_app_without_a_fallback_has_no_hold_and_no_switch():
    side = _built(HOTBOX).managing
    assert side.fallback_hold is None and side.fallback_switch is None
    assert side.adaptation_manager.hold is None


def test_a_managed_only_process_has_no_managing_side():
    platform = _built(HOTBOX, role="managed")
    assert platform.assembly.managing is None
    assert platform.assembly.managed_system is not None
    with pytest.raises(PlatformError, match="a process of role managed has no managing side"):
        platform.managing  # noqa: B018 - the property raises


def test_the_parts_are_asked_for_before_they_are_built():
    platform = Platform(HOTBOX, RunOptions(clock="simulated", knowledge="memory"))
    with pytest.raises(PlatformError, match="not built yet"):
        platform.assembly  # noqa: B018 - the property raises
    assert not platform.built and platform.restored_from is None
