"""Hostile files each reproduced once: a clear message at file:line:col and exit 2, no traceback.

The nesting cases run the real command in a subprocess (the recursion limit is what broke);
the others call the command line's ``main()`` in-process, as the other command-line tests do.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from rasm.cli import main
from rasm.yamltext import MAX_ALIAS_VALUES, MAX_DEPTH

from .support import assert_refused_at, chart_nested, position, rasm

BIG = "1" * 5000  # past Python's 4300-digit limit on int() of a text


def run_main(capsys: pytest.CaptureFixture[str], *args: str | Path) -> tuple[int, str]:
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.err + out.out


# ----------------------------------------------------------------------------- nesting


@pytest.fixture(scope="module")
def deep_chart(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    text = chart_nested(150)
    path = tmp_path_factory.mktemp("deep") / "deep.yaml"
    path.write_text(text)
    # each state takes two levels (its mapping in its parent's 'states' list) below three
    deepest = (MAX_DEPTH - 3) // 2 + 1  # the first state past the limit
    return path, f"{path}:{position(text, f'name: s{deepest}')}"


@pytest.mark.parametrize("command", [["simulate"], ["graph", "--format", "dot"]])
def test_a_chart_nested_150_states_deep_is_refused_at_the_first_state_too_deep(
    deep_chart: tuple[Path, str], command: list[str]
) -> None:
    path, place = deep_chart
    code, out = rasm(command[0], path, *command[1:])
    assert_refused_at(code, out, place, f"nested more than {MAX_DEPTH} levels deep")


def test_lint_reports_a_chart_nested_too_deep_as_a_problem_at_its_place(
    deep_chart: tuple[Path, str],
) -> None:
    path, place = deep_chart
    code, out = rasm("lint", path)
    assert "Traceback" not in out
    assert code == 1  # lint's exit code for a file with problems
    assert out.startswith(f"{place}: nested more than {MAX_DEPTH} levels deep"), out


def test_a_chart_just_within_the_nesting_limit_runs(tmp_path: Path) -> None:
    path = tmp_path / "deep.yaml"
    path.write_text(chart_nested((MAX_DEPTH - 3) // 2))
    code, out = rasm("simulate", path, "--format", "json")
    assert code == 0, out
    assert '"s47"' in out


@pytest.mark.parametrize("command", [["simulate"], ["graph", "--format", "mermaid"], ["lint"]])
def test_yaml_nested_500_deep_is_refused_where_it_gets_too_deep(
    tmp_path: Path, command: list[str]
) -> None:
    path = tmp_path / "flow.yaml"
    path.write_text("statechart: " + "[" * 500 + "]" * 500 + "\n")
    code, out = rasm(command[0], path, *command[1:])
    place = f"{path}:1:{len('statechart: ') + MAX_DEPTH}"
    if command == ["lint"]:
        assert "Traceback" not in out and code == 1 and out.startswith(place), out
    else:
        assert_refused_at(code, out, place, "nested more than")


def test_aliases_of_aliases_are_refused_at_the_alias_past_the_limit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lines = ["a: &a [" + ", ".join(["x"] * 10) + "]"]
    for name, previous in zip("bcdefg", "abcdef", strict=True):
        lines.append(f"{name}: &{name} [" + ", ".join([f"*{previous}"] * 10) + "]")
    text = "\n".join(lines) + "\nstatechart: {name: x, root state: {name: r}}\n"
    path = tmp_path / "laughs.yaml"
    path.write_text(text)
    code, out = run_main(capsys, "simulate", path)
    # *a stands for 11 values, *b 111, *c 1111, *d 11111: lines 2-4 repeat 12330 values and
    # the 8th *d of line 5 takes the total past 100000
    place = f"{path}:5:{len('e: &e [') + 7 * len('*d, ') + 1}"
    assert_refused_at(code, out, place, f"more than {MAX_ALIAS_VALUES} values")


# ----------------------------------------------------------------------------- huge integers


def test_a_huge_integer_in_a_property_is_refused_at_the_literal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    props = tmp_path / "p.rv"
    props.write_text(f"input x: int\nproperty p:\n    always (x <= {BIG})\n")
    trace = tmp_path / "t.jsonl"
    trace.write_text('{"time": 0, "x": 1}\n')
    code, out = run_main(capsys, "check", props, trace)
    assert_refused_at(code, out, f"{props}:3:18", "too large")


def test_a_huge_integer_default_is_refused_at_the_literal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    props = tmp_path / "p.rv"
    props.write_text(f"input x: int = {BIG}\nproperty p:\n    always (x <= 1)\n")
    code, out = run_main(capsys, "check", props, props)
    assert_refused_at(code, out, f"{props}:1:16", "too large")


def test_a_long_integer_with_leading_zeros_is_its_value(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    props = tmp_path / "p.rv"
    props.write_text(f"input x: int\nproperty p:\n    always (x <= {'0' * 5000}7)\n")
    trace = tmp_path / "t.jsonl"
    trace.write_text('{"time": 0, "x": 7}\n{"time": 1, "x": 8}\n')
    code, out = run_main(capsys, "check", props, trace)
    assert code == 1 and "Traceback" not in out  # violated at t=1, where x = 8 > 7
    assert "violated" in out


def test_a_huge_integer_in_a_rules_file_is_refused_at_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rules = tmp_path / "r.yaml"
    rules.write_text(f"variables:\n  x: {{type: int, min: 0, max: {BIG}}}\nrules: []\n")
    code, out = run_main(capsys, "verify-rules", rules)
    assert_refused_at(code, out, f"{rules}:2:31", "integer with 5000 digits is too long")

    rules.write_text(
        f"variables:\n  x: {{type: int}}\nrules:\n  - name: r\n    require: x <= {BIG}\n"
    )
    code, out = run_main(capsys, "verify-rules", rules)
    assert_refused_at(code, out, f"{rules}:5:19", "too large")


# ----------------------------------------------------------------------------- odd characters


def test_a_nul_byte_in_a_string_literal_of_a_property_is_refused_at_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    props = tmp_path / "p.rv"
    props.write_text('input mode: str\nproperty p:\n    always (mode == "a\x00b")\n')
    code, out = run_main(capsys, "check", props, props)
    assert_refused_at(code, out, f"{props}:3:23", "NUL")


def test_an_escape_python_cannot_decode_is_refused_at_its_string(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    props = tmp_path / "p.rv"
    props.write_text('input mode: str\nproperty p:\n    always (mode == "\\N{no such name}")\n')
    code, out = run_main(capsys, "lint", props)
    assert code == 1 and "Traceback" not in out
    assert f"{props}:3:21: invalid string literal" in out, out


def test_a_nul_byte_in_a_chart_is_refused_at_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    chart = tmp_path / "c.yaml"
    chart.write_text("statechart:\n  name: c\x00d\n  root state:\n    name: r\n")
    code, out = run_main(capsys, "simulate", chart)
    assert_refused_at(code, out, f"{chart}:2:10", "U+0000 is not allowed")


@pytest.mark.parametrize(
    "command,file,words",
    [
        (["simulate"], "chart.yaml", "a statechart file is a mapping"),
        (["graph", "--format", "dot"], "chart.yaml", "a statechart file is a mapping"),
        (["verify-rules"], "rules.yaml", "a rules file is a mapping"),
        (["run"], "app/app.yaml", "an app manifest is a mapping"),
    ],
)
def test_a_scalar_yaml_document_is_refused_at_its_line_and_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: list[str], file: str, words: str
) -> None:
    path = tmp_path / file
    path.parent.mkdir(exist_ok=True)
    path.write_text("# just a number\n\n42\n")
    target = path.parent if command == ["run"] else path
    code, out = run_main(capsys, command[0], target, *command[1:])
    assert_refused_at(code, out, f"{path}:3:1", words)


def test_a_rules_file_that_is_not_utf8_is_refused_at_its_first_bad_byte(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rules = tmp_path / "r.yaml"
    rules.write_bytes(
        b"variables:\n  x: {type: int}\nrules:\n  - name: r\xff\n    require: x <= 3\n"
    )
    code, out = run_main(capsys, "verify-rules", rules)
    assert_refused_at(code, out, f"{rules}:4:12", "not a UTF-8 text file")
    code, out = run_main(capsys, "lint", rules)
    assert code == 1 and out.startswith(f"{rules}:4:12: not a UTF-8 text file"), out


def test_a_date_that_does_not_exist_is_refused_at_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    chart = tmp_path / "c.yaml"
    chart.write_text("statechart:\n  name: x\n  description: 2021-02-30\n  root state: {name: r}\n")
    code, out = run_main(capsys, "simulate", chart)
    assert_refused_at(code, out, f"{chart}:3:16", "day is out of range")


# ----------------------------------------------------------------------------- history as initial

HISTORY_ROOT = """\
statechart:
  name: hist
  root state:
    name: root
    initial: h
    states:
      - name: h
        type: shallow history
      - name: a
"""


def test_lint_rejects_a_history_state_as_the_roots_initial(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    chart = tmp_path / "c.yaml"
    chart.write_text(HISTORY_ROOT)
    code, out = run_main(capsys, "lint", chart)
    assert code == 1
    assert out.startswith(f"{chart}:5:14: the root state's 'initial' is the history state 'h'")
    # what it saves the user from: the chart fails at its first step (now: refused up front)
    code, out = run_main(capsys, "simulate", chart)
    assert_refused_at(code, out, f"{chart}:5:14", "name the state to start in")


def test_a_nested_initial_history_without_memory_is_a_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    chart = tmp_path / "c.yaml"
    nested = HISTORY_ROOT.replace("initial: h", "initial: p").replace(
        "      - name: h\n        type: shallow history\n      - name: a\n",
        "      - name: p\n        initial: h\n        states:\n"
        "          - name: h\n            type: deep history\n          - name: a\n",
    )
    chart.write_text(nested)
    code, out = run_main(capsys, "lint", chart)
    assert code == 1
    assert f"{chart}:8:18: warning: initial state 'h' of 'p' is a history state without" in out
    remembers = "type: deep history\n            memory: a"
    chart.write_text(nested.replace("type: deep history", remembers))
    assert run_main(capsys, "lint", chart) == (0, "")


# ----------------------------------------------------------------------------- z3 gives up

REAL_NONLINEAR = """\
variables:
  x: {type: real}
  y: {type: real}
  z: {type: real}
rules:
  - name: curved
    require: x*x*x*y - y*y*z*x + z*z*z*z*x*y > 3
  - name: linear
    require: x + y <= 10
"""


@pytest.fixture
def impatient_z3(monkeypatch: pytest.MonkeyPatch) -> None:
    """z3 with a 1 ms limit per question: it gives up on nonlinear rules at once."""
    import rasm.rules.mus

    monkeypatch.setattr(rasm.rules.mus, "SOLVER_TIMEOUT_MS", 1)


def test_z3_giving_up_on_real_rules_names_the_rule_and_does_not_blame_ints(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], impatient_z3: None
) -> None:
    rules = tmp_path / "r.yaml"
    rules.write_text(REAL_NONLINEAR)
    code, out = run_main(capsys, "verify-rules", rules)
    assert_refused_at(code, out, f"{rules}:{position(REAL_NONLINEAR, 'name: curved')}",
                      "z3 could not decide rule 'curved'")
    assert "nonlinear real arithmetic" in out and "int" not in out


def test_z3_giving_up_on_int_rules_says_why(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], impatient_z3: None
) -> None:
    text = REAL_NONLINEAR.replace("type: real", "type: int")
    rules = tmp_path / "r.yaml"
    rules.write_text(text)
    code, out = run_main(capsys, "verify-rules", rules)
    assert_refused_at(code, out, f"{rules}:{position(text, 'name: curved')}", "int variables")


def test_z3_giving_up_on_a_property_checked_against_the_rules_names_the_property(
    impatient_z3: None,
) -> None:
    from rasm.rules import parse_rules
    from rasm.rules.against import check_properties
    from rasm.rules.verify import Undecided

    rules = parse_rules(
        "variables:\n  a: {type: int}\n  b: {type: int}\n  c: {type: int}\nrules:\n"
        "  - name: positive\n    require: a > 0 and b > 0 and c > 0\n",
        source="r.yaml",
    )
    props = "property fermat:\n    always (a*a*a + b*b*b != c*c*c)\n"
    with pytest.raises(Undecided) as caught:
        check_properties(rules, props, source="p.rv")
    assert str(caught.value).startswith("p.rv:1:10: z3 could not decide property 'fermat'")
    assert "int variables" in str(caught.value)


@pytest.mark.parametrize(
    "scenario,words",
    [
        ("[" * 100_000, "nested too deeply"),  # not a file name: too long for one
        ('{"a": ' + BIG + "}", "an integer longer than 4300 digits"),
    ],
)
def test_a_hostile_scenario_is_refused(
    capsys: pytest.CaptureFixture[str], scenario: str, words: str
) -> None:
    from .support import ROOT

    code, out = run_main(
        capsys, "run", ROOT / "examples" / "hotbox", "--clock", "simulated", "--duration", "1",
        "--scenario", scenario,
    )
    assert_refused_at(code, out, "--scenario:1:1", words)
    assert len(out) < 500  # the argument is not echoed back whole


def test_control_characters_from_a_file_reach_the_terminal_escaped(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    chart = tmp_path / "c.yaml"
    chart.write_text('statechart:\n  name: x\n  "\\e[2J": 1\n  root state:\n    name: r\n')
    for command in (["lint"], ["simulate"]):
        code, out = run_main(capsys, command[0], chart)
        assert code in (1, 2)
        assert "\x1b" not in out and "unknown key '\\x1b[2J'" in out, out


@pytest.mark.parametrize(
    "line,words",
    [
        ('{"time": ' + BIG + ', "x": 1}', "an integer longer than 4300 digits"),
        ('{"time": 0, "x": ' + "[" * 5000 + "]" * 5000 + "}", "nested too deeply"),
    ],
)
def test_a_hostile_trace_line_is_refused_at_its_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, line: str, words: str
) -> None:
    props = tmp_path / "p.rv"
    props.write_text("input x: float\nproperty p: always (avg[0, 5s](x) < 3)\n")
    trace = tmp_path / "t.jsonl"
    trace.write_text('{"time": 0, "x": 1}\n' + line + "\n")
    code, out = run_main(capsys, "check", props, trace)
    assert_refused_at(code, out, f"{trace}:2:1", words)
