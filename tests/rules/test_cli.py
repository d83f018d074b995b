"""``rasm verify-rules``: output formats and exit codes 0 / 1 / 2."""

from __future__ import annotations

import json

import pytest

from rasm.cli import main

CONSISTENT = """\
variables:
  velocity: {type: real, min: 0, max: 1.0}
  mode:     {type: enum, values: [navigate, dock, idle]}
rules:
  - name: slow_docking
    when: mode == "dock"
    require: velocity <= 0.1
  - name: slower_docking
    when: mode == "dock"
    require: velocity <= 0.5
"""

INCONSISTENT = CONSISTENT + """\
  - name: fast_docking
    when: mode == "dock"
    require: velocity >= 0.2
  - name: too_fast
    when: mode == "idle"
    require: velocity > 1.5
  - name: never
    when: velocity > 2
    require: mode == "idle"
"""


@pytest.fixture
def write(tmp_path):
    def write(text: str, name: str = "rules.yaml") -> str:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return str(path)

    return write


def test_consistent_rules_exit_0(write, capsys):
    assert main(["verify-rules", write(CONSISTENT)]) == 0
    out = capsys.readouterr().out
    assert "redundant: slower_docking: implied by slow_docking" in out
    assert "2 rules, consistent" in out


def test_inconsistent_rules_exit_1_with_the_spec_json(write, capsys):
    assert main(["verify-rules", write(INCONSISTENT), "--format", "json"]) == 1
    data = json.loads(capsys.readouterr().out)
    assert list(data) == ["consistent", "unsatisfiable", "conflicts", "redundant", "dead",
                          "witnesses"]
    assert data["consistent"] is False
    assert data["unsatisfiable"] == ["too_fast"]
    assert data["conflicts"] == [["slow_docking", "fast_docking"]]
    assert data["redundant"] == ["slower_docking"]
    assert data["dead"] == ["never"]
    witness = data["witnesses"]["conflicts"][0]
    assert witness["rules"] == ["slow_docking", "fast_docking"]
    assert witness["context"]["mode"] == "dock"
    assert data["witnesses"]["unsatisfiable"]["too_fast"]["mode"] == "idle"
    assert data["witnesses"]["redundant"] == {"slower_docking": {"implied_by": ["slow_docking"]}}


def test_inconsistent_rules_text_report(write, capsys):
    assert main(["verify-rules", write(INCONSISTENT)]) == 1
    out = capsys.readouterr().out
    assert "conflict: slow_docking, fast_docking" in out
    assert "unsatisfiable: too_fast" in out
    assert "dead: never" in out
    assert "inconsistent" in out.splitlines()[-1]


def test_bad_input_exits_2_with_file_line_and_column(write, capsys):
    path = write(CONSISTENT.replace('mode == "dock"', 'mode == "fly"', 1))
    assert main(["verify-rules", path]) == 2
    err = capsys.readouterr().err
    assert f"{path}:6:19: 'fly' is not a value of mode" in err
    assert "Traceback" not in err


def test_a_missing_file_exits_2(tmp_path, capsys):
    assert main(["verify-rules", str(tmp_path / "absent.yaml")]) == 2
    assert "absent.yaml" in capsys.readouterr().err


def test_an_empty_rule_list_is_consistent(write, capsys):
    assert main(["verify-rules", write("variables: {}\nrules: []\n"), "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["consistent"] is True


def test_redundant_and_dead_rules_alone_keep_a_set_consistent(write, capsys):
    text = CONSISTENT + "  - name: never\n    when: velocity > 2\n    require: velocity < 0\n"
    assert main(["verify-rules", write(text), "--format", "json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["dead"] == ["never"] and data["redundant"] == ["slower_docking"]


PROPS = """\
let docking = mode == "dock"
property dock_speed:
    always (docking -> velocity <= 0.2)
property nav_speed:
    always (mode == "navigate" -> velocity <= 0.5)
property timely:
    always (velocity > 0.5 -> eventually[0, 2s] mode == "idle")
"""


def test_against_finds_a_plan_the_rules_admit_that_violates_an_invariant(write, capsys):
    rules, props = write(CONSISTENT), write(PROPS, "props.rv")
    assert main(["verify-rules", rules, "--against", props, "--format", "json"]) == 1
    against = {v["property"]: v for v in json.loads(capsys.readouterr().out)["against"]}
    assert against["dock_speed"]["admitted_violation"] is False
    nav = against["nav_speed"]
    assert nav["admitted_violation"] is True
    assert nav["witness"]["mode"] == "navigate" and nav["witness"]["velocity"] > 0.5
    assert "skipped" in against["timely"]


def test_against_exits_0_when_the_rules_enforce_every_invariant(write, capsys):
    rules, props = write(CONSISTENT), write(PROPS.split("property nav_speed")[0], "props.rv")
    assert main(["verify-rules", rules, "--against", props]) == 0
    assert "dock_speed: every plan the rules admit satisfies it" in capsys.readouterr().out


def test_against_a_bad_property_file_exits_2(write, capsys):
    rules, props = write(CONSISTENT), write("property p:\n    always (velocity <)\n", "props.rv")
    assert main(["verify-rules", rules, "--against", props]) == 2
    assert f"{props}:2:" in capsys.readouterr().err


def test_the_summary_says_its_counts_in_words(write, capsys):
    one = ("variables:\n  v: {type: int, min: 0, max: 3}\nrules:\n"
           "  - name: a\n    require: v <= 1\n  - name: b\n    require: v >= 2\n")
    assert main(["verify-rules", write(one)]) == 1
    out = capsys.readouterr().out
    assert out.endswith(": 2 rules, inconsistent: 0 unsatisfiable, 1 conflict, 0 redundant, "
                        "0 dead\n")
    single = ("variables:\n  v: {type: int, min: 0, max: 3}\nrules:\n"
              "  - name: a\n    require: true\n")
    assert main(["verify-rules", write(single)]) == 0
    assert ": 1 rule, consistent: 0 unsatisfiable, 0 conflicts," in capsys.readouterr().out
