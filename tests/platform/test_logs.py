"""A failure that recurs is logged once in full, then as a count per interval and in the summary."""

from __future__ import annotations

import logging
import re
import shutil
import subprocess
import sys
from collections import Counter

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm import Platform, RunOptions
from rasm.logs import RepeatedLogs

from .conftest import HOTBOX

COUNT = re.compile(r"^(?P<what>.*) \((?P<n>\d+) more times? in the last (?P<secs>[\d.e+]+) s\)$")


class Clock:
    """Seconds that pass only when the test says so."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class Lines(logging.Handler):
    """The lines a logger writes, with the time of the test clock at each."""

    def __init__(self, clock: Clock) -> None:
        super().__init__()
        self.clock = clock
        self.lines: list[tuple[float, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append((self.clock.now, record.getMessage()))


def a_logger(name: str, clock: Clock) -> tuple[logging.Logger, Lines]:
    logger = logging.getLogger(f"test.repeated.{name}")
    logger.propagate = False
    logger.handlers = [lines := Lines(clock)]
    logger.setLevel(logging.INFO)
    return logger, lines


EVENTS = st.lists(
    st.tuples(st.floats(0, 7, allow_nan=False), st.sampled_from(["a", "b", "c", "d"])),
    max_size=60,
)


@settings(max_examples=300, deadline=None)
@given(events=EVENTS, interval=st.sampled_from([1.0, 5.0, 10.0]), capacity=st.integers(1, 5))
def test_every_occurrence_is_accounted_for_and_lines_keep_their_interval(
    events, interval, capacity
):
    clock = Clock()
    logger, handler = a_logger("property", clock)
    logs = RepeatedLogs(interval, clock=clock, capacity=capacity)
    happened = Counter()
    for step, what in events:
        clock.now += step
        logs.log(logger, logging.ERROR, f"failure {what}", "failure %s in full", what)
        happened[what] += 1
    clock.now += 1.0
    logs.flush()

    logged = Counter()
    last_line: dict[str, float] = {}
    for at, line in handler.lines:
        count = COUNT.match(line)
        if count:
            what = count["what"].removeprefix("failure ")
            logged[what] += int(count["n"])
        else:
            what = line.removeprefix("failure ").removesuffix(" in full")
            logged[what] += 1
        last_line[what] = at
    # every occurrence is either a full line or counted in exactly one count line
    assert logged == happened
    if capacity >= 4:  # nothing forgotten: one full line per failure, counts no closer than
        full = [line for _, line in handler.lines if line.endswith(" in full")]
        assert sorted(full) == sorted(f"failure {w} in full" for w in happened)
        before_flush = [(at, line) for at, line in handler.lines if at < clock.now]
        seen: dict[str, float] = {}
        for at, line in before_flush:
            count = COUNT.match(line)
            what = count["what"] if count else line.removesuffix(" in full")
            if count:
                assert at - seen[what] >= interval
                assert float(count["secs"]) == round(at - seen[what], 1)
            seen[what] = at
    repeated = {f"failure {what}": n for what, n in happened.items() if n > 1}
    if capacity >= 4:
        assert logs.totals == repeated
    else:  # a forgotten failure starts afresh: its total can only fall short
        assert all(logs.totals[what] <= repeated[what] for what in logs.totals)


def test_a_recurring_failure_is_logged_in_full_once_then_counted_every_interval():
    clock = Clock()
    logger, handler = a_logger("interval", clock)
    logs = RepeatedLogs(10.0, clock=clock)
    for _ in range(57):  # one failure every 0.7 s for 40 s
        assert logs.log(logger, logging.ERROR, "plan failed: boom", "plan failed: boom\nTB") == (
            clock.now == 0.0
        )
        clock.now += 0.7
    logs.flush()
    assert [line for _, line in handler.lines] == [
        "plan failed: boom\nTB",
        "plan failed: boom (15 more times in the last 10.5 s)",
        "plan failed: boom (15 more times in the last 10.5 s)",
        "plan failed: boom (15 more times in the last 10.5 s)",
        "plan failed: boom (11 more times in the last 8.4 s)",
    ]
    assert logs.totals == {"plan failed: boom": 57}


class Failing:
    """A planner that raises at every call and a monitor that stores a wrong-type value."""

    def plan(self, ctx):
        return 1 / 0

    def monitor(self, ctx):
        return {"temperature": "hot"}

    def analyse(self, ctx):
        return {"reason": "always"}


def test_a_planner_raising_every_iteration_gives_one_traceback_and_a_count(hotbox, caplog):
    failing = Failing()
    platform = Platform(
        hotbox,
        RunOptions(
            clock="simulated",
            knowledge="memory",
            components={"plan": failing, "monitor": failing, "analyse": failing},
        ),
    )
    # counted on the simulated clock, so the intervals are the same on any machine
    platform.logs = RepeatedLogs(10.0, clock=lambda: platform.clock.time)
    with caplog.at_level(logging.WARNING, logger="rasm"):
        summary = platform.run(40.0)
    messages = [r.getMessage() for r in caplog.records if r.name.startswith("rasm")]
    failures = summary.stats.failed_stages["plan"]
    assert failures == summary.stats.iterations == 80
    plan = "plan stage failed: ZeroDivisionError: division by zero"
    full = [m for m in messages if m.startswith(plan) and "Traceback" in m]
    assert len(full) == 1
    counts = [int(COUNT.match(m)["n"]) for m in messages if m.startswith(plan) and COUNT.match(m)]
    assert 1 + sum(counts) == failures and len(counts) == 4  # at 10, 20, 30 s and the end
    assert summary.repeated_failures[plan] == failures
    # the wrong-type value: one warning naming it, then counted whatever the value
    stored = [m for m in messages if m.startswith("knowledge temperature=")]
    assert stored == ["knowledge temperature='hot' refused: knowledge 'temperature': "
                      "expected float, got str 'hot'"]
    refused = "knowledge temperature refused: knowledge 'temperature': expected float, got str …"
    assert summary.repeated_failures[refused] == failures


def test_rasm_run_prints_one_traceback_and_the_count_in_its_summary(tmp_path):
    app = tmp_path / "app"
    shutil.copytree(HOTBOX, app)
    with (app / "components.py").open("a") as components:
        components.write("\n\nclass BrokenPlan:\n    def plan(self, ctx):\n        return 1 / 0\n")
    manifest = app / "app.yaml"
    text = manifest.read_text().replace("components:HotboxPlan", "components:BrokenPlan")
    manifest.write_text(text)
    done = subprocess.run(
        [sys.executable, "-m", "rasm.cli", "run", str(app), "--clock", "simulated",
         "--duration", "60"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
    )
    assert done.returncode in (0, 1), done.stderr
    assert done.stderr.count("Traceback") == 1, done.stderr
    # the traceback's last line, once
    assert done.stderr.splitlines().count("ZeroDivisionError: division by zero") == 1
    failed = int(re.search(r"failed stages: \{'plan': (\d+)\}", done.stdout)[1])
    assert failed > 50
    assert f"{failed} × plan stage failed: ZeroDivisionError: division by zero" in done.stdout
    logged = [COUNT.match(line.split(": ", 1)[1]) for line in done.stderr.splitlines()
              if "more time" in line]
    assert 1 + sum(int(m["n"]) for m in logged) == failed
