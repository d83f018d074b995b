"""The engineer's regions in generated files: ``# >>> rasm:user ID`` … ``# <<< rasm:user ID``.

Regenerating a file renders it afresh and puts back the text each region held before. A region
whose ID no longer exists (its component left the model) cannot be put back: it is returned as an
orphan so the caller can save it and say so. Lines ending in ``# placeholder`` are generated
defaults; a region holding nothing else is not worth reporting when it disappears.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from rasm.errors import RasmError

__all__ = ["Region", "RegionError", "merge", "parse_regions"]

_OPEN = re.compile(r"^\s*(?:#|<!--) >>> rasm:user (\S+?)(?: -->)?\s*$")
_CLOSE = re.compile(r"^\s*(?:#|<!--) <<< rasm:user (\S+?)(?: -->)?\s*$")


class RegionError(RasmError, ValueError):
    """Markers that do not pair up (an open without its close, a close without its open)."""


@dataclass(frozen=True)
class Region:
    """One marked region: its ID, the lines between its markers, and where it opened."""

    id: str
    body: tuple[str, ...]
    line: int

    @property
    def written(self) -> bool:
        """True if the region holds more than generated placeholders and blank lines."""
        return any(
            line.strip() and not line.rstrip().endswith("# placeholder") for line in self.body
        )


def parse_regions(text: str, source: str = "<text>") -> dict[str, Region]:
    """The regions of ``text`` by ID; raises :class:`RegionError` on unbalanced markers."""
    regions: dict[str, Region] = {}
    current: tuple[str, int, list[str]] | None = None
    for number, line in enumerate(text.splitlines(), start=1):
        opened, closed = _OPEN.match(line), _CLOSE.match(line)
        if opened:
            if current is not None:
                raise RegionError(
                    f"{source}:{number}: region {opened[1]} opens inside "
                    f"{current[0]} (line {current[1]})"
                )
            current = (opened[1], number, [])
        elif closed:
            if current is None or current[0] != closed[1]:
                raise RegionError(
                    f"{source}:{number}: '<<< rasm:user {closed[1]}' closes a "
                    "region that is not open"
                )
            if current[0] in regions:
                raise RegionError(f"{source}:{current[1]}: region {current[0]} appears twice")
            regions[current[0]] = Region(current[0], tuple(current[2]), current[1])
            current = None
        elif current is not None:
            current[2].append(line)
    if current is not None:
        raise RegionError(f"{source}:{current[1]}: region {current[0]} is never closed")
    return regions


def merge(fresh: str, old: str | None, source: str = "<text>") -> tuple[str, list[Region]]:
    """``fresh`` with every region's body taken from ``old``; also the orphaned old regions."""
    if old is None:
        return fresh, []
    kept = parse_regions(old, source)
    parse_regions(fresh, "<generated>")  # the templates' own markers must pair up
    out: list[str] = []
    skipping: str | None = None
    used: set[str] = set()
    for line in fresh.splitlines(keepends=True):
        if skipping is not None:
            closed = _CLOSE.match(line.rstrip("\n"))
            if closed and closed[1] == skipping:
                out.append(line)
                skipping = None
            continue
        out.append(line)
        opened = _OPEN.match(line.rstrip("\n"))
        if opened and opened[1] in kept:
            out.extend(body + "\n" for body in kept[opened[1]].body)
            used.add(opened[1])
            skipping = opened[1]
    orphans = [region for rid, region in kept.items() if rid not in used]
    return "".join(out), orphans
