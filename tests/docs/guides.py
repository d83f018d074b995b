"""The guides' code blocks, read from the Markdown: what a reader is told to type or write.

A fenced block is one of:

* a **command block** (`console`: lines starting with ``$ `` are commands, the lines after one are
  its output; `bash`/`sh`: a script): run in the guide's folder;
* a **Python block** (`python`): run with the guide's folder as the current directory; a
  top-level expression line whose comment shows a value (``verify(signed, key)  # True``) or a
  ``print(...)`` line whose comment shows what it prints must give exactly that;
* a **file**: a block whose first line is a comment naming a file (``# props.rv``,
  ``# test_hotbox.py``), or one after ``<!-- file: NAME -->``, is written to that file instead of
  run (``<!-- append: NAME -->`` adds it at the end of one);
* anything else (YAML excerpts, JSON, diagrams, output shown in prose) is data, not run.

HTML comments right before a block (invisible on the rendered page) say more:
``<!-- not run: REASON -->`` leaves a block out with its reason (a server that runs until
stopped, a command that needs a robot); ``<!-- run first: COMMAND -->`` runs a shell command the
prose describes ("misspell the initial state…") before the block.

Expected output may elide: a line ``...`` stands for any number of lines, and ``...`` inside a
line for any text (timings, process ids, hashes).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

FENCE = re.compile(r"^```(\S*)\s*$")
DIRECTIVE = re.compile(r"^<!--\s*([a-z ]+?)\s*:\s*(.*?)\s*-->\s*$")
FILE_COMMENT = re.compile(r"^#\s+([\w./-]+\.(?:py|rv|yaml|yml|jsonl|json|txt))\s*$")
SHELL = {"console", "bash", "sh", "shell"}


@dataclass
class Block:
    guide: str  # path relative to the repository
    line: int  # of the opening fence
    lang: str
    text: str
    directives: dict[str, list[str]] = field(default_factory=dict)

    @property
    def where(self) -> str:
        return f"{self.guide}:{self.line}"

    @property
    def skipped(self) -> str | None:
        reasons = self.directives.get("not run")
        return reasons[0] if reasons else None

    @property
    def file(self) -> tuple[str, bool] | None:
        """``(name, append)`` when the block is a file to write."""
        for key, append in (("file", False), ("append", True), ("tutorial", False)):
            for name in self.directives.get(key, []):
                if "." in name:
                    return name, append
        first = self.text.split("\n", 1)[0]
        match = FILE_COMMENT.match(first)
        if match and self.lang not in SHELL:
            return match.group(1), False
        return None

    @property
    def kind(self) -> str:
        """``skip``, ``file``, ``shell``, ``python`` or ``data``."""
        if self.skipped is not None:
            return "skip"
        if self.file is not None:
            return "file"
        if self.lang in SHELL:
            return "shell"
        if self.lang == "python":
            return "python"
        return "data"


def read_blocks(root: Path, guide: str) -> list[Block]:
    """The fenced blocks of ``root/guide`` in order, with the directives just before each."""
    lines = (root / guide).read_text(encoding="utf-8").split("\n")
    blocks: list[Block] = []
    i = 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        if not match:
            i += 1
            continue
        end = i + 1
        while end < len(lines) and not lines[end].startswith("```"):
            end += 1
        directives: dict[str, list[str]] = {}
        j = i - 1
        while j >= 0 and (found := DIRECTIVE.match(lines[j])):
            directives.setdefault(found.group(1), []).insert(0, found.group(2))
            j -= 1
        text = "\n".join(lines[i + 1 : end])
        blocks.append(Block(guide, i + 1, match.group(1).lower(), text + "\n", directives))
        i = end + 1
    return blocks


@dataclass
class Command:
    line: int
    command: str
    expected: list[str]


def console_commands(block: Block) -> list[Command]:
    """The ``$`` commands of a console block with the output lines shown after each."""
    commands: list[Command] = []
    for offset, text in enumerate(block.text.rstrip("\n").split("\n"), start=1):
        if text.startswith("$ "):
            commands.append(Command(block.line + offset, text[2:], []))
        elif commands:
            commands[-1].expected.append(text)
        elif text.strip():
            raise ValueError(f"{block.where}: output before the first '$ ' command: {text!r}")
    return commands


def output_matches(expected: list[str], actual: str) -> bool:
    """Whether ``actual`` is what ``expected`` shows (``...`` elides; trailing blanks ignored)."""
    lines = [line.rstrip() for line in actual.rstrip().split("\n")] if actual.strip() else []
    expected = [line.rstrip() for line in expected]
    while expected and not expected[-1]:
        expected.pop()
    pattern = []
    for line in expected:
        if line.strip() in ("...", "…"):
            pattern.append(r"(?:[^\n]*\n)*?")
            continue
        parts = [re.escape(part) for part in line.split("...")]
        pattern.append("[^\n]*".join(parts) + "\n")
    return re.fullmatch("".join(pattern), "".join(f"{line}\n" for line in lines)) is not None
