"""The lines of a generated monitor, before they are written out for ``step`` or for ``run``.

The same body is generated twice (:mod:`rasm.properties.codegen`): in ``step(t, record)``,
online, verdicts are Verdict objects; in ``run(records)``, offline, they are plain values in
record order. Most lines read the same in both (:class:`Code`); the others say what they do
and each mode writes them its own way. A :class:`Block` holds the lines under a head (``try:``,
``if …:``), one level further in. Lines are written with :func:`render`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

__all__ = ["Block", "Code", "Emit", "Fault", "Line", "Offline", "Online", "Reject", "render"]

INDENT = "    "


class Line(Protocol):
    def write(self, out: list[str], online: bool, pad: str) -> None:
        """Append its source in ``step`` (``online``) or in ``run`` to ``out``, each line
        ``pad`` in (nothing where it has none in that mode)."""
        ...


@dataclass(frozen=True)
class Code:
    """A line that reads the same online and offline."""

    text: str

    def write(self, out: list[str], online: bool, pad: str) -> None:
        out.append(pad + self.text)


@dataclass(frozen=True)
class Online:
    """A line only ``step`` has: it keeps the records owed a verdict, which only a fault
    online needs to know (offline, values go out in record order)."""

    text: str

    def write(self, out: list[str], online: bool, pad: str) -> None:
        if online:
            out.append(pad + self.text)


@dataclass(frozen=True)
class Offline:
    """Lines only ``run`` has (such as handing on robustness values in record order: online
    each goes out with its verdict)."""

    lines: tuple[Line, ...]

    def write(self, out: list[str], online: bool, pad: str) -> None:
        if not online:
            for line in self.lines:
                line.write(out, online, pad)


@dataclass(frozen=True)
class Block:
    """``head`` (``try:``, ``if …:``, ``while …:``) and the lines under it."""

    head: str
    body: tuple[Line, ...]

    def write(self, out: list[str], online: bool, pad: str) -> None:
        out.append(pad + self.head)
        inner = pad + INDENT
        for line in self.body:
            line.write(out, online, inner)


@dataclass(frozen=True)
class Emit:
    """Property ``number``'s verdict ``value`` for the record ``index`` at ``time`` (each the
    source of an expression): a Verdict online; offline a plain value, through ``order`` (the
    property's :class:`~rasm.properties.streams.InOrder`) where verdicts come in any order.

    ``robustness`` (online only): the name of the variable holding the verdict's robustness, a
    float, ``final`` (else it may be None: not final yet)."""

    number: int
    index: str
    time: str
    value: str
    order: str | None = None
    robustness: str | None = None
    final: bool = True

    def write(self, out: list[str], online: bool, pad: str) -> None:
        number, index, value, order = self.number, self.index, self.value, self.order
        if online:
            r = self.robustness
            if r is None:
                robust = "None, None"
            elif self.final:
                robust = f"{r}, ({r}, {r})"
            else:
                robust = f"{r}, {r} if {r} is None else ({r}, {r})"
            # built as its tuple of fields (VERDICT_NEW is tuple.__new__): the NamedTuple's own
            # __new__ is a Python function, a third of step's time on a cheap property
            out.append(f"{pad}out.append(VERDICT_NEW(Verdict, "
                       f"(NAME_{number}, {index}, {self.time}, {value}, None, {robust})))")
        elif order is None:
            out.append(f"{pad}values_{number}({value})")
        elif index == "i":
            out.append(f"{pad}{order}.put(i, {value}, values_{number})")
        else:
            # values in record order go straight on (the common case: one call less)
            out.append(f"{pad}if {index} == {order}.next and not {order}.waiting: "
                       f"values_{number}({value}); {order}.next += 1")
            out.append(f"{pad}else: {order}.put({index}, {value}, values_{number})")


@dataclass(frozen=True)
class Fault:
    """The handler of property ``number``'s exception (``_exc``), at a record or, ``finishing``,
    at the end of the trace (:meth:`rasm.properties.monitor.Monitor._fault`)."""

    number: int
    finishing: bool

    def write(self, out: list[str], online: bool, pad: str) -> None:
        number = self.number
        if not online:
            out.append(f"{pad}FAULT_RUN({number}, i, {'None' if self.finishing else 'tn'}, _exc)")
        elif self.finishing:
            out.append(f"{pad}FAULT({number}, None, None, None, _exc, out)")
        else:
            out.append(f"{pad}FAULT({number}, i, t, tn, _exc, out)")


@dataclass(frozen=True)
class Reject:
    """Refuse the record (when ``condition`` holds; None: always): its ``signal``'s value is
    not a ``kind`` (signal None: its time or the record itself is wrong). ``step`` counts the
    rejection and returns no verdicts; ``run`` raises."""

    condition: str | None
    signal: str | None
    kind: str

    def write(self, out: list[str], online: bool, pad: str) -> None:
        test = "" if self.condition is None else f"if {self.condition}: "
        reject = "REJECT_STEP" if online else "REJECT_RUN"
        out.append(f"{pad}{test}return {reject}(i + 1, t, rec, {self.signal!r}, {self.kind!r})")


def render(lines: Sequence[Line], online: bool, pad: str = "") -> list[str]:
    """The source lines of ``lines`` in ``step`` (``online``) or in ``run``, ``pad`` in."""
    out: list[str] = []
    for line in lines:
        line.write(out, online, pad)
    return out
