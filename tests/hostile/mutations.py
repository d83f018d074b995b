"""Hypothesis strategies for hostile files: a valid file with a few hostile edits.

An edit replaces a few characters somewhere with a token that has broken a reader before (a NUL
byte, deep nesting, a 5000-digit integer, an alias, a tag, a date that does not exist, ...).
Starting from a valid file keeps most examples close enough to valid to reach the deeper
checks, where the interesting failures are; ``free_text`` adds anything at all.
"""

from __future__ import annotations

from hypothesis import strategies as st

TOKENS = [
    "\x00", "\x1b[2J", "\ufeff", "\u2028", "\\", '"', "'", ":", ": ", "- ", "-", "{", "}", "[",
    "]", ",", "&a ", "*a", "<<: *a", "!!binary ", "!!python/object:os.system ", "!!float ",
    "!!int ", "!!set ", "!!omap ", "? ", "|", ">", "~", "null", "true", "yes", "0x", "0o7",
    "1_0", "1" * 5000, "9" * 400, "1e999", "-1e999", ".nan", "NaN", "Infinity", "2021-02-30",
    "2021-13-01 25:61:61", "[" * 300, "{a: " * 120, "(" * 300, "not " * 400, "\n", "\n  ",
    "\t", "#", "%YAML 1.1\n---\n", "---\n", "\n...\n", "é", "😀", "=", "==", "<=", "->",
    "and", "or", "always", "eventually[0, 1e308]", "once[0, inf]", "prev(", "time", "avg(",
    "sum[0,5s](", "1/0", "0", "-0", "inf", "int", "float", "str", "bool", "enum", "real",
]


@st.composite
def edited(draw: st.DrawFn, seed: str, max_edits: int = 3) -> str:
    """``seed`` with up to ``max_edits`` replacements of a few characters by a token."""
    text = seed
    for _ in range(draw(st.integers(1, max_edits))):
        at = draw(st.integers(0, len(text)))
        cut = draw(st.integers(0, 4))
        token = draw(st.sampled_from(TOKENS))
        text = text[:at] + token + text[at + cut :]
    return text


def hostile(seed: str) -> st.SearchStrategy[str]:
    """Mostly edits of ``seed``; now and then a few edits on top of its lines shuffled, or
    free text."""
    lines = st.permutations(seed.splitlines(keepends=True)).map("".join)
    return st.one_of(
        edited(seed),
        edited(seed),
        lines.flatmap(lambda text: edited(text, 2)),
        st.text(max_size=200),
    )
