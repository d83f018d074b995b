"""Every error path of the rules loader names the file, line and column."""

from __future__ import annotations

import pytest

from rasm.errors import SourceError, SourceErrors
from rasm.rules import load_rules, parse_rules

HEAD_X = "variables:\n  x: {type: int, min: 0, max: 5}\nrules:\n  - name: r\n"
HEAD_MODE = "variables:\n  mode: {type: enum, values: [dock, idle]}\nrules:\n  - name: r\n"


def errors_of(text: str) -> list[SourceError]:
    with pytest.raises((SourceError, SourceErrors)) as info:
        parse_rules(text, source="r.yaml")
    exc = info.value
    return exc.errors if isinstance(exc, SourceErrors) else [exc]


CASES = [
    # (name, text, "line:col", words in the message)
    ("yaml syntax", "variables:\n  x: {type: int\nrules: []\n", "3:6", "YAML syntax error"),
    ("yaml duplicate key", "variables:\n  x: {type: int}\n  x: {type: real}\nrules: []\n",
     "3:3", "duplicate key"),
    ("not a mapping", "- a\n- b\n", "1:1", "not a list"),
    ("empty file", "", "1:1", "empty file"),
    ("unknown top key", "variables: {}\nrules: []\nrulez: []\n", "3:1", "unknown key 'rulez'"),
    ("rules not a list", "variables: {}\nrules: {a: 1}\n", "2:8", "must be a list"),
    ("variables not a mapping", "variables: [x]\nrules: []\n", "1:12", "must be a mapping"),
    ("unknown type", "variables:\n  x: {type: float32}\nrules: []\n", "2:13",
     "unknown type 'float32'"),
    ("missing type", "variables:\n  x: {min: 1}\nrules: []\n", "2:6", "missing 'type'"),
    ("empty domain", "variables:\n  x: {type: real, min: 2, max: 1}\nrules: []\n", "2:24",
     "empty domain"),
    ("bound not a number", "variables:\n  x: {type: real, max: high}\nrules: []\n", "2:24",
     "finite number"),
    ("int with fractional bound", "variables:\n  x: {type: int, min: 0.5}\nrules: []\n", "2:23",
     "must be an integer"),
    ("enum without values", "variables:\n  m: {type: enum}\nrules: []\n", "2:13",
     "needs 'values'"),
    ("enum value not a string", "variables:\n  m: {type: enum, values: [a, 1]}\nrules: []\n",
     "2:31", "must be a non-empty string"),
    ("duplicate enum value", "variables:\n  m: {type: enum, values: [a, a]}\nrules: []\n",
     "2:31", "duplicate enum value"),
    ("min on an enum", "variables:\n  m: {type: enum, values: [a], min: 0}\nrules: []\n",
     "2:32", "only to real and int"),
    ("values on a bool", "variables:\n  b: {type: bool, values: [a]}\nrules: []\n", "2:19",
     "only to enum"),
    ("unknown variable key", "variables:\n  x: {type: int, step: 1}\nrules: []\n", "2:18",
     "unknown key 'step'"),
    ("reserved variable name", "variables:\n  time: {type: real}\nrules: []\n", "2:3",
     "reserved"),
    ("rule not a mapping", "variables: {}\nrules:\n  - just text\n", "3:5", "expected a mapping"),
    ("missing name", "variables:\n  x: {type: int}\nrules:\n  - require: x > 1\n", "4:5",
     "missing 'name'"),
    ("missing require", HEAD_X + "    when: x > 1\n", "4:5", "missing 'require'"),
    ("unknown rule key", HEAD_X + "    require: x > 1\n    unless: x < 0\n", "6:5",
     "unknown key 'unless'"),
    ("require not a condition value", HEAD_X + "    require: 3\n", "5:14",
     "must be a condition"),
    ("empty require", HEAD_X + "    require: ''\n", "5:14", "is empty"),
    ("syntax error", HEAD_X + "    require: x > > 1\n", "5:18", "unexpected '>'"),
    ("unknown variable", HEAD_X + "    require: y > 1\n", "5:14", "unknown variable 'y'"),
    ("unknown variable in quotes", HEAD_X + '    require: "x >= y"\n', "5:20",
     "unknown variable 'y'"),
    ("unknown variable in a block", HEAD_X + "    require: |\n      x >=\n        zz\n", "7:9",
     "unknown variable 'zz'"),
    ("bare enum value", HEAD_MODE + "    require: mode == dock\n", "5:22",
     'written as strings, e.g. mode == "dock"'),
    ("enum value outside the domain", HEAD_MODE + '    require: mode == "fly"\n', "5:22",
     "'fly' is not a value of mode"),
    ("enum compared with a number", HEAD_MODE + "    require: mode == 1\n", "5:14",
     "cannot compare an enum value with a number"),
    ("enum ordered", HEAD_MODE + "    require: mode > 1\n", "5:14", "orders numbers only"),
    ("arithmetic on an enum", HEAD_MODE + "    when: mode + 1 == 2\n    require: true\n", "5:11",
     "arithmetic on an enum value"),
    ("enum on the right of arithmetic", HEAD_MODE + "    require: 1 + mode > 1\n", "5:18",
     "arithmetic on an enum value"),
    ("bool ordered", "variables:\n  b: {type: bool}\nrules:\n  - name: r\n    require: 1 < b\n",
     "5:18", "orders numbers only, not a condition"),
    ("not a condition", HEAD_X + "    require: x + 1\n", "5:14", "must be a condition"),
    ("temporal operator", HEAD_X + "    require: eventually[0, 1] x > 1\n", "5:14",
     "temporal operator"),
    ("prev", HEAD_X + "    require: prev(x) > 1\n", "5:14", "temporal operator"),
    ("unknown function", HEAD_X + "    require: sqrt(x) > 1\n", "5:14", "unknown function"),
    ("wrong arity", HEAD_X + "    require: abs(x, x) > 1\n", "5:14", "takes 1 argument"),
    ("and on numbers", HEAD_X + "    require: x and true\n", "5:14", "'and' needs conditions"),
    ("duplicate rule name",
     HEAD_X + "    require: x > 1\n  - name: r\n    require: x < 1\n", "6:11",
     "duplicate rule name 'r' (first defined at r.yaml:4:11)"),
]


@pytest.mark.parametrize(("text", "where", "words"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_error_names_file_line_and_column(text, where, words):
    errors = errors_of(text)
    matching = [e for e in errors if words in e.message]
    assert matching, [str(e) for e in errors]
    error = matching[0]
    assert f"{error.location.line}:{error.location.col}" == where
    assert str(error).startswith(f"r.yaml:{where}: ")


def test_independent_problems_are_all_reported():
    text = HEAD_X + "    require: y > 1\n  - name: s\n    require: z < 1\n"
    errors = errors_of(text)
    assert [(e.location.line, e.location.col) for e in errors] == [(5, 14), (7, 14)]


def test_a_refused_declaration_is_reported_once_not_again_at_every_use():
    # x is declared, with an empty domain: its uses are not "unknown variable" errors too
    text = (
        "variables:\n  x: {type: real, min: 2, max: 1}\n  y: {type: real}\nrules:\n"
        "  - name: r\n    require: x <= 0.1 and y > 0\n  - name: s\n    require: z > 1\n"
    )
    errors = errors_of(text)
    assert [(e.location.line, e.location.col) for e in errors] == [(2, 24), (8, 14)]
    assert "empty domain" in errors[0].message
    assert "unknown variable 'z'" in errors[1].message


def test_errors_carry_a_marked_excerpt():
    (error,) = errors_of(HEAD_X + "    require: y > 1\n")
    assert error.excerpt.splitlines() == ["        require: y > 1", "                 ^"]


def test_a_valid_file_loads_with_domains_and_defaults(tmp_path):
    path = tmp_path / "rules.yaml"
    path.write_text(
        "variables:\n"
        "  velocity: {type: real, min: 0, max: 1.0}\n"
        "  stops: {type: int, min: 0, max: 10}\n"
        "  mode: {type: enum, values: [navigate, dock, idle]}\n"
        "  armed: {type: bool}\n"
        "rules:\n"
        "  - name: slow_docking\n"
        '    when: mode == "dock"\n'
        "    require: velocity <= 0.1\n"
        "  - name: disarmed\n"
        "    require: not armed or stops < 3\n",
        encoding="utf-8",
    )
    rules = load_rules(path)
    assert rules.names == ["slow_docking", "disarmed"]
    assert rules.variables["velocity"].maximum == 1.0
    assert rules.variables["mode"].values == ("navigate", "dock", "idle")
    first, second = rules.rules
    assert first.when_text == 'mode == "dock"' and first.reads == {"mode", "velocity"}
    assert second.when is None and second.when_text == "true"
    assert (first.location.line, first.location.col) == (7, 5)


def test_an_unreadable_file_is_a_source_error(tmp_path):
    with pytest.raises(SourceError) as info:
        load_rules(tmp_path / "missing.yaml")
    assert "missing.yaml" in str(info.value)


def test_yaml_booleans_are_conditions():
    rules = parse_rules(HEAD_X + "    when: true\n    require: false\n", source="r.yaml")
    assert rules.rules[0].require_text == "false"
