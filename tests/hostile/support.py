"""Running the real ``rasm`` command on hostile files, and the checks every run must pass."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def rasm(*args: str | Path, cwd: Path | None = None, timeout: float = 120) -> tuple[int, str]:
    """Exit code and standard error (standard output appended) of ``python -m rasm.cli``."""
    done = subprocess.run(
        [sys.executable, "-m", "rasm.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=timeout,
    )
    return done.returncode, done.stderr + done.stdout


def assert_refused_at(code: int, output: str, place: str, words: str = "") -> None:
    """Exit 2, the message at ``place`` (``file:line:col``), no traceback."""
    assert "Traceback" not in output, output
    assert code == 2, output
    assert f"{place}: " in output, output
    assert words in output, output


def chart_nested(depth: int) -> str:
    """A chart whose states are nested ``depth`` deep (each the only child of the one above)."""
    lines = ["statechart:", "  name: deep", "  root state:"]
    indent = 4
    for level in range(depth):
        lines.append(" " * indent + f"name: s{level}")
        if level < depth - 1:
            lines += [" " * indent + f"initial: s{level + 1}", " " * indent + "states:"]
            lines.append(" " * (indent + 2) + "-")
            indent += 4
    return "\n".join(lines) + "\n"


def position(text: str, needle: str) -> str:
    """``line:col`` (1-based) where ``needle`` first starts in ``text``."""
    start = text.index(needle)
    line = text.count("\n", 0, start) + 1
    return f"{line}:{start - (text.rfind(chr(10), 0, start) + 1) + 1}"
