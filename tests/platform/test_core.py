"""Core brings blocks up in dependency order, down in reverse, and rolls back a failed start-up."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.errors import PlatformError
from rasm.platform.block import Block
from rasm.platform.core import Core, PlatformAborted, StartupError, start_order


class Recorder(Block):
    """A block that records its mode work in a shared journal and can be told to fail."""

    chart_name = "knowledge_manager"

    def __init__(self, name, journal, *, depends_on=(), fail_in=None):
        self.journal = journal
        self.fail_in = fail_in
        super().__init__(name, depends_on=depends_on)

    def on_configuration(self):
        self.journal.append(("configure", self.name))
        if self.fail_in == "configuration":
            raise RuntimeError("bad parameter")

    def on_initialization(self):
        self.journal.append(("initialize", self.name))
        if self.fail_in == "initialization":
            raise OSError("port in use")

    def on_termination(self):
        self.journal.append(("terminate", self.name))


def test_blocks_start_in_dependency_order_and_stop_in_reverse():
    journal = []
    km = Recorder("km", journal)
    cm = Recorder("cm", journal)
    stom = Recorder("stom", journal, depends_on=(km,))
    tg = Recorder("tg", journal, depends_on=(km, cm))
    core = Core([tg, stom, km, cm])
    core.initialize()
    assert core.mode == "initialized"
    assert "running" in core.configuration
    assert all(b.mode == "initialized" for b in (km, stom, tg, cm))
    started = [name for what, name in journal if what == "initialize"]
    assert started == ["km", "cm", "tg", "stom"]
    journal.clear()
    core.deinitialize()
    assert core.mode == "terminated"
    assert [name for what, name in journal] == ["stom", "tg", "cm", "km"]
    assert all(b.mode == "terminated" for b in (km, stom, tg, cm))


@pytest.mark.parametrize("fail_in", ["configuration", "initialization"])
def test_a_failing_block_aborts_startup_and_stops_the_started_ones(fail_in):
    journal = []
    a = Recorder("a", journal)
    b = Recorder("b", journal, depends_on=(a,))
    bad = Recorder("bad", journal, depends_on=(b,), fail_in=fail_in)
    never = Recorder("never", journal, depends_on=(bad,))
    core = Core([a, b, bad, never])
    with pytest.raises(StartupError) as info:
        core.initialize()
    assert info.value.block == "bad"
    assert "bad parameter" in str(info.value) or "port in use" in str(info.value)
    assert core.mode == "fault"
    assert [name for what, name in journal if what == "terminate"] == ["bad", "b", "a"]
    assert ("configure", "never") not in journal
    assert never.mode == "instantiated"
    assert {a.mode, b.mode, bad.mode} == {"terminated"}
    core.deinitialize()
    assert core.mode == "terminated"


def test_dependency_cycles_and_dependencies_not_started_are_reported():
    """A dependency is a block given when the block is made, so a cycle needs one changed
    afterwards: Core still refuses it."""
    journal = []
    x = Recorder("x", journal)
    y = Recorder("y", journal, depends_on=(x,))
    x.depends_on = (y,)
    with pytest.raises(PlatformError, match="cycle: x -> y -> x"):
        start_order([x, y])
    ghost = Recorder("ghost", journal)
    with pytest.raises(PlatformError, match="depends on block 'ghost', which is not started"):
        start_order([Recorder("x", journal, depends_on=(ghost,))])
    x = Recorder("x", journal)
    x.depends_on = (x,)
    with pytest.raises(StartupError, match="cycle"):
        Core([x]).initialize()


def test_abort_uses_the_handler_or_shuts_down():
    journal = []
    core = Core([Recorder("a", journal)])
    core.initialize()
    seen = []
    core.set_abort_handler(seen.append)
    core.abort("overheat")
    assert seen == ["overheat"] and core.mode == "initialized"
    core.set_abort_handler(None)
    with pytest.raises(PlatformAborted, match="overheat"):
        core.abort("overheat")
    assert core.mode == "terminated"
    assert ("terminate", "a") in journal


@settings(max_examples=60, deadline=None)
@given(st.data())
def test_start_order_respects_every_dependency(data):
    n = data.draw(st.integers(1, 7))
    names = [f"b{i}" for i in range(n)]
    # edges only to lower indices: acyclic by construction; shuffled declaration order
    deps = {
        name: tuple(data.draw(st.sets(st.sampled_from(names[:i]))) if i else ())
        for i, name in enumerate(names)
    }
    declared = data.draw(st.permutations(names))
    journal = []
    made: dict[str, Recorder] = {}
    for name in names:  # made in index order: each after the blocks it depends on
        made[name] = Recorder(name, journal, depends_on=tuple(made[d] for d in sorted(deps[name])))
    order = [b.name for b in start_order([made[name] for name in declared])]
    assert sorted(order) == sorted(names)
    for name in names:
        for dep in deps[name]:
            assert order.index(dep) < order.index(name)
