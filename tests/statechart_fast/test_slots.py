"""The hot classes keep their step attributes in slots (read without the instance dict): a slot
is only what a read sees when no class before it in the MRO defines the same name (a class
default found first would be read instead, and the slot never)."""

from __future__ import annotations

import copy

import pytest
from sismic.io import import_from_yaml

from rasm.statechart.fast import FastInterpreter, PropertyListener
from rasm.statechart.fast_tables import ChartTables
from rasm.statechart.interpreter import Interpreter
from tests.slots import shadowed_slots

CHART = import_from_yaml("""
statechart:
  name: s
  root state:
    name: root
    initial: a
    states:
      - name: a
        transitions:
          - target: b
            event: go
      - name: b
""")

PROPERTY = import_from_yaml("""
statechart:
  name: p
  root state:
    name: root
    initial: watching
    states:
      - name: watching
        transitions:
          - target: seen
            event: state entered
            guard: event.state == 'b'
      - name: seen
""")


@pytest.mark.parametrize("klass", [FastInterpreter, Interpreter, PropertyListener, ChartTables])
def test_no_slot_is_shadowed_by_a_class_attribute(klass: type) -> None:
    assert shadowed_slots(klass) == []


def test_the_shadow_check_finds_a_shadowed_slot() -> None:
    class Base:
        __slots__ = ("_x",)

    class Mixin:
        _x = 0

    class Both(Mixin, Base):
        pass

    assert shadowed_slots(Both) == [("_x", "Base", "Mixin")]


@pytest.mark.parametrize("klass", [FastInterpreter, Interpreter])
def test_every_slot_is_set_after_construction(klass: type) -> None:
    interp = klass(CHART)
    listener = interp.bind_property_statechart(PROPERTY)
    parts = ((interp, klass), (listener, PropertyListener), (interp._tables, ChartTables))
    for obj, owner in parts:
        for base in owner.__mro__:
            for name in base.__dict__.get("__slots__", ()):
                getattr(obj, name)  # AttributeError for a slot never set


@pytest.mark.parametrize("klass", [FastInterpreter, Interpreter])
def test_a_deep_copy_runs_as_the_original(klass: type) -> None:
    interp = klass(CHART)
    interp.execute()
    clone = copy.deepcopy(interp)
    for each in (interp, clone):
        each.queue("go")
        each.execute()
    assert clone.configuration == interp.configuration == ["root", "b"]
    assert clone._configuration is not interp._configuration
