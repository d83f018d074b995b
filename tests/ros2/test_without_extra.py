"""The default install, without the ``ros2`` extra: every command that needs it says which
extra to install, exits 2 and prints no traceback (tests/ros2/without_extra.py hides the
extra's packages from the import system, as a default install does not have them)."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from rasm.extras import EXTRAS
from tests.ros2.conftest import DATA
from tests.ros2.test_replay import record

WITHOUT = Path(__file__).with_name("without_extra.py")
ROOT = Path(__file__).resolve().parents[2]
GUARD, WIDE, HOTBOX = DATA / "guard", DATA / "wide", ROOT / "examples" / "hotbox"
GUARD_RV = GUARD / "properties" / "guard.rv"
TOPICS = "probes:\n  - topic: /odom\n    type: nav_msgs/msg/Odometry\n    signals:\n" \
         "      speed: {field: twist.twist.linear.x, type: float}\n"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    """What the commands read, made with the extra installed: rosbag2 recordings (MCAP and
    SQLite3) and a topic map."""
    folder = tmp_path_factory.mktemp("inputs")
    record(folder / "bag", "mcap")
    record(folder / "bagdb", "sqlite3")
    (folder / "topics.yaml").write_text(TOPICS)
    return folder


def without_extra(*args: object, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(WITHOUT), *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=120)


# the arguments of rasm (files in the inputs folder by name), the module it finds missing
COMMANDS = {
    "check an MCAP bag": (["check", GUARD_RV, "bag/bag.mcap", "--app", GUARD], "numpy"),
    "check an MCAP bag by topics": (["check", GUARD_RV, "bag/bag.mcap", "--topics",
                                     "topics.yaml"], "numpy"),
    "check an SQLite3 bag": (["check", GUARD_RV, "bagdb", "--topics", "topics.yaml"], "numpy"),
    "check a bag folder": (["check", GUARD_RV, "bag", "--app", GUARD], "numpy"),
    "run with ROS 2 types": (["run", WIDE, "--duration", "1", "--clock", "simulated"], "numpy"),
    "run a replay": (["run", GUARD, "--replay", "bag/bag.mcap"], "numpy"),
    "monitor over DDS": (["monitor", GUARD_RV, "--transport", "dds://", "--duration", "1"],
                         "numpy"),
    "verify an app's rules": (["verify-rules", GUARD], "numpy"),
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_command_that_needs_the_ros2_extra_says_which_to_install(inputs, command):
    args, module = COMMANDS[command]
    done = without_extra(*args, cwd=inputs)
    assert done.returncode == 2, (done.stdout, done.stderr)
    assert "Traceback" not in done.stdout + done.stderr, done.stderr
    assert done.stderr.startswith("rasm: ")
    assert (f"not installed (no module named {module!r}); install it with: pip install "
            "'rasm[ros2]'") in done.stderr


def test_the_message_names_the_command(inputs):
    done = without_extra("check", GUARD_RV, "bagdb", "--topics", "topics.yaml", cwd=inputs)
    assert done.stderr == (
        "rasm: rasm check needs rasm's ROS 2 support, which is not installed (no module named "
        "'numpy'); install it with: pip install 'rasm[ros2]'\n"
    )


def test_rasm_s_own_mcap_traces_need_no_extra(inputs):
    run = without_extra("run", HOTBOX, "--duration", "1", "--clock", "simulated", "--trace",
                        "out.mcap", cwd=inputs)
    assert run.returncode in (0, 1), run.stderr
    check = without_extra("check", HOTBOX / "properties" / "hotbox.rv", "out.mcap", cwd=inputs)
    assert check.returncode in (0, 1) and "records of out.mcap" in check.stdout, check.stderr


def test_lint_reports_an_app_with_ros2_types_at_the_type(inputs):
    done = without_extra("lint", GUARD, cwd=inputs)
    assert done.returncode == 1 and "Traceback" not in done.stdout + done.stderr
    assert (f"{GUARD / 'app.yaml'}:13:11: a ROS 2 interface type needs rasm's ROS 2 support, "
            "which is not installed (no module named 'numpy')") in done.stdout


def test_the_python_api_says_which_extra_to_install():
    code = ("import sys; from tests.ros2.without_extra import NotInstalled; "
            "sys.meta_path.insert(0, NotInstalled()); import rasm.ros2")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=60)
    assert "MissingExtra: rasm.ros2 needs rasm's ROS 2 support, which is not installed (no " \
           "module named 'numpy'); install it with: pip install 'rasm[ros2]'" in done.stderr


def test_the_extras_modules_are_the_packages_pyproject_lists():
    listed = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]["ros2"]
    packages = {entry.split(">")[0].split("<")[0].split("=")[0] for entry in listed}
    module_of = {"eclipse-zenoh": "zenoh"}  # the one whose module has another name
    assert {module_of.get(p, p) for p in packages} == set(EXTRAS["ros2"][1])
