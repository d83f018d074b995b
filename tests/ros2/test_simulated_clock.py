"""A seeded run on the simulated clock over Zenoh or Cyclone DDS gives the same trace every
time: the clock moves only once the simulator's messages are back, taken in the order they were
sent (Zenoh may bring two topics' messages back crossed). The app is the TurtleBot's ROS 2 app
with its simulator in the process, speaking ROS 2 messages."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from ruamel.yaml import YAML

from rasm import Platform, RunOptions
from rasm.loop import MEASURED_KEYS
from rasm.platform.manifest import load_manifest
from rasm.ros2.zenoh import ZenohTransport

ROOT = Path(__file__).resolve().parents[2]
RUNS = 3

SIMULATOR = '''
from robot import ros_messages
from tb4.simulator import TurtleBotSimulator


class RosRobot(TurtleBotSimulator):
    """The TurtleBot simulator, its readings as ROS 2 messages stamped with the simulated time."""

    def step(self, time, dt):
        return ros_messages(super().step(time, dt), time, self)
'''


def ros_app_with_simulator(tmp_path: Path) -> Path:
    """examples/turtlebot/ros2.yaml with the simulator of app.yaml in the same process."""
    app = tmp_path / "turtlebot"  # the folder's name is its messages' package
    shutil.copytree(ROOT / "examples" / "turtlebot", app,
                    ignore=shutil.ignore_patterns("__pycache__"))
    (app / "rossim.py").write_text(SIMULATOR)
    scenario = load_manifest(ROOT / "examples" / "turtlebot").scenario
    text = (app / "ros2.yaml").read_text()
    modes = "managed_system:\n  modes: statecharts/navigation_modes.yaml"
    assert modes in text
    text = text.replace(modes, f"{modes}\n  simulator: rossim:RosRobot\n  period: 0.1\n"
                               f"  scenario: {json.dumps(scenario)}\n  #", 1)
    # the simulator takes the spin plan on its topic (a simulator serves no action): the spin
    # effector publishes it, and the fallback (docking through a service) is left out
    manifest = YAML(typ="safe").load(text)
    spin = manifest["effectors"]["spin"]
    manifest["effectors"] = {"spin": {"topic": "/spin_config", "type": "turtlebot/msg/SpinConfig",
                                      "modes": spin["modes"], "fields": spin["fields"]}}
    del manifest["fallback"], manifest["trustworthiness"]
    (app / "sim.yaml").write_text(json.dumps(manifest))  # JSON is YAML
    return app / "sim.yaml"


def seeded_traces(app: Path, url: str, tmp_path: Path) -> list[list[dict]]:
    """The traces of RUNS runs of ``app`` with seed 1 over ``url``, without durations."""
    traces = []
    for run in range(RUNS):
        trace_file = tmp_path / f"run-{run}.jsonl"
        Platform(app, RunOptions(
            clock="simulated",
            seed=1,
            transport=url,
            knowledge="memory",
            state_dir=tmp_path / f"state-{run}",
            trace=trace_file,
        )).run(20.0)
        records = [json.loads(line) for line in trace_file.read_text().splitlines()]
        traces.append([{k: v for k, v in r.items() if k not in MEASURED_KEYS} for r in records])
    return traces


@pytest.mark.slow
def test_a_seeded_simulated_run_over_zenoh_gives_the_same_trace_every_time(
    tmp_path, zenoh_port, transports
):
    app = ros_app_with_simulator(tmp_path)
    url = f"zenoh://127.0.0.1:{zenoh_port}"
    # the meeting point the run connects to
    transports(ZenohTransport(url, listen=[f"tcp/127.0.0.1:{zenoh_port}"])).connect()
    traces = seeded_traces(app, url, tmp_path)
    # every step's odometry reached knowledge: 0.1 s steps from 0 to 20 s
    assert sum("qw" in r for r in traces[0]) == 201
    assert all(trace == traces[0] for trace in traces[1:])


@pytest.mark.slow
def test_a_seeded_simulated_run_over_dds_gives_the_same_trace_every_time(tmp_path, dds_domain):
    app = ros_app_with_simulator(tmp_path)
    traces = seeded_traces(app, f"dds://?domain={dds_domain}", tmp_path)
    assert sum("qw" in r for r in traces[0]) == 201
    assert all(trace == traces[0] for trace in traces[1:])
