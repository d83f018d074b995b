"""The charts the fast-path tests share: the shipped ones, and small ones written for a case."""

from __future__ import annotations

from sismic.io import import_from_yaml
from sismic.model import Statechart, Transition

from rasm.resources import data_dir

STATECHARTS = data_dir("statecharts")
MONITORS = data_dir("monitors")


def chart(text: str) -> Statechart:
    return import_from_yaml(text)


def cycle(*, shortcut: bool = False) -> Statechart:
    """a -> b -> c -> a, one step per event ``n``; with ``shortcut``, a -> c on ``m`` too."""
    statechart = chart("""
statechart:
  name: cycle
  root state:
    name: root
    initial: a
    states:
    - name: a
      transitions:
      - {target: b, event: n}
    - name: b
      transitions:
      - {target: c, event: n}
    - name: c
      transitions:
      - {target: a, event: n}
""")
    if shortcut:
        statechart.add_transition(Transition("a", "c", event="m"))
    return statechart


def toggle() -> Statechart:
    """a <-> b on every event ``n``."""
    return chart("""
statechart:
  name: toggle
  root state:
    name: root
    initial: a
    states:
    - name: a
      transitions:
      - {target: b, event: n}
    - name: b
      transitions:
      - {target: a, event: n}
""")


def never_b_twice() -> Statechart:
    """A property statechart: ``b`` must not be entered twice without ``c`` in between."""
    return chart("""
statechart:
  name: never b twice
  root state:
    name: root
    initial: idle
    states:
    - name: idle
      transitions:
      - {target: seen, event: state entered, guard: event.state == 'b'}
    - name: seen
      transitions:
      - {target: fail, event: state entered, guard: event.state == 'b'}
      - {target: idle, event: state entered, guard: event.state == 'c'}
    - name: fail
      type: final
""")
