"""Every guide runs as written: each command and Python block of README.md and docs/*.md, in order,
in a copy of the repository with this venv's ``rasm`` on the PATH, each shown output compared.

The blocks of one guide share its folder (a file an early block writes is there for a later one),
as they would for a reader going down the page. A block that cannot be run says why, in the
guide (``<!-- not run: … -->``); :mod:`tests.docs.guides` has the conventions. The well-known
ports the guides use (1883, 6379, 8086) are those of real servers started on free loopback ports
for the guides that use them; 7448, where a guide's Zenoh session listens, becomes a free port.
A ``rasm run`` on the wall clock lasts at most ``WALL_SECONDS`` (``RASM_MAX_WALL_SECONDS``).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from rasm.testing.servers import free_port

from .guides import Block, console_commands, output_matches, read_blocks

ROOT = Path(__file__).resolve().parents[2]
HARNESS = Path(__file__).with_name("harness.py")
GUIDES = ["README.md", *sorted(f"docs/{p.name}" for p in (ROOT / "docs").glob("*.md"))]
# guides that take more than a second or two to run as written (`pytest -m "not slow"` skips them)
SLOW = {"README.md", "docs/distribution.md", "docs/performance-user-paths.md",
        "docs/properties.md", "docs/report.md", "docs/ros2.md", "docs/rules.md",
        "docs/runtime.md", "docs/statecharts.md", "docs/testing.md", "docs/turtlebot.md",
        "docs/workflow.md"}
# guides whose blocks are not yet made runnable, with why (RASM_DOCS_PENDING=1 runs them anyway)
PENDING: dict[str, str] = {}
COPIED = ("examples", "properties", "statecharts", "monitors", "benchmarks", "scripts", "docs")
COMMAND_TIMEOUT = 300  # seconds: the slowest guide command (a packaging) takes about a minute
SEPARATOR = "\x1e"  # between the outputs of a console block's commands
WALL_SECONDS = "15"  # RASM_MAX_WALL_SECONDS: what a guide's wall-clock `rasm run` lasts here


def workdir(tmp: Path) -> Path:
    """A copy of the repository's user-facing folders, with ``.venv`` this test venv."""
    folder = tmp / "rasm"
    ignore = shutil.ignore_patterns(".rasm", "__pycache__", "*.pyc", ".hypothesis")
    for name in COPIED:
        shutil.copytree(ROOT / name, folder / name, ignore=ignore)
    for name in ("README.md", "pyproject.toml"):
        shutil.copy(ROOT / name, folder / name)
    (folder / ".venv").symlink_to(Path(sys.prefix), target_is_directory=True)
    # .venv is this test venv: a guide block running setup.sh would reinstall rasm from the copy
    (folder / "scripts" / "setup.sh").write_text(
        "echo 'setup.sh is run by tests/docs/test_setup.py, not by a guide block' >&2; exit 1\n"
    )
    return folder


class Servers:
    """Real servers on free loopback ports, started the first time a guide names their port; and
    for a port the guide's own code listens on (a Zenoh session that is its own meeting point),
    one free loopback port for the whole guide, so that guides run at once never clash."""

    PORTS = {"1883": "shared_broker", "6379": "redis_server", "8086": "influx"}
    LISTENED = ("7448",)

    def __init__(self, request: pytest.FixtureRequest) -> None:
        self.request = request
        self.free: dict[str, int] = {}

    def substitute(self, text: str) -> str:
        for port, fixture in self.PORTS.items():
            for host in ("127.0.0.1", "localhost"):
                if f"{host}:{port}" in text:
                    server = self.request.getfixturevalue(fixture)
                    text = text.replace(f"{host}:{port}", f"127.0.0.1:{server.port}")
        for port in self.LISTENED:
            for host in ("127.0.0.1", "localhost"):
                if f"{host}:{port}" in text:
                    if port not in self.free:
                        self.free[port] = free_port()
                    text = text.replace(f"{host}:{port}", f"127.0.0.1:{self.free[port]}")
        return text


def environment(home: Path, wheelhouse: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "RASM_"))}
    env.update(
        PATH=f"{Path(sys.prefix) / 'bin'}{os.pathsep}{env.get('PATH', '')}",
        VIRTUAL_ENV=sys.prefix,
        COLUMNS="80",
        NO_COLOR="1",
        PYTHONDONTWRITEBYTECODE="1",
        # the wall-clock demos (a 40 s Hotbox, a 60 s TurtleBot) run 15 s: the Hotbox's lid opens at
        # 8 s and stays open past 13 s (boost_while_open is put to the test, as in the README);
        # tests/platform and tests/turtlebot test the whole loops on both clocks
        RASM_MAX_WALL_SECONDS=WALL_SECONDS,
        RASM_WHEELHOUSE=str(wheelhouse),  # the session's, shared with tests/workflow
    )
    env.pop("PYTHONPATH", None)
    # pytest prints whole failure messages in its summary when CI or BUILD_NUMBER is set; the
    # guides show what a user's terminal shows
    env.pop("CI", None)
    env.pop("BUILD_NUMBER", None)
    # ~ and temporary files in the test's folder (a guide deploys to ~/hotbox); pip's cache
    # stays the user's, so that packaging finds what it downloaded before
    env["PIP_CACHE_DIR"] = os.environ.get("PIP_CACHE_DIR", str(Path.home() / ".cache" / "pip"))
    env["HOME"] = env["TMPDIR"] = str(home)
    return env


def shell(args: list[str], folder: Path, env: dict) -> subprocess.CompletedProcess:
    """Run a block's shell in a session of its own; what it left running in the background
    (``command &``) is stopped when it ends, as closing the reader's terminal would."""
    # files, not pipes: a background command keeps a pipe open after the shell has ended
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        process = subprocess.Popen(
            args, cwd=folder, env=env, stdout=out, stderr=err, text=True,
            stdin=subprocess.DEVNULL, start_new_session=True,
        )
        try:
            process.wait(timeout=COMMAND_TIMEOUT)
        finally:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGTERM)
            process.wait()
        out.seek(0)
        err.seek(0)
        return subprocess.CompletedProcess(args, process.returncode, out.read(), err.read())


def run_shell(block: Block, folder: Path, env: dict, servers: Servers) -> list[str]:
    """Run a command block; the problems found (an empty list when it did what it shows)."""
    problems = []
    first = "\n".join(servers.substitute(c) for c in block.directives.get("run first", []))
    if block.lang == "console":
        commands = console_commands(block)
        script = ["exec 2>&1", first]
        for command in commands:
            script.append(servers.substitute(command.command))
            script.append(f'__rc=$?; printf "\\n{SEPARATOR}%d{SEPARATOR}\\n" $__rc; (exit $__rc)')
        done = shell(["bash", "-c", "\n".join(script)], folder, env)
        chunks = done.stdout.split(SEPARATOR)
        outputs, codes = chunks[0:-1:2], [int(c) for c in chunks[1::2]]
        if len(codes) != len(commands):
            return [f"{block.where}: the block stopped after {len(codes)} of {len(commands)} "
                    f"commands:\n{done.stdout}{done.stderr}"]
        for i, (command, output, code) in enumerate(zip(commands, outputs, codes, strict=True)):
            output = output.lstrip("\n") if i else output
            next_shows_code = i + 1 < len(commands) and commands[i + 1].command == "echo $?"
            if command.expected:
                if not output_matches(command.expected, output):
                    problems.append(
                        f"{block.guide}:{command.line}: $ {command.command}\n--- the guide "
                        "shows:\n" + "\n".join(command.expected) + f"\n--- it printed (exit "
                        f"{code}):\n{output.rstrip()}"
                    )
            elif code != 0 and not next_shows_code:
                problems.append(f"{block.guide}:{command.line}: $ {command.command}\nexit {code}:"
                                f"\n{output.rstrip()}")
    else:
        done = shell(["bash", "-e", "-c", first + "\n" + servers.substitute(block.text)],
                     folder, env)
        if done.returncode != 0:
            problems.append(f"{block.where}: exit {done.returncode}\n{done.stdout}{done.stderr}")
    return problems


def run_python(block: Block, folder: Path, env: dict, servers: Servers) -> list[str]:
    first = "\n".join(servers.substitute(c) for c in block.directives.get("run first", []))
    if first:
        done = shell(["bash", "-e", "-c", first], folder, env)
        if done.returncode != 0:
            return [f"{block.where}: 'run first' failed\n{done.stdout}{done.stderr}"]
    source = folder / ".guide_block.py"
    source.write_text(servers.substitute(block.text), encoding="utf-8")
    done = subprocess.run(
        [sys.executable, str(HARNESS), str(source), str(block.line)], cwd=folder, env=env,
        capture_output=True, text=True, timeout=COMMAND_TIMEOUT, stdin=subprocess.DEVNULL,
    )
    source.unlink()
    if done.returncode != 0:
        return [f"{block.where}: the Python block failed\n{done.stdout}{done.stderr}"]
    return []


def write_file(block: Block, folder: Path) -> None:
    name, append = block.file
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a" if append else "w", encoding="utf-8") as out:
        out.write(block.text)


@pytest.mark.parametrize(
    "guide", [pytest.param(g, marks=pytest.mark.slow) if g in SLOW else g for g in GUIDES]
)
def test_the_guide_runs_as_written(guide, tmp_path, request, wheelhouse):
    if guide in PENDING and not os.environ.get("RASM_DOCS_PENDING"):
        pytest.skip(f"{guide}: {PENDING[guide]}")
    folder = workdir(tmp_path)
    home = tmp_path / "tmp"
    home.mkdir()
    env = environment(home, wheelhouse)
    servers = Servers(request)
    problems: list[str] = []
    for block in read_blocks(ROOT, guide):
        kind = block.kind
        if kind == "file":
            write_file(block, folder)
        elif kind == "shell":
            problems += run_shell(block, folder, env, servers)
        elif kind == "python":
            problems += run_python(block, folder, env, servers)
    assert not problems, "\n\n".join(problems)


def test_the_slow_guides_are_guides():
    assert SLOW <= set(GUIDES), SLOW - set(GUIDES)


def test_every_runnable_block_is_run_or_says_why_not():
    """A command or Python block is run unless the guide gives a reason, and reasons are rare."""
    skipped = []
    for guide in GUIDES:
        for block in read_blocks(ROOT, guide):
            if block.lang in ("console", "bash", "sh", "shell", "python"):
                if block.kind == "skip":
                    assert block.skipped, f"{block.where}: 'not run' needs a reason"
                    skipped.append(block.where)
    runnable = sum(
        1 for guide in GUIDES for block in read_blocks(ROOT, guide)
        if block.lang in ("console", "bash", "sh", "shell", "python")
    )
    assert len(skipped) <= runnable // 3, skipped
