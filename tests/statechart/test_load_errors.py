"""Every validation problem sismic does not catch is reported at its file, line and column."""

from __future__ import annotations

import textwrap

import pytest

from rasm.cli import main
from rasm.errors import SourceErrors
from rasm.statechart import check_statechart, load_statechart


def problems(text: str) -> list[tuple[int, int, str]]:
    _, found = check_statechart(textwrap.dedent(text).lstrip("\n"), "chart.yaml")
    return [(p.error.location.line, p.error.location.col, p.one_line()) for p in found]


def only(text: str) -> tuple[int, int, str]:
    found = problems(text)
    assert len(found) == 1, found
    return found[0]


CASES = {
    "yaml syntax": (
        """
        statechart:
          name: x
          root state: [
        """,
        4,
        1,
        "YAML syntax error",
    ),
    "not a statechart": (
        """
        - just
        - a list
        """,
        1,
        1,
        "top-level 'statechart' key",
    ),
    "unknown top-level key": (
        """
        statechart:
          name: x
          root state:
            name: r
        extra: 1
        """,
        5,
        1,
        "unknown top-level key 'extra'",
    ),
    "missing root state": (
        """
        statechart:
          name: x
        """,
        1,
        1,
        "no 'root state'",
    ),
    "unknown state key": (
        """
        statechart:
          name: x
          root state:
            name: r
            on_entry: x = 1
        """,
        5,
        5,
        "unknown key 'on_entry' in a state",
    ),
    "unknown transition key": (
        """
        statechart:
          name: x
          root state:
            name: r
            transitions:
              - event: e
                targett: r
        """,
        7,
        9,
        "unknown key 'targett' in a transition",
    ),
    "bad state type": (
        """
        statechart:
          name: x
          root state:
            name: r
            initial: a
            states:
              - name: a
                type: finale
        """,
        8,
        15,
        "unknown state type 'finale'",
    ),
    "unknown target": (
        """
        statechart:
          name: x
          root state:
            name: r
            initial: a
            states:
              - name: a
                transitions:
                  - target: nowhere
                    event: go
        """,
        9,
        21,
        "targets unknown state 'nowhere'",
    ),
    "compound without initial": (
        """
        statechart:
          name: x
          root state:
            name: r
            states:
              - name: a
        """,
        4,
        5,
        "compound state 'r' has no 'initial'",
    ),
    "initial not a child": (
        """
        statechart:
          name: x
          root state:
            name: r
            initial: b
            states:
              - name: a
              - name: c
                transitions:
                  - target: a
                    event: e
        """,
        5,
        14,
        "initial state 'b' of 'r' is not one of its children",
    ),
    "duplicate names": (
        """
        statechart:
          name: x
          root state:
            name: r
            initial: a
            states:
              - name: a
                initial: a
                states:
                  - name: a
        """,
        10,
        19,
        "duplicate state name 'a' (first defined at line 7)",
    ),
    "guard syntax, plain scalar": (
        """
        statechart:
          name: x
          root state:
            name: r
            transitions:
              - event: e
                guard: x >> > 1
        """,
        7,
        21,
        "invalid Python expression in 'guard'",
    ),
    "guard syntax, quoted scalar": (
        """
        statechart:
          name: x
          root state:
            name: r
            transitions:
              - event: e
                guard: "x ==="
        """,
        7,
        21,
        "invalid Python expression in 'guard'",
    ),
    "guard over several lines without parentheses": (
        """
        statechart:
          name: x
          root state:
            name: r
            transitions:
              - event: e
                guard: |
                  x == 1
                  and y < 3
        """,
        9,
        11,
        "invalid Python expression in 'guard': the expression goes on over several lines, "
        "which Python reads only inside parentheses: put the whole expression in ( )",
    ),
    "guard over several lines with an error of its own": (
        """
        statechart:
          name: x
          root state:
            name: r
            transitions:
              - event: e
                guard: |
                  x ==
                  and y < 3
        """,
        8,
        15,
        "invalid Python expression in 'guard': invalid syntax",
    ),
    "action syntax, block scalar": (
        """
        statechart:
          name: x
          root state:
            name: r
            transitions:
              - event: e
                action: |
                  a = 1
                  b = = 2
        """,
        9,
        15,
        "invalid Python code in 'action'",
    ),
    "preamble syntax": (
        """
        statechart:
          name: x
          preamble: |
            import
          root state:
            name: r
        """,
        4,
        11,
        "invalid Python code in 'preamble'",
    ),
    "contract syntax": (
        """
        statechart:
          name: x
          root state:
            name: r
            contract:
              - always: x <
        """,
        6,
        17,
        "invalid Python expression in 'always'",
    ),
    "bad contract shape": (
        """
        statechart:
          name: x
          root state:
            name: r
            contract:
              - sometimes: x
        """,
        6,
        9,
        "a contract of state 'r' is one of",
    ),
    "transition on a final state": (
        """
        statechart:
          name: x
          root state:
            name: r
            initial: a
            states:
              - name: a
                type: final
                transitions:
                  - target: a
        """,
        9,
        9,
        "a final state cannot have 'transitions'",
    ),
    "history memory not a sibling": (
        """
        statechart:
          name: x
          root state:
            name: r
            initial: a
            states:
              - name: a
              - name: h
                type: shallow history
                memory: r
        """,
        10,
        17,
        "memory 'r' of history state 'h' is not a sibling",
    ),
    "bad priority": (
        """
        statechart:
          name: x
          root state:
            name: r
            transitions:
              - event: e
                priority: urgent
        """,
        7,
        19,
        "'priority' must be an integer, 'high' or 'low'",
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_each_problem_is_reported_at_its_position(case):
    text, line, col, message = CASES[case]
    found_line, found_col, found = only(text)
    assert message in found
    assert (found_line, found_col) == (line, col), found
    assert found.startswith(f"chart.yaml:{line}:{col}: ")


def test_unreachable_state_is_a_warning_that_does_not_stop_loading():
    text = """
        statechart:
          name: x
          root state:
            name: r
            initial: a
            states:
              - name: a
              - name: lonely
        """
    line, col, message = only(text)
    assert (line, col) == (8, 15) and "warning: state 'lonely' can never be entered" in message
    chart = load_statechart(text=textwrap.dedent(text), source="chart.yaml")
    assert "lonely" in chart.states


def test_states_reached_through_transitions_history_and_parallel_are_not_unreachable():
    text = """
        statechart:
          name: x
          root state:
            name: r
            initial: a
            states:
              - name: a
                transitions:
                  - target: inner
                    event: e
              - name: b
                initial: h
                states:
                  - name: h
                    type: shallow history
                    memory: b1
                  - name: b1
                  - name: inner
              - name: p
                parallel states:
                  - name: p1
                  - name: p2
            transitions:
              - target: p
                event: go
        """
    assert problems(text) == []


def test_all_problems_are_reported_in_file_order():
    text = """
        statechart:
          name: x
          root state:
            name: r
            states:
              - name: a
                transitions:
                  - target: z
                    guard: 1 +
        """
    lines = [line for line, _, _ in problems(text)]
    assert lines == sorted(lines) and len(lines) == 3


def test_load_raises_source_errors_listing_every_error():
    with pytest.raises(SourceErrors) as info:
        load_statechart(
            text="statechart:\n  name: x\n  root state:\n    name: r\n    bogus: 1\n",
            source="c.yaml",
        )
    assert [str(e).splitlines()[0] for e in info.value.errors] == [
        "c.yaml:5:5: unknown key 'bogus' in a state (expected one of: contract, description, "
        "initial, memory, name, on entry, on exit, parallel states, states, transitions, type)"
    ]


def test_cli_simulate_exits_2_naming_the_place(tmp_path, capsys):
    chart = tmp_path / "bad.yaml"
    chart.write_text(
        "statechart:\n  name: x\n  root state:\n    name: r\n    initial: nope\n"
        "    states:\n      - name: a\n"
    )
    assert main(["simulate", str(chart)]) == 2
    err = capsys.readouterr().err
    assert f"{chart}:5:14: initial state 'nope'" in err
    assert "Traceback" not in err


def test_cli_lint_exits_1_with_one_line_per_problem(tmp_path, capsys):
    chart = tmp_path / "bad.yaml"
    chart.write_text(
        "statechart:\n  name: x\n  root state:\n    name: r\n    initial: a\n"
        "    states:\n      - name: a\n        transitions:\n"
        "          - target: b\n            guard: (\n"
    )
    good = tmp_path / "good.yaml"
    good.write_text("statechart:\n  name: y\n  root state:\n    name: r\n")
    assert main(["lint", str(tmp_path)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out == [
        f"{chart}:9:21: transition of 'a' targets unknown state 'b'",
        f"{chart}:10:20: invalid Python expression in 'guard': '(' was never closed",
    ]
    assert main(["lint", str(good)]) == 0
    assert main(["lint", str(tmp_path / "missing.yaml")]) == 2


def test_two_unguarded_transitions_of_a_state_on_one_event_are_a_warning(tmp_path, capsys):
    chart = tmp_path / "twins.yaml"
    chart.write_text(
        "statechart:\n  name: t\n  root state:\n    name: r\n    initial: a\n"
        "    states:\n      - name: a\n        transitions:\n"
        "          - {target: b, event: go}\n"
        "          - {target: b, event: go, guard: 'x > 1'}\n"  # guarded: may be meant
        "          - {target: b, event: go, priority: 1}\n"  # another priority: chosen first
        "          - {target: b, event: stop}\n"
        "          - {target: b, event: go}\n"
        "      - name: b\n"
    )
    assert main(["lint", str(chart)]) == 1
    assert capsys.readouterr().out.splitlines() == [
        f"{chart}:13:25: warning: state 'a' has two transitions on 'go' and no guard on either: "
        "both are always enabled together, a non-deterministic choice that fails the step "
        "(guard one, or give them different priorities)"
    ]


def test_cli_bad_events_file_names_the_line(tmp_path, capsys):
    chart = tmp_path / "c.yaml"
    chart.write_text("statechart:\n  name: y\n  root state:\n    name: r\n")
    events = tmp_path / "events.jsonl"
    events.write_text(
        '{"time": 1, "event": "a"}\n\n{"time": 0.5, "event": "b"}\n'
        '{"time": 2, "event": 3}\nnot json\n{"time": 3, "event": "e", "data": {"name": 1}}\n'
    )
    assert main(["simulate", str(chart), "--events", str(events)]) == 2
    err = capsys.readouterr().err
    assert f"{events}:3:1: time 0.5 goes back" in err
    assert f'{events}:4:1: "event" must be a non-empty string' in err
    assert f"{events}:5:1: not JSON" in err
    assert f"{events}:6:1: data key 'name' is reserved" in err


def test_cli_events_file_context_must_be_an_object_of_variable_names(tmp_path, capsys):
    chart = tmp_path / "c.yaml"
    chart.write_text("statechart:\n  name: y\n  root state:\n    name: r\n")
    events = tmp_path / "events.jsonl"
    events.write_text(
        '{"time": 1, "event": "a", "context": [1]}\n'
        '{"time": 2, "event": "a", "context": {"not a name": 1}}\n'
        '{"time": 3, "event": "a", "context": {"lambda": 1}}\n'
        '{"time": 4, "event": "a", "contxt": {}}\n'
    )
    assert main(["simulate", str(chart), "--events", str(events)]) == 2
    err = capsys.readouterr().err
    assert f'{events}:1:1: "context" must be a JSON object' in err
    assert f"{events}:2:1: context key 'not a name' is not a variable name" in err
    assert f"{events}:3:1: context key 'lambda' is not a variable name" in err
    assert f"{events}:4:1: unknown key 'contxt' (expected time, event, data, context)" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("command", ["simulate", "graph"])
def test_cli_non_utf8_chart_exits_2_at_the_bad_byte(tmp_path, capsys, command):
    chart = tmp_path / "latin1.yaml"
    chart.write_bytes(b"statechart:\n  name: x\n  root state:\n    name: caf\xe9\n")
    assert main([command, str(chart)]) == 2
    err = capsys.readouterr().err
    assert f"{chart}:4:14: not a UTF-8 text file" in err
    assert "Traceback" not in err


def test_cli_events_file_with_reserved_key_huge_time_or_bad_bytes_exits_2(tmp_path, capsys):
    chart = tmp_path / "c.yaml"
    chart.write_text("statechart:\n  name: y\n  root state:\n    name: r\n")
    events = tmp_path / "events.jsonl"
    events.write_text(
        '{"time": 1, "event": "a", "data": {"self": 1}}\n'
        '{"time": 2, "event": "a", "data": {"event_or_name": 1}}\n'
        '{"time": 1' + "0" * 400 + ', "event": "b"}\n'
    )
    assert main(["simulate", str(chart), "--events", str(events)]) == 2
    err = capsys.readouterr().err
    assert f"{events}:1:1: data key 'self' is reserved" in err
    assert f"{events}:2:1: data key 'event_or_name' is reserved" in err
    assert f'{events}:3:1: "time" must be a finite number' in err
    assert "Traceback" not in err
    events.write_bytes(b'{"time": 1, "event": "a"}\n{"time": 2, "event": "caf\xe9"}\n')
    assert main(["simulate", str(chart), "--events", str(events)]) == 2
    err = capsys.readouterr().err
    assert f"{events}:2:26: not a UTF-8 text file" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("until", ["-1", "nan", "inf", "1e999"])
def test_cli_simulate_until_must_be_a_finite_time(tmp_path, capsys, until):
    chart = tmp_path / "tick.yaml"
    chart.write_text(
        "statechart:\n  name: t\n  root state:\n    name: r\n    initial: a\n    states:\n"
        "      - name: a\n        transitions:\n          - target: a\n"
        "            guard: after(1)\n"
    )
    assert main(["simulate", str(chart), f"--until={until}"]) == 2
    err = capsys.readouterr().err
    assert "--until must be a finite time in seconds" in err
    assert "Traceback" not in err


def test_cli_simulate_stops_a_chart_that_never_becomes_stable(tmp_path, capsys):
    chart = tmp_path / "loop.yaml"
    chart.write_text(
        "statechart:\n  name: loop\n  root state:\n    name: r\n    initial: a\n    states:\n"
        "      - name: a\n        transitions:\n          - target: b\n"
        "      - name: b\n        transitions:\n          - target: a\n"
    )
    assert main(["simulate", str(chart), "--format", "json"]) == 1
    captured = capsys.readouterr()
    assert "did not become stable after 10000 steps at time 0" in captured.err
    assert len(captured.out.splitlines()) == 10_000


def test_a_list_where_a_single_value_belongs_is_named_in_words():
    with pytest.raises(SourceErrors) as info:
        load_statechart(
            text="statechart:\n  name: [1]\n  root state:\n    name: r\n", source="c.yaml"
        )
    assert str(info.value.errors[0]).splitlines()[0] == (
        "c.yaml:2:9: 'name' must be a single value, not a list"
    )


def test_cli_simulate_with_a_failing_preamble_exits_2_at_the_preamble(tmp_path, capsys):
    chart = tmp_path / "c.yaml"
    chart.write_text(
        "statechart:\n  name: c\n  preamble: x = 1 / 0\n  root state:\n    name: r\n"
    )
    assert main(["simulate", str(chart)]) == 2
    err = capsys.readouterr().err
    assert f"{chart}:3:13: the chart's preamble failed: ZeroDivisionError: division by zero" in err
    assert "Traceback" not in err
