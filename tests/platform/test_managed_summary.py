"""A managed-only run (`rasm run --role managed`) ends with a summary of what the managed side
did — simulator steps, readings published, actions applied — not the managing side's empty
loop tables, which read like a failure. Over a real mosquitto, with the managing side in this
process."""

from __future__ import annotations

import re
import subprocess
import sys
import threading
from pathlib import Path

from rasm import Platform, RunOptions
from rasm.testing.servers import start_mosquitto

HOTBOX = Path(__file__).resolve().parents[2] / "examples" / "hotbox"


def test_a_managed_only_run_says_what_the_managed_side_did(tmp_path):
    broker = start_mosquitto(tmp_path)
    managed = subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "run", str(HOTBOX), "--role", "managed",
         "--transport", broker.url, "--duration", "20"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )
    platform = Platform(HOTBOX, RunOptions(role="managing", transport=broker.url,
                                           knowledge="memory", state_dir=tmp_path / "state"))
    executed = threading.Event()

    def watch(when, record):
        if record.get("executed"):  # an action went to the managed side: enough
            executed.set()
            platform.request_stop("the test saw an action")

    platform.on_record.append(watch)
    try:
        platform.run(18.0)
        out, _ = managed.communicate(timeout=60)
    finally:
        if managed.poll() is None:
            managed.kill()
        broker.stop()
    assert executed.is_set(), "the managing side sent no action"
    assert managed.returncode == 0, out
    assert ("hotbox: 20 s on the wall clock, the managed side only (--role managed: the loop, "
            "its properties and its verdicts are the managing process's)") in out
    steps = re.search(r"(\d+) simulator steps, \1 readings published \(hotbox/sensors \1\)",
                      out)
    assert steps and int(steps.group(1)) >= 150, out  # a step each 0.1 s of the 20 s
    assert re.search(r"\b1 action applied \(heater 1\)", out), out
    # none of the managing side's tables, which would all be empty here
    assert "adaptations" not in out and "properties" not in out.replace(
        "its properties", "")
