"""User code that raises a BaseException (sys.exit(), raise KeyboardInterrupt, a class of its
own) fails that step or stage like any exception; only a real Ctrl-C stops a command."""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from sismic.clock import SimulatedClock

from rasm.errors import Interrupted, is_interrupt, raise_interrupted
from rasm.statechart import Interpreter, load_statechart

from .support import ROOT, rasm


class Escape(BaseException):
    """A BaseException of the user's own."""


def _block(code: str, indent: int) -> str:
    return "\n".join(" " * indent + line for line in code.splitlines()) + "\n"


def chart(code: str, where: str = "action") -> str:
    """A chart going from 'a' to 'b' on 'go' and back on 'back', with ``code`` in the first
    transition's action or guard, or in the ``on entry`` of 'b' (``where="entry"``)."""
    transition = "          - target: b\n            event: go\n"
    if where in ("action", "guard"):
        transition += f"            {where}: |\n" + _block(code, 14)
    entry = "        on entry: |\n" + _block(code, 10) if where == "entry" else ""
    return (
        "statechart:\n  name: escapes\n  root state:\n    name: root\n    initial: a\n"
        "    states:\n      - name: a\n        transitions:\n"
        f"{transition}      - name: b\n{entry}"
        "        transitions:\n          - target: a\n            event: back\n"
    )


EVENTS = '{"time": 1, "event": "go"}\n{"time": 2, "event": "back"}\n'


@pytest.mark.parametrize(
    "code,where,shown",
    [
        ("import sys\nsys.exit(5)", "action", "SystemExit: 5"),
        ("raise KeyboardInterrupt", "action", "KeyboardInterrupt"),
        ("__import__('sys').exit(7)", "guard", "SystemExit: 7"),
        ("raise GeneratorExit('gone')", "entry", "GeneratorExit: gone"),
    ],
)
def test_simulate_reports_a_base_exception_in_chart_code_as_a_rolled_back_step(
    tmp_path: Path, code: str, where: str, shown: str
) -> None:
    path = tmp_path / "c.yaml"
    path.write_text(chart(code, where))
    events = tmp_path / "e.jsonl"
    events.write_text(EVENTS)
    exit_code, out = rasm("simulate", path, "--events", events, "--format", "json")
    assert "Traceback" not in out, out
    assert exit_code == 1, out  # a step failed (not the user's 5 or 7, not 130)
    failed = "rasm: at time 1: event 'go' (line 1): step rolled back: CodeEvaluationError"
    assert f"{failed}: '{shown}" in out
    if where != "guard":  # (a guard that raises fails every step that evaluates it)
        # the step was rolled back: 'back' finds the chart still in 'a', where it does nothing
        last = out.splitlines()[-1]
        assert '"event": "back"' in last and '"exited": []' in last, out


def test_a_chart_preamble_that_exits_is_refused_at_the_preamble(tmp_path: Path) -> None:
    path = tmp_path / "c.yaml"
    path.write_text(
        "statechart:\n  name: x\n  preamble: |\n    import sys\n    sys.exit(3)\n"
        "  root state:\n    name: r\n"
    )
    exit_code, out = rasm("simulate", path)
    assert "Traceback" not in out
    assert exit_code == 2, out
    assert f"{path}:3:13: the chart's preamble failed" in out
    assert "SystemExit: 3" in out


def test_the_interpreter_rolls_back_a_step_whose_code_raises_a_base_exception(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # what the rasm command does: a real Ctrl-C raises Interrupted
    monkeypatch.setattr(signal, "getsignal", lambda signum: raise_interrupted)
    statechart = load_statechart(text=chart("raise Escape()", "action"))
    interp = Interpreter(statechart, clock=SimulatedClock(), initial_context={"Escape": Escape})
    interp.execute()
    interp.queue("go")
    with pytest.raises(Exception, match="'Escape' occurred while executing"):
        interp.execute_once()
    assert interp.configuration == ["root", "a"]
    assert isinstance(interp.last_failure.exception.__cause__, Escape)


def test_a_real_interrupt_is_not_taken_for_user_code() -> None:
    assert is_interrupt(Interrupted())
    assert not is_interrupt(SystemExit(1)) and not is_interrupt(Escape())
    # as a library, with Python's own SIGINT handler, a Ctrl-C is a plain KeyboardInterrupt
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        assert is_interrupt(KeyboardInterrupt())
        signal.signal(signal.SIGINT, raise_interrupted)
        assert not is_interrupt(KeyboardInterrupt())  # under rasm's handler: user code's
    finally:
        signal.signal(signal.SIGINT, previous)


def test_ctrl_c_still_stops_a_simulation_stuck_in_chart_code(tmp_path: Path) -> None:
    marker = tmp_path / "looping"
    path = tmp_path / "c.yaml"
    path.write_text(chart(f"open({str(marker)!r}, 'w').close()\nwhile True:\n    pass", "action"))
    events = tmp_path / "e.jsonl"
    events.write_text(EVENTS)
    process = subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "simulate", str(path), "--events", str(events)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 60
        while not marker.exists():
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "the chart never reached its loop"
            time.sleep(0.02)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=30)
    finally:
        process.kill()
    assert process.returncode == 130, err
    assert "Traceback" not in err


@pytest.fixture(scope="module")
def hotbox_whose_monitor_raises(tmp_path_factory: pytest.TempPathFactory) -> Path:
    app = tmp_path_factory.mktemp("apps") / "hotbox"
    shutil.copytree(ROOT / "examples" / "hotbox", app)
    components = app / "components.py"
    text = components.read_text()
    raising = (
        "    def monitor(self, ctx):\n"
        "        if ctx.time > 3:\n"
        "            raise ESCAPE\n"
    )
    text = text.replace("    def monitor(self, ctx):\n", raising, 1)
    components.write_text(text + "\nESCAPE = None\n")
    return app


@pytest.mark.parametrize("escape", ["KeyboardInterrupt", "SystemExit(7)", "GeneratorExit()"])
def test_a_monitor_stage_raising_a_base_exception_fails_that_stage_and_the_run_ends_in_order(
    hotbox_whose_monitor_raises: Path, escape: str
) -> None:
    components = hotbox_whose_monitor_raises / "components.py"
    text = components.read_text()
    components.write_text(text[: text.rindex("ESCAPE = ")] + f"ESCAPE = {escape}\n")
    exit_code, out = rasm(
        "run", hotbox_whose_monitor_raises, "--clock", "simulated", "--duration", "8"
    )
    assert exit_code in (0, 1), out  # as a normal end (not 7, not 130)
    assert f"monitor stage failed: {escape.split('(')[0]}" in out
    assert "stage timing" in out  # the summary was printed


class ExitingTwin:
    """A digital twin whose every method calls sys.exit()."""

    inputs = ("temperature",)

    def observe(self, time: float, values: dict) -> None:
        raise SystemExit("observe")

    def simulate(self, plan: dict, state: dict, horizon: float, dt: float) -> list:
        raise SystemExit("simulate")

    def model(self) -> dict:
        return {}

    def load(self, model: dict) -> None:
        raise SystemExit("load")


def test_a_twin_that_exits_fails_closed_and_the_loop_goes_on(tmp_path: Path) -> None:
    from rasm import Platform, RunOptions
    from rasm.platform.manifest import load_manifest

    trace = tmp_path / "trace.jsonl"
    summary = Platform(
        load_manifest(ROOT / "examples" / "hotbox"),
        RunOptions(
            clock="simulated",
            seed=1,
            knowledge="memory",
            trace=trace,
            components={"twin": ExitingTwin()},
        ),
    ).run(30)
    assert summary.stats.iterations == int(30 / 0.5)
    text = trace.read_text()
    # Legitimate cannot judge a plan on a twin that exits: no plan is accepted on its word
    assert "the twin could not simulate the plan: simulate" in text
    assert summary.stats.executed == 0
