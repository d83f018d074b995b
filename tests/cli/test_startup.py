"""What a command loads: ``rasm --help``, ``rasm lint`` and ``rasm check`` on a property file and
a JSONL trace, and the pytest plugin (imported by every pytest run), each load only what they use
— no platform, no statechart engine, no solver, no hypothesis where they are not needed."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

PROPERTY = "input a: bool\ninput b: bool\nproperty p: always (b -> once[0, 1s] a)\n"

# modules (and their submodules) that none of these paths needs
HEAVY = ["rasm.platform", "rasm.statechart", "rasm.rules", "rasm.ros2", "rasm.report",
         "rasm.workflow", "rasm.comm", "rasm.knowledge", "sismic", "z3", "hypothesis", "rich",
         "ruamel", "rosbags", "paho"]

# what runs in a fresh interpreter, then prints the names in sys.modules
RUN_MAIN = """
import sys
from rasm.cli import main
try:
    code = main(sys.argv[1:])
except SystemExit as exc:  # --help
    code = exc.code
"""


def _loaded(code: str, *args: str, cwd: Path, env: dict[str, str] | None = None) -> set[str]:
    script = code + "\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))\n"
    out = subprocess.run([sys.executable, "-c", script, *args], cwd=cwd, capture_output=True,
                         text=True, check=True, timeout=60, env=env)
    return set(json.loads(out.stdout.splitlines()[-1]))


def _heavy(modules: set[str], allowed: tuple[str, ...] = ()) -> list[str]:
    return sorted(
        name for name in modules
        if any(name == top or name.startswith(top + ".") for top in HEAVY if top not in allowed)
    )


@pytest.fixture
def inputs(tmp_path: Path) -> Path:
    (tmp_path / "p.rv").write_text(PROPERTY)
    (tmp_path / "t.jsonl").write_text('{"time": 0, "a": true, "b": false}\n')
    return tmp_path


def test_rasm_help_loads_no_property_language(inputs: Path) -> None:
    loaded = _loaded(RUN_MAIN, "--help", cwd=inputs)
    assert "rasm.cli" in loaded
    assert _heavy(loaded) == []
    assert not {"rasm.properties", "lark"} & loaded


@pytest.mark.parametrize("command", [["lint", "p.rv"], ["check", "p.rv", "t.jsonl"]])
def test_lint_and_check_of_a_property_file_load_the_property_language_only(
    inputs: Path, command: list[str]
) -> None:
    loaded = _loaded(RUN_MAIN + "assert code == 0, code\n", *command, cwd=inputs)
    assert "rasm.properties.monitor" in loaded
    assert _heavy(loaded) == []


def test_a_check_of_an_unchanged_property_file_loads_no_parser_and_no_pool(inputs: Path) -> None:
    # the first check keeps the checked file in the cache folder; the next reads it back
    env = {**os.environ, "XDG_CACHE_HOME": str(inputs / "cache")}
    run = RUN_MAIN + "assert code == 0, code\n"
    first = _loaded(run, "check", "p.rv", "t.jsonl", cwd=inputs, env=env)
    again = _loaded(run, "check", "p.rv", "t.jsonl", cwd=inputs, env=env)
    assert "lark" in first
    unused = {"lark", "rasm.properties.parser", "multiprocessing", "concurrent.futures.process",
              "sqlite3", "tempfile", "rasm.trace_parts"}
    assert unused & again == set()


def test_the_pytest_plugin_loads_neither_rasm_testing_nor_the_platform(inputs: Path) -> None:
    loaded = _loaded("import pytest\nimport rasm.testing.plugin", cwd=inputs)
    assert "rasm.testing.plugin" in loaded
    assert _heavy(loaded) == []
    rasm_modules = sorted(name for name in loaded if name.startswith("rasm"))
    # rasm._lazy is the faces' name loader (it imports nothing but importlib)
    assert rasm_modules == ["rasm", "rasm._lazy", "rasm.testing", "rasm.testing.plugin"]


def test_rasm_testing_names_load_on_first_use_whatever_the_order(inputs: Path) -> None:
    # rasm.testing.scenarios and .traces are modules named after their functions: asking for a
    # sibling first must not leave the module where the function is expected
    code = (
        "import inspect, rasm.testing as t\n"
        "from rasm.testing import windows, signal_domains\n"
        "bad = [n for n in t.__all__ if inspect.ismodule(getattr(t, n))]\n"
        "assert not bad, bad\n"
        "assert callable(t.scenarios) and callable(t.traces)\n"
    )
    loaded = _loaded(code, cwd=inputs)
    assert "rasm.testing.machine" in loaded
