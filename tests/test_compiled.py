"""The compiled build (rasm.compiled): loaded only while its source is unchanged, and the same
behaviour as plain Python."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
import textwrap
from pathlib import Path

import pytest

import rasm.compiled
from rasm.compiled import MODULES, status

ROOT = Path(__file__).resolve().parents[1]
SUFFIX = sysconfig.get_config_var("EXT_SUFFIX")
# scripts/test.sh has just built it: there its absence is a failure, not a reason to skip
EXPECTED = os.environ.get("RASM_EXPECT_COMPILED") == "1"


def python(code: str, env: dict[str, str]) -> str:
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.fixture(scope="module")
def toy(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """A one-module package compiled into its own folder; the environment that finds both."""
    root = tmp_path_factory.mktemp("toy")
    (root / "toyhot").mkdir()
    (root / "toyhot" / "__init__.py").write_text("")
    (root / "toyhot" / "hot.py").write_text("def answer():\n    return 41 + 1\n")
    env = {
        "PYTHONPATH": os.pathsep.join([str(root), str(ROOT)]),
        "RASM_COMPILED_DIR": str(root / "build"),
        "RASM_PURE_PYTHON": "",
    }
    python("from rasm.compiled import build; build(['toyhot.hot'])", env)
    env["TOY"] = str(root)
    return env


IMPORT_TOY = """
import rasm, rasm.compiled, toyhot.hot
print(toyhot.hot.__file__, toyhot.hot.answer(), rasm.compiled.status(['toyhot.hot'])['toyhot.hot'])
"""


def test_a_module_built_from_its_current_source_is_imported_compiled(toy):
    file, answer, state = python(IMPORT_TOY, toy).split()
    assert file.endswith(SUFFIX) and Path(file).is_relative_to(Path(toy["RASM_COMPILED_DIR"]))
    assert answer == "42" and state == "compiled"


def test_an_edited_module_runs_as_plain_python_until_rebuilt(toy):
    source = Path(toy["TOY"]) / "toyhot" / "hot.py"
    original = source.read_text()
    source.write_text(original.replace("41 + 1", "41 + 2"))
    try:
        file, answer, state = python(IMPORT_TOY, toy).split()
    finally:
        source.write_text(original)
    assert file == str(source) and answer == "43" and state == "stale"


def test_rasm_pure_python_turns_the_build_off(toy):
    file, answer, state = python(IMPORT_TOY, {**toy, "RASM_PURE_PYTHON": "1"}).split()
    assert file.endswith("hot.py") and answer == "42" and state == "off"


def test_a_folder_without_a_build_installs_nothing(tmp_path):
    out = python(
        "import sys, rasm.compiled as c; print(c.install(), c._finder in sys.meta_path)",
        {"RASM_COMPILED_DIR": str(tmp_path), "RASM_PURE_PYTHON": "", "PYTHONPATH": str(ROOT)},
    )
    assert out.split() == ["False", "False"]


def test_source_of_names_the_source_of_a_module_imported_compiled_too():
    for name in MODULES:
        source = rasm.compiled.source_of(name)
        assert source == ROOT / (name.replace(".", "/") + ".py")


built = all(state == "compiled" for state in status().values())
needs_build = pytest.mark.skipif(
    not (built or EXPECTED), reason="no compiled build here (python -m rasm.compiled build)"
)


@needs_build
def test_the_hot_modules_run_compiled():
    assert status() == dict.fromkeys(MODULES, "compiled")
    import rasm.statechart.fast

    assert rasm.statechart.fast.__file__.endswith(SUFFIX)
    assert "rasm.statechart.fast" in rasm.compiled.loaded()


TRACE = """
import json, sys, rasm.compiled
from rasm.testing import run_app
trace = run_app({app!r}, seed=3, duration=120.0, scenario={scenario!r})
# a stage's duration is measured on the wall clock: the one field that differs run to run
records = [{{k: v for k, v in r.items() if k != "duration"}} for r in trace]
print(json.dumps({{"compiled": sorted(rasm.compiled.loaded()), "trace": records}}))
"""


@needs_build
@pytest.mark.parametrize(
    "app, scenario",
    [("hotbox", {"content_change": [[20.0, 1200.0]]}), ("turtlebot", None)],
)
def test_the_demonstrators_leave_the_same_trace_compiled_and_as_plain_python(app, scenario):
    code = TRACE.format(app=str(ROOT / "examples" / app), scenario=scenario)
    compiled = json.loads(python(code, {"RASM_PURE_PYTHON": ""}))
    plain = json.loads(python(code, {"RASM_PURE_PYTHON": "1"}))
    assert set(compiled["compiled"]) >= {"rasm.statechart.fast", "rasm.knowledge.base"}
    assert plain["compiled"] == []
    assert len(compiled["trace"]) > 200
    assert compiled["trace"] == plain["trace"]


def test_a_failed_build_says_why_and_keeps_the_build_there_was(toy):
    done = subprocess.run(
        [sys.executable, "-m", "rasm.compiled", "build", "--force"],
        env={**os.environ, **toy, "CC": "/bin/false"},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 1
    assert "build failed: CompileError" in done.stderr and "/bin/false" in done.stderr
    assert done.stdout == ""  # the compiler's chatter went to the log, shown with the error
    file, answer, state = python(IMPORT_TOY, toy).split()
    assert file.endswith(SUFFIX) and state == "compiled"


def test_a_source_edited_during_the_build_is_not_recorded_as_compiled(tmp_path):
    # The C compiler is a wrapper that edits the module (Cython has already read it) before
    # compiling: the binary holds the old text, so its manifest entry must not name the new one.
    (tmp_path / "toyedit").mkdir()
    (tmp_path / "toyedit" / "__init__.py").write_text("")
    hot = tmp_path / "toyedit" / "hot.py"
    hot.write_text("def answer():\n    return 42\n")
    compiler = tmp_path / "cc"
    compiler.write_text(
        f"#!/bin/sh\nprintf 'def answer():\\n    return 43\\n' > {hot}\nexec cc \"$@\"\n"
    )
    compiler.chmod(0o755)
    env = {
        "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)]),
        "RASM_COMPILED_DIR": str(tmp_path / "build"),
        "RASM_PURE_PYTHON": "",
        "CC": str(compiler),
    }
    done = subprocess.run(
        [sys.executable, "-c", "from rasm.compiled import build; build(['toyedit.hot'])"],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 1
    assert "SourceChangedError: edited while it was being compiled" in done.stderr
    assert str(hot) in done.stderr
    assert hot.read_text().endswith("return 43\n")  # the wrapper did run
    # nothing was installed: the edited module runs from its source
    answer = python(
        "import rasm, rasm.compiled, toyedit.hot\n"
        "print(toyedit.hot.answer(), rasm.compiled.status(['toyedit.hot'])['toyedit.hot'])",
        env,
    )
    assert answer.split() == ["43", "not", "built"]


def test_status_names_every_module_and_the_folder(toy):
    out = python("from rasm.compiled.__main__ import main; main(['status'])", toy)
    lines = out.splitlines()
    assert [line.split()[0] for line in lines[:-1]] == list(MODULES)
    assert {line.split(None, 1)[1] for line in lines[:-1]} == {"not built"}
    assert lines[-1] == f"folder: {Path(toy['RASM_COMPILED_DIR']) / rasm.compiled.folder().name}"


@needs_build
def test_the_hot_modules_run_compiled_under_pytest_started_after_rasm_was_imported(tmp_path):
    # pytest's assertion rewriter, put first once rasm is imported, would take them as plain
    # Python if rasm.testing (the plugin) did not put the compiled finder back in front
    (tmp_path / "test_probe.py").write_text(
        "import sysconfig\n"
        "def test_probe():\n"
        "    import rasm.statechart.fast as fast\n"
        "    assert fast.__file__.endswith(sysconfig.get_config_var('EXT_SUFFIX'))\n"
    )
    code = f"""
    import sys, rasm, pytest
    sys.exit(pytest.main(["-q", "-p", "no:cacheprovider", {str(tmp_path / "test_probe.py")!r}]))
    """
    assert "1 passed" in python(code, {"RASM_PURE_PYTHON": ""})


def test_an_unknown_command_is_refused_with_exit_2_and_no_traceback():
    done = subprocess.run(
        [sys.executable, "-m", "rasm.compiled", "bogus"], capture_output=True, text=True
    )
    assert done.returncode == 2
    assert "invalid choice: 'bogus'" in done.stderr and "Traceback" not in done.stderr
