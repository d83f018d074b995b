"""Bad charts, environments and property files: exit 2 at file:line:col, never a traceback."""

from __future__ import annotations

import pytest

from rasm.cli import main

CHART = """
statechart:
  name: door
  root state:
    name: root
    initial: closed
    states:
      - name: closed
        transitions:
          - target: open
            event: open
      - name: open
        transitions:
          - target: closed
            event: close
"""

CASES = {
    # name: (file it goes in, its text, where the error is, words of the message)
    "env not a mapping": ("env", "- open\n", "env.yaml:1:1", "a mapping with events: and clock:"),
    "env unknown key": ("env", "events: [open]\nclocks: [1]\n", "env.yaml:2:1", "unknown key"),
    "env events not a list": ("env", "events: 5\n", "env.yaml:1:9", "a list of event names"),
    "env event without name": ("env", "events:\n  - data: {v: [1]}\n", "env.yaml:2:5",
                               "needs a name"),
    "env empty domain": ("env", "events:\n  - name: open\n    data: {v: []}\n", "env.yaml:3:15",
                         "non-empty list"),
    "env reserved data key": ("env", "events:\n  - name: open\n    data: {delay: [1]}\n",
                              "env.yaml:3:12", "reserved by sismic"),
    "env negative clock": ("env", "events: [open]\nclock: [0.5, -1]\n", "env.yaml:2:14",
                           "positive number of seconds"),
    "env yaml syntax": ("env", "events: [open\n", "env.yaml:2:1", ""),
    "property future operator": ("rv", "property p: eventually[0, 1] in_state(\"open\")\n",
                                 "p.rv:1:13", "past-time operators only"),
    "property unknown state": ("rv", "property p: always not in_state(\"opn\")\n", "p.rv:1:24",
                               "not a state of the chart"),
    "property unknown event": ("rv", "property p: once received(\"shut\")\n", "p.rv:1:18",
                               "not an event the environment or the chart sends"),
    "property bad argument": ("rv", "property p: in_state(3)\n", "p.rv:1:13",
                              "one name in quotes"),
    "property syntax": ("rv", "property p: once (\n", "p.rv:1:19", "expected an expression"),
    "property file without property": ("rv", "input x: int\n", "p.rv:1:1", "no property"),
    "chart without initial state": ("chart", CHART.replace("initial: closed", "initial: ajar"),
                                    "chart.yaml:6:14", "ajar"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_is_exit_2_at_its_place(case, tmp_path, capsys, monkeypatch):
    kind, text, where, words = CASES[case]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "chart.yaml").write_text(text if kind == "chart" else CHART)
    args = ["verify", "chart.yaml"]
    if kind == "env":
        (tmp_path / "env.yaml").write_text(text)
        args += ["--env", "env.yaml"]
    if kind == "rv":
        (tmp_path / "p.rv").write_text(text)
        args += ["--properties", "p.rv"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"rasm: {where}: " in err, err
    assert words in err
    assert "Traceback" not in err


@pytest.mark.parametrize("args, words", [
    (["verify", "nothere.yaml"], "no such chart or app"),
    (["verify", "chart.yaml", "--max-states", "0"], "--max-states must be at least 1"),
    (["verify", "chart.yaml", "--env", "nothere.yaml"], "nothere.yaml: cannot read"),
])
def test_bad_usage_is_exit_2(args, words, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "chart.yaml").write_text(CHART)
    assert main(args) == 2
    assert words in capsys.readouterr().err
