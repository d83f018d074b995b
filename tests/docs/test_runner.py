"""The guide runner's own rules: how blocks are read and how shown output is compared."""

from __future__ import annotations

import contextlib
import re
import socket

from hypothesis import given
from hypothesis import strategies as st

from .guides import console_commands, output_matches, read_blocks
from .test_guides import Servers

# printable lines without the elision mark, and not ending in blanks (trailing blanks are ignored)
LINE = st.text(st.characters(blacklist_categories=("Cc", "Cs"), blacklist_characters="\n."),
               max_size=30).map(str.rstrip)
LINES = st.lists(LINE, max_size=8)


@given(LINES)
def test_an_output_matches_itself_shown_in_full(lines):
    assert output_matches(lines, "\n".join(lines) + "\n")


FILLED = st.lists(LINE.filter(bool), max_size=8)  # an output's trailing blank lines are dropped


@given(FILLED, LINES, FILLED)
def test_an_elided_line_stands_for_any_lines(before, hidden, after):
    shown = [*before, "...", *after]
    assert output_matches(shown, "\n".join([*before, *hidden, *after]))


@given(LINES, LINE.filter(bool))
def test_a_line_the_output_lacks_is_a_mismatch(lines, extra):
    assert not output_matches([*lines, extra], "\n".join(lines))


def test_dots_inside_a_line_stand_for_any_text():
    assert output_matches(["ran in ... s"], "ran in 0.52 s\n")
    assert not output_matches(["ran in ... s"], "ran in 0.52 ms and failed\n")


def test_blocks_their_directives_and_commands(tmp_path):
    (tmp_path / "guide.md").write_text(
        "Intro.\n\n<!-- not run: it serves forever -->\n```console\n$ rasm serve\n```\n\n"
        "<!-- file: trace.jsonl -->\n```json\n{\"time\": 0}\n```\n\n"
        "```python\n# test_x.py\nx = 1\n```\n\n"
        "```console\n$ rasm check p.rv t.jsonl\nok\n$ echo $?\n0\n```\n"
    )
    skipped, data, test_file, console = read_blocks(tmp_path, "guide.md")
    assert skipped.kind == "skip" and skipped.skipped == "it serves forever"
    assert data.kind == "file" and data.file == ("trace.jsonl", False)
    assert test_file.kind == "file" and test_file.file == ("test_x.py", False)
    assert console.kind == "shell" and console.where == "guide.md:18"
    commands = console_commands(console)
    assert [(c.command, c.expected) for c in commands] == [
        ("rasm check p.rv t.jsonl", ["ok"]), ("echo $?", ["0"])
    ]
    assert [c.line for c in commands] == [19, 21]


def test_a_port_the_guide_listens_on_is_one_free_port_for_all_its_blocks(request):
    servers = Servers(request)
    block = 'open_transport("zenoh://127.0.0.1:7448", listen=["tcp/127.0.0.1:7448"])'
    with socket.socket() as shown_port:
        # held (or someone else's already): the free port cannot be the one the guide shows
        with contextlib.suppress(OSError):
            shown_port.bind(("127.0.0.1", 7448))
        first = re.findall(r"127\.0\.0\.1:(\d+)", servers.substitute(block))
    later = re.findall(r"127\.0\.0\.1:(\d+)", servers.substitute("zenoh://localhost:7448"))
    assert len(set(first + later)) == 1 and first[0] != "7448"
    with socket.socket() as sock:  # nobody listens there: the guide's session can
        sock.bind(("127.0.0.1", int(first[0])))
    assert servers.substitute("zenoh://127.0.0.1:7447") == "zenoh://127.0.0.1:7447"
