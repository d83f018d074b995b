"""The README's set-up, run for real in a copy of the repository: it leaves a .venv from which
every guide's commands run (rasm, python with rasm and hypothesis, and pytest with the plugin)."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_setup_leaves_a_venv_with_rasm_and_pytest(tmp_path):
    copy = tmp_path / "rasm"
    ignore = shutil.ignore_patterns(".venv", ".rasm", ".git", "__pycache__", ".hypothesis",
                                    "tests", "benchmarks", "docs")
    shutil.copytree(ROOT, copy, ignore=ignore)
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    done = subprocess.run(["bash", "scripts/setup.sh"], cwd=copy, env=env, capture_output=True,
                          text=True, timeout=900)
    assert done.returncode == 0, done.stdout + done.stderr
    venv = copy / ".venv" / "bin"
    version = subprocess.run([venv / "rasm", "--version"], capture_output=True, text=True)
    assert version.stdout.startswith("rasm "), version.stdout + version.stderr
    # the testing guide's command: pytest from .venv, with rasm importable and its plugin loaded
    (copy / "test_guide.py").write_text(
        "import rasm\n\n\ndef test_plugin(rasm_app):\n    assert rasm.Platform\n"
    )
    tests = subprocess.run([venv / "pytest", "-q", "-p", "no:cacheprovider", "test_guide.py"],
                           cwd=copy, env=env, capture_output=True, text=True, timeout=300)
    assert tests.returncode == 0 and "1 passed" in tests.stdout, tests.stdout + tests.stderr
