"""A JSONL trace read in parts by byte range: the :class:`rasm.properties.shards.Part` of a file.

A part is the lines that start in ``[start, end)``, the bytes cut just after a line break
(:func:`cut_points`), so the lines of the parts are exactly the lines of the whole file, split as
:func:`open` splits them (``\\n``, ``\\r\\n`` or a lone ``\\r``). The part's own lines and those
after it are read forward; the lines before it backward, a block at a time; a signal's last
value before it by a search of the raw bytes for its key (a line that sets it holds its name
in quotes, or a backslash where the key is escaped), so a signal set once at the start of a
large trace is found without decoding the lines in between. Every line read is decoded and
checked as :func:`rasm.trace.scan_records` checks it.
"""

from __future__ import annotations

import io
import os
import re
from collections.abc import Collection, Iterator, Mapping

from rasm.trace import scan_records

__all__ = ["JsonlPart", "cut_points"]

BLOCK = 1 << 16  # bytes read backward at a time, at first
MAX_BLOCK = 1 << 22


def cut_points(path: str, parts: int) -> list[int]:
    """Byte offsets cutting the file into about ``parts`` parts of equal size, each just after
    a line break: ``[0, …, size]``."""
    size = os.path.getsize(path)
    cuts = [0]
    with open(path, "rb") as handle:
        for k in range(1, parts):
            at = max(size * k // parts, cuts[-1])
            handle.seek(at)
            while True:
                block = handle.read(BLOCK)
                if not block:
                    at = size
                    break
                found = block.find(b"\n")
                if found >= 0:
                    at += found + 1
                    break
                at += len(block)
            if cuts[-1] < at < size:
                cuts.append(at)
    cuts.append(size)
    return cuts


class _Range(io.RawIOBase):
    """Bytes ``[start, end)`` of an open file (read with ``pread``: no shared position)."""

    def __init__(self, fd: int, start: int, end: int) -> None:
        self.fd, self.at, self.end = fd, start, end

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        n = min(len(buffer), self.end - self.at)
        if n <= 0:
            return 0
        data = os.pread(self.fd, n, self.at)
        buffer[:len(data)] = data
        self.at += len(data)
        return len(data)


def _lines(data: bytes) -> list[str]:
    """Whole lines of bytes, split as a file opened in text mode splits them."""
    return list(io.StringIO(data.decode("utf-8"), newline=None))


class JsonlPart:
    """The lines of ``path`` that start in ``[start, end)``, and the lines around them.

    ``unchecked`` are the signals whose values the reader checks (those the monitors do not:
    see :func:`rasm.properties.check.check_file`). Use it as a context manager, or close it."""

    def __init__(self, path: str, start: int, end: int, *,
                 unchecked: Mapping[str, str] | None = None) -> None:
        self.path, self.start, self.end = path, start, end
        self.unchecked = dict(unchecked or {})
        self.fd = os.open(path, os.O_RDONLY)
        self.size = os.fstat(self.fd).st_size
        self._given: list = []  # the records earlier() gave, newest first
        self._rest: list = []  # decoded by earlier() but not given yet, newest last
        self._unread = start  # earlier() has not read the bytes before this

    def close(self) -> None:
        os.close(self.fd)

    def __enter__(self) -> JsonlPart:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _forward(self, start: int, end: int) -> Iterator[tuple[float, dict]]:
        raw = io.BufferedReader(_Range(self.fd, start, end), buffer_size=1 << 16)
        text = io.TextIOWrapper(raw, encoding="utf-8", newline=None)
        return scan_records(text, self.unchecked, source=self.path)

    def inside(self) -> Iterator[tuple[float, dict]]:
        return self._forward(self.start, self.end)

    def beyond(self) -> Iterator[tuple[float, dict]]:
        return self._forward(self.end, self.size)

    def _block_before(self, end: int, size: int) -> tuple[int, bytes]:
        """The whole lines in about ``size`` bytes before ``end``: where they start, and them."""
        while True:
            low = max(0, end - size)
            block = os.pread(self.fd, end - low, low)
            if low == 0:
                return 0, block
            found = block.find(b"\n")
            if found >= 0:
                return low + found + 1, block[found + 1:]
            size *= 2  # a line longer than the block

    def _decode(self, data: bytes) -> list:
        return list(scan_records(_lines(data), self.unchecked, source=self.path))

    def earlier(self) -> Iterator[tuple[float, dict]]:
        # each call reads anew (held_before() goes on from where the last one stopped)
        self._given, self._rest, self._unread = [], [], self.start
        size = BLOCK
        while self._rest or self._unread > 0:
            if not self._rest:
                self._unread, block = self._block_before(self._unread, size)
                self._rest = self._decode(block)
                size = min(size * 2, MAX_BLOCK)
                continue
            record = self._rest.pop()
            self._given.append(record)
            yield record

    def held_before(self, count: int, names: Collection[str]) -> dict[str, object]:
        wanted, found = set(names), {}

        def note(records) -> None:
            for _, record in records:
                for name in wanted & record.keys():
                    found[name] = record[name]
                wanted.difference_update(record.keys())
                if not wanted:
                    return

        note(self._given[count:])
        if wanted:
            note(reversed(self._rest))
        end = self._unread
        size = BLOCK
        while wanted and end > 0:
            keys = b"|".join(re.escape(b'"' + n.encode("utf-8") + b'"') for n in sorted(wanted))
            candidates = re.compile(keys + rb"|\\")
            start, block = self._block_before(end, size)
            lines: list[tuple[int, int]] = []  # the lines holding a candidate, newest last
            for match in candidates.finditer(block):
                if lines and match.start() < lines[-1][1]:
                    continue
                head = block.rfind(b"\n", 0, match.start()) + 1
                tail = block.find(b"\n", match.end())
                lines.append((head, len(block) if tail < 0 else tail + 1))
            for head, tail in reversed(lines):
                note(self._decode(block[head:tail])[::-1])
                if not wanted:
                    break
            end = start
            size = min(size * 2, MAX_BLOCK)
        return found
