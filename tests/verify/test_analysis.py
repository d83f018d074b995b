"""The static facts the exploration is built on, found with less work: one walk per piece of code,
timer thresholds evaluated once per value of what they read."""

from __future__ import annotations

import ast

from hypothesis import given
from hypothesis import strategies as st

from rasm.statechart import load_statechart
from rasm.verify.code import _effects, _scan, _scan_code
from rasm.verify.component import ChartRun, SettableClock

# statements as chart actions write them: assignments, calls, sends, event data, introspection,
# the time, and compound statements (_scan_code walks those whole)
STATEMENTS = [
    "x = 1",
    "y = x + event.data['a']",
    "items.append(event.data.get('b'))",
    "send('go', v=x)",
    "z += time",
    "obj.attr = val",
    "del table[key]",
    "setdefault('m', 0)",
    "seen = locals()",
    "w = event.speed + event.name.count('a')",
    "if x > 2:\n    y = 3\nelse:\n    send('far')",
    "for i in range(n):\n    acc = acc + i",
    "with lock(k):\n    u = v",
    "try:\n    a = b\nexcept E:\n    c = d",
    "while c < 3:\n    c += 1",
]


@given(st.lists(st.sampled_from(STATEMENTS), min_size=1, max_size=6))
def test_scanning_an_action_statement_by_statement_finds_what_one_walk_over_it_finds(lines):
    tree = ast.parse("\n".join(lines))
    fast = _scan_code(tree)
    whole = _scan(tree)
    for name in ("reads", "writes", "data", "sends", "introspects", "reads_time"):
        assert getattr(fast, name) == getattr(whole, name), name
    assert fast.effects == _effects(tree)


def test_a_timer_threshold_follows_the_variable_it_reads(tmp_path):
    chart = tmp_path / "timer.yaml"
    chart.write_text(
        "statechart:\n  name: timer\n  preamble: limit = 1\n  root state:\n    name: root\n"
        "    initial: a\n    states:\n      - name: a\n        transitions:\n"
        "          - {target: b, guard: after(limit)}\n      - name: b\n"
    )
    clock = SettableClock()
    run = ChartRun(load_statechart(chart), clock)
    run.execute()
    clock.set(5_000_000_000)
    # a's age is kept up to the threshold: past it, every age decides the same future
    assert run.key()[3] == (("a", "after", 1_000_000_000),)
    run.context["limit"] = 3
    assert run.key()[3] == (("a", "after", 3_000_000_000),)
    run.context["limit"] = 1
    assert run.key()[3] == (("a", "after", 1_000_000_000),)
    run.context["limit"] = "soon"  # no threshold: the age is kept exactly
    assert run.key()[3] == (("a", "after", 5_000_000_000),)
