"""One exception hierarchy for rasm.

Users catch :class:`RasmError`; each subclass says which layer failed. Errors that come from a
user's file carry its name, line and column (1-based) and print as ``file:line:col: message``,
the form editors and CI logs understand.
"""

from __future__ import annotations

import difflib
import os
import signal
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path


class RasmError(Exception):
    """Base class of every error rasm raises on purpose."""


@dataclass(frozen=True)
class Location:
    """A place in a user's file. ``line`` and ``col`` are 1-based; 0 means unknown."""

    file: str
    line: int = 0
    col: int = 0

    def __str__(self) -> str:
        if self.line <= 0:
            return self.file
        if self.col <= 0:
            return f"{self.file}:{self.line}"
        return f"{self.file}:{self.line}:{self.col}"


class SourceError(RasmError):
    """A problem in something the user wrote: a chart, a property file, rules, a manifest, a trace.

    The command line prints it as ``file:line:col: message`` and exits with code 2.
    ``excerpt`` is an optional marked copy of the offending line (``^`` under the column).
    """

    def __init__(self, message: str, location: Location, excerpt: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.location = location
        self.excerpt = excerpt

    def __str__(self) -> str:
        text = f"{self.location}: {self.message}"
        if self.excerpt:
            text += "\n" + self.excerpt
        return text


class SourceErrors(RasmError):
    """Several :class:`SourceError` found in one pass (linting reports all, not just the first)."""

    def __init__(self, errors: list[SourceError]) -> None:
        super().__init__("\n".join(str(e) for e in errors))
        self.errors = list(errors)


EXCERPT_WIDTH = 100  # characters of a long line shown around the marked column


def mark(text: str, line: int, col: int, width: int = 1) -> str | None:
    """Return the ``line``-th line of ``text`` with a ``^^^`` marker under ``col`` (1-based).

    A line longer than :data:`EXCERPT_WIDTH` is cut to that many characters around the column
    (``...`` where it was cut), and control characters are shown as ``?``: a hostile file
    cannot fill the terminal or write to it through an error message.
    """
    lines = text.splitlines()
    if not 1 <= line <= len(lines):
        return None
    source = lines[line - 1]
    start = max(col - 1, 0)
    width = max(min(width, EXCERPT_WIDTH // 2), 1)
    left, right = "", ""
    if len(source) > EXCERPT_WIDTH:
        first = max(0, min(start - EXCERPT_WIDTH // 2, len(source) - EXCERPT_WIDTH))
        left = "..." if first > 0 else ""
        right = "..." if first + EXCERPT_WIDTH < len(source) else ""
        source, start = source[first : first + EXCERPT_WIDTH], start - first
    source = "".join("?" if (ord(c) < 32 and c != "\t") or c == "\x7f" else c for c in source)
    pad = "".join(c if c == "\t" else " " for c in left + source[:start])
    return f"    {left}{source}{right}\n    {pad}{'^' * width}"


def marked_error(message: str, where: Location, width: int = 1) -> SourceError:
    """A :class:`SourceError` at ``where`` with the marked excerpt of its line, when the file
    reads (else without one)."""
    try:
        text = read_utf8(where.file)
    except (OSError, SourceError):
        return SourceError(message, where)
    return SourceError(message, where, mark(text, where.line, where.col, width))


def printable(text: str) -> str:
    """``text`` with control characters other than newline and tab escaped (``\\x1b``): a
    message that quotes a hostile file cannot drive the terminal it is printed on."""
    if text.isprintable():
        return text
    return "".join(
        c if c.isprintable() or c in "\n\t" else repr(c)[1:-1] for c in text
    )


def not_utf8(file: str, exc: UnicodeDecodeError) -> SourceError:
    """A :class:`SourceError` for a file that is not UTF-8, placed at its first bad byte."""
    data = exc.object[: exc.start]
    line = data.count(b"\n") + 1
    col = exc.start - (data.rfind(b"\n") + 1) + 1
    return SourceError(f"not a UTF-8 text file: {exc.reason}", Location(file, line, col))


def read_utf8(path: str | os.PathLike[str]) -> str:
    """The text of ``path``; a file that is not UTF-8 raises :class:`SourceError` at its first
    bad byte (line and column)."""
    data = Path(path).read_bytes()
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise not_utf8(str(path), exc) from None


class Interrupted(KeyboardInterrupt):
    """A real Ctrl-C: what the ``rasm`` command's SIGINT handler raises.

    User code (chart code, stage components, a simulator, a twin) may raise ``SystemExit``,
    ``KeyboardInterrupt`` or any other ``BaseException`` itself; that fails the step or stage
    like any exception and does not stop rasm. Only an interrupt from outside does (see
    :func:`is_interrupt`).
    """


def raise_interrupted(signum: int, frame: object) -> None:
    """A SIGINT handler raising :class:`Interrupted` (installed by the ``rasm`` command)."""
    raise Interrupted


def is_interrupt(exc: BaseException) -> bool:
    """Whether ``exc``, caught around user code, is a real interrupt that must stop rasm:
    an :class:`Interrupted`, or a ``KeyboardInterrupt`` while Python's default SIGINT handler is
    in place (rasm used as a library: a Ctrl-C cannot be told from one user code raised, so it
    stops). Anything else user code raised is that code's failure."""
    if isinstance(exc, Interrupted):
        return True
    return (
        isinstance(exc, KeyboardInterrupt)
        and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    )


class Misfit(RasmError):
    """A value that does not fit its declared type or range (see :func:`rasm.values.fit`).

    ``reason`` says why without quoting the value (``expected float, got str``: what a count of
    refusals is keyed by); the message quotes it (``expected float, got str 'hot'``).
    """

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


class StatechartError(RasmError):
    """The statechart layer failed: a step of a chart raised, or a chart cannot be run.

    (A chart that does not load is a :class:`SourceError` at its place.)
    """


class ExecutionError(StatechartError):
    """A step of a chart raised and was rolled back (:class:`rasm.statechart.Interpreter`).

    ``cause`` (also ``__cause__``) is what sismic or the chart's code raised: sismic's
    ``ContractError``, ``PropertyStatechartError``, ``CodeEvaluationError``, … The message
    names it: ``CodeEvaluationError: 'division by zero' occurred while executing 'x = 1 / 0'``.
    """

    def __init__(self, cause: BaseException) -> None:
        super().__init__(f"{type(cause).__name__}: {cause}")
        self.cause = cause


class SpecError(RasmError):
    """The property language layer failed."""


class RulesError(RasmError):
    """The rules layer failed."""


class PlatformError(RasmError):
    """A building block or the loop failed."""


class KnowledgeError(RasmError):
    """The knowledge layer failed: a value of the wrong type, time going back, a storage fault."""


class CommError(RasmError):
    """The communication layer failed: a bad transport URL, topic or payload, or a broker fault."""


def closest(name: str, candidates: Collection[str]) -> str | None:
    """The candidate most like ``name`` (a likely misspelling of it, for a "did you mean"), or
    None."""
    found = difflib.get_close_matches(name, sorted(candidates), n=1)
    return found[0] if found else None
