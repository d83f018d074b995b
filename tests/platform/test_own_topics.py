"""The platform's own topics are nobody else's: verdicts go out on rasm/verdict/<property> (an
effector named after a property receives none of them, over a real mosquitto), and lint and
start-up refuse a probe, effector or external verdict topic the platform publishes, and the new
manifest keys' bad values, each at its place."""

from __future__ import annotations

import subprocess
import sys

import pytest

from rasm import Platform, RunOptions
from rasm.cli import main
from rasm.comm import open_transport
from rasm.errors import SourceErrors
from rasm.testing.servers import start_mosquitto

from .guarded import write_guarded_app


@pytest.mark.slow
def test_an_effector_named_after_a_property_receives_no_verdict_as_an_action(tmp_path):
    # the effector's topic is "slow", the veto property's name: the old verdict topic
    app = write_guarded_app(tmp_path / "app", period=0.1)
    text = (app / "app.yaml").read_text().replace("topic: robot/motor", "topic: slow")
    (app / "app.yaml").write_text(text)
    broker = start_mosquitto(tmp_path)
    listener = open_transport(broker.url)
    listener.connect()
    on_effector: list[dict] = []
    verdicts: list[dict] = []
    listener.subscribe("slow", lambda m: on_effector.append(m.payload), qos=1)
    listener.subscribe("rasm/verdict/slow", lambda m: verdicts.append(m.payload), qos=1)
    try:
        # fast the whole run: the veto holds, no action may reach the effector
        platform = Platform(app, RunOptions(
            transport=broker.url,
            clock="wall",
            knowledge="memory",
            state_dir=tmp_path / "state",
            scenario={"fast": [[0, 100]]},
        ))
        platform.run(1.5)
    finally:
        listener.close()
        broker.stop()
    assert verdicts and all(v["value"] is False for v in verdicts)
    assert on_effector == []


def _write(tmp_path, edit):
    app = write_guarded_app(tmp_path / "app")
    (app / "app.yaml").write_text(edit((app / "app.yaml").read_text()))
    return app


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace("topic: robot/motor", "topic: rasm/verdict/slow"),
     "effector motor: rasm/verdict/slow is a topic the platform publishes itself (the verdicts "
     "of slow)"),
    (lambda t: t.replace("topic: robot/sensors", "topic: rasm/#"),
     "probe rasm/#: rasm/# is a topic the platform publishes itself"),
    (lambda t: t.replace("topic: robot/motor", "topic: rasm/presence/robot"),
     "is a topic the platform publishes itself (the processes' presence)"),
    (lambda t: t + "  external_verdicts:\n    other: {topic: /rasm/verdict/budget}\n",
     "external verdict other: /rasm/verdict/budget is a topic the platform publishes itself"),
    (lambda t: t.replace("topic: robot/motor", "topic: /rasm/verdict/no_oscillation"),
     "(the verdicts of no_oscillation)"),
])
def test_a_topic_the_platform_publishes_is_refused_by_lint_and_at_start(
    tmp_path, capsys, edit, message
):
    app = _write(tmp_path, edit)
    assert main(["lint", str(app)]) == 1
    out = capsys.readouterr().out
    assert message in out and "app.yaml:" in out, out
    with pytest.raises(SourceErrors) as caught:
        Platform(app, RunOptions(clock="simulated", knowledge="memory"))
    assert message in str(caught.value)


def test_another_rasms_verdict_topic_may_be_an_external_source(tmp_path, capsys):
    app = _write(tmp_path, lambda t: t + (
        "  external_verdicts:\n    arm_ok: {topic: rasm/verdict/arm_ok}\n"))
    assert main(["lint", str(app)]) == 0, capsys.readouterr().out


@pytest.mark.parametrize("edit, line, message", [
    (lambda t: t.replace("  - topic: robot/sensors\n", "  - topic: robot/sensors\n"
                                                       "    staleness: -1\n"),
     "staleness", "-1 is less than or equal to the minimum of 0"),
    (lambda t: t.replace("  - topic: robot/sensors\n", "  - topic: robot/sensors\n"
                                                       "    publisher: /robot\n"),
     "publisher", "publisher belongs to a ROS 2 topic"),
    (lambda t: t + "  external_verdicts:\n    ok: {topic: checker/ok, publisher: /m}\n",
     "publisher", "publisher names a ROS 2 node"),
    (lambda t: t + "  external_verdicts:\n    ok: {topic: /ok, type: std_msgs/msg/Bool,"
                   " publisher: monitor}\n",
     "publisher", "does not match"),
    (lambda t: t + "  external_verdicts:\n    ok: {topic: /ok, type: std_msgs/msg/Empty,"
                   " freshness: 1}\n",
     "freshness", "an Empty source has no freshness"),
    (lambda t: t + "  external_verdicts:\n    ok: {topic: ok, freshness: 0}\n",
     "freshness", "less than or equal to the minimum of 0"),
])
def test_the_new_keys_are_checked_at_their_place(tmp_path, edit, line, message):
    app = _write(tmp_path, edit)
    run = subprocess.run([sys.executable, "-m", "rasm.cli", "run", str(app), "--clock",
                          "simulated", "--duration", "1"],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 2, run.stdout + run.stderr
    assert message in run.stderr and "Traceback" not in run.stderr, run.stderr
    # file:line:col of the key itself
    text = (app / "app.yaml").read_text().splitlines()
    where = next(i for i, row in enumerate(text, start=1) if f"{line}:" in row)
    assert f"app.yaml:{where}:" in run.stderr, run.stderr


def test_an_external_source_over_ros2_without_a_publisher_is_refused_at_start(tmp_path):
    app = _write(tmp_path, lambda t: t + (
        "  external_verdicts:\n    ok: {topic: /ok, type: std_msgs/msg/Bool}\n"))
    run = subprocess.run([sys.executable, "-m", "rasm.cli", "run", str(app), "--transport",
                          "zenoh://127.0.0.1:1", "--duration", "1"],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 2, run.stdout + run.stderr
    assert "over ROS 2 only the declared publisher's messages count" in run.stderr
    assert "app.yaml:" in run.stderr and "Traceback" not in run.stderr
