"""The block drivers in rasm.platform and the charts in statecharts/ name the same things.

A driver reacts to sub-states by name (``on_enter_<state>``) and answers with events by name
(``post("…")``/``send("…")``). A renamed state or event on either side would not fail loudly: the
hook would simply never run, or the event would be consumed without effect, and the block would
stall. These tests make such a mismatch fail here instead.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil

import pytest

import rasm.platform
from rasm.platform.block import Block

from .support import BLOCKS, chart_path, load, transition_events

MODULES = [
    f"rasm.platform.{module.name}" for module in pkgutil.iter_modules(rasm.platform.__path__)
]


def sent_by(cls: type) -> set[str]:
    """The string literals in the first argument of every ``.post(...)``/``.send(...)`` call in
    ``cls``'s source (``post("a" if ok else "b")`` gives both). Event names computed at run time
    (``post(event)``) are out of reach of this check."""
    module = ast.parse(inspect.getsource(importlib.import_module(cls.__module__)))
    (tree,) = [n for n in module.body if isinstance(n, ast.ClassDef) and n.name == cls.__name__]
    names = set()
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr in ("post", "send")
            and node.args
        ):
            for leaf in ast.walk(node.args[0]):
                if isinstance(leaf, ast.Constant) and isinstance(leaf.value, str):
                    names.add(leaf.value)
    return names


def drivers() -> list[type[Block]]:
    found = []
    for module_name in MODULES:
        module = importlib.import_module(module_name)
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if issubclass(cls, Block) and cls.__module__ == module_name and cls.chart_name:
                found.append(cls)
    return found


DRIVERS = drivers()


def test_every_platform_chart_has_a_driver():
    assert {cls.chart_name for cls in DRIVERS} == set(BLOCKS)


@pytest.mark.parametrize("driver", DRIVERS, ids=lambda cls: cls.__name__)
def test_every_hook_names_a_state_of_the_chart(driver):
    chart = load(chart_path(driver.chart_name))
    hooks = {name[len("on_enter_"):] for name in dir(driver) if name.startswith("on_enter_")}
    assert hooks <= set(chart.states)


@pytest.mark.parametrize("driver", DRIVERS, ids=lambda cls: cls.__name__)
def test_every_event_the_driver_sends_is_one_its_chart_reacts_to(driver):
    chart = load(chart_path(driver.chart_name))
    sent = set().union(*(sent_by(k) for k in driver.__mro__ if k is not object))
    assert "failed" in sent  # Block's own: the check sees the calls it should
    assert sent <= transition_events(chart)
