"""The ten Timescales specification patterns (Ulus, RV 2019), written from their descriptions.

Each pattern is a Dwyer-style property over propositions p, q, r, s with bounds l and u, in
three concrete syntaxes: rasm's, reelay's (past MTL, ``{p}`` atoms) and rtamt's (STL over
floats, ``(p >= 0.5)`` atoms). rtamt has no open bounds, so ``since[u, inf]`` is rewritten
for it as ``once[u,u](φ since ψ) and historically[0,u-1] φ`` (equivalent in discrete time).

Traces are random, with densities that keep the patterns' scopes busy: q and r (scope
delimiters) are rare, p and s (the events the patterns talk about) frequent. This is our own
generator, not the published (GPL) one.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

__all__ = ["PATTERNS", "RASM_HEADER", "Pattern", "pattern", "trace"]


@dataclass(frozen=True)
class Pattern:
    """One pattern instance: the same property in three syntaxes."""

    name: str
    rasm: str
    reelay: str
    rtamt: str


# The patterns' bodies: each pattern is historically(body). {x} marks an atom; [a:b] a bound;
# [u:] an open bound (rasm: [u, inf])
SCOPED = "({r} and (not {q}) and (once {q}))"
RESPOND = "(({s} -> (once[l:u] {p})) and (not ((not {s}) since[u:] {p})))"
PATTERNS = {
    "AbsentAQ": "(once[0:u] {q}) -> ((not {p}) since {q})",
    "AbsentBR": "{r} -> (historically[0:u] (not {p}))",
    "AbsentBQR": SCOPED + " -> ((not {p}) since[l:u] {q})",
    "AlwaysAQ": "(once[0:u] {q}) -> ({p} since {q})",
    "AlwaysBR": "{r} -> (historically[0:u] {p})",
    "AlwaysBQR": SCOPED + " -> ({p} since[l:u] {q})",
    "RecurGLB": "once[0:u] {p}",
    "RecurBQR": SCOPED + " -> ((once[0:u] ({p} or {q})) since {q})",
    "RespondGLB": RESPOND,
    "RespondBQR": SCOPED + " -> (" + RESPOND + " since {q})",
}


def _fill(template: str, low: int, high: int) -> str:
    return template.replace("[l:u]", f"[{low}:{high}]").replace("[0:u]", f"[0:{high}]").replace(
        "[u:]", f"[{high}:]"
    )


def _to_rasm(text: str) -> str:
    import re

    text = re.sub(r"\{(\w+)\}", r"\1", text)
    text = re.sub(r"\[(\d+):(\d+)\]", r"[\1, \2]", text)
    return re.sub(r"\[(\d+):\]", r"[\1, inf]", text)


def _to_reelay(text: str) -> str:
    import re

    # reelay writes unbounded-since/once without brackets and open bounds as [u:]
    return re.sub(r"\{(\w+)\}", r"{\1}", text)


def _to_rtamt(text: str, high: int) -> str:
    import re

    # ((not {s}) since[u:] {p})  ->  (once[u:u]((not s) since p) and historically[0:u-1](not s))
    def open_since(match: re.Match) -> str:
        left, right = match.group(1), match.group(3)
        bound = int(match.group(2))
        return (
            f"((once[{bound}:{bound}]({left} since {right})) and "
            f"(historically[0:{bound - 1}]{left}))"
        )

    text = re.sub(r"(\(not \{s\}\)) since\[(\d+):\] (\{p\})", open_since, text)
    # rtamt reads a variable named s as the seconds unit: call it sx
    text = text.replace("{s}", "{sx}")
    return re.sub(r"\{(\w+)\}", r"(\1 >= 0.5)", text)


def pattern(name: str, low: int, high: int, *, body: bool = False) -> Pattern:
    """Pattern ``name`` with bounds ``l = low`` and ``u = high`` (integers, low < high).

    ``body=True`` leaves out the outermost ``historically``, so that a differential test sees
    the pattern's value at every record instead of "false ever since the first violation".
    """
    text = _fill(PATTERNS[name], low, high)
    if not body:
        text = f"historically({text})"
    return Pattern(name, _to_rasm(text), _to_reelay(text), _to_rtamt(text, high))


def trace(n: int, seed: int = 0, *, density: dict[str, float] | None = None) -> list[dict]:
    """``n`` records over p, q, r, s (all four set on every record), discrete time 0, 1, …"""
    rng = random.Random(seed)
    density = density or {"p": 0.6, "q": 0.02, "r": 0.05, "s": 0.1}
    return [
        {"time": k, **{name: rng.random() < chance for name, chance in density.items()}}
        for k in range(n)
    ]


RASM_HEADER = "input p: bool\ninput q: bool\ninput r: bool\ninput s: bool\n"
