"""The lines of a generated monitor, before they are written out for ``step`` or for ``run``.

The same body is generated twice (:mod:`rasm.properties.codegen`): in ``step(t, record)``,
online, verdicts are Verdict objects; in ``run(records)``, offline, they are plain values in
record order. Most lines read the same in both (:class:`Code`); the others say what they do
and each mode writes them its own way. Every line is indented with :meth:`Line.indented`
and written with :meth:`Line.render` (None: the line has nothing to do in that mode).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol

__all__ = ["Code", "Emit", "Fault", "Line", "Online", "Reject", "indent", "render"]


class Line(Protocol):
    def indented(self, pad: str) -> Line:
        """The same line, ``pad`` further in."""
        ...

    def render(self, online: bool) -> str | None:
        """Its source in ``step`` (``online``) or in ``run``; None where it has none."""
        ...


@dataclass(frozen=True)
class Code:
    """A line that reads the same online and offline."""

    text: str

    def indented(self, pad: str) -> Code:
        return Code(pad + self.text)

    def render(self, online: bool) -> str:
        return self.text


@dataclass(frozen=True)
class Online:
    """A line only ``step`` has: it keeps the records owed a verdict, which only a fault
    online needs to know (offline, values go out in record order)."""

    text: str

    def indented(self, pad: str) -> Online:
        return Online(pad + self.text)

    def render(self, online: bool) -> str | None:
        return self.text if online else None


@dataclass(frozen=True)
class Emit:
    """Property ``number``'s verdict ``value`` for the record ``index`` at ``time`` (each the
    source of an expression): a Verdict online; offline a plain value, through ``order`` (the
    property's :class:`~rasm.properties.streams.InOrder`) where verdicts come in any order."""

    number: int
    index: str
    time: str
    value: str
    order: str | None = None
    pad: str = ""

    def indented(self, pad: str) -> Emit:
        return replace(self, pad=pad + self.pad)

    def render(self, online: bool) -> str:
        pad, values = self.pad, f"values_{self.number}"
        if online:
            verdict = f"Verdict(NAME_{self.number}, {self.index}, {self.time}, {self.value})"
            return f"{pad}out.append({verdict})"
        order = self.order
        if order is None:
            return f"{pad}{values}({self.value})"
        if self.index == "i":
            return f"{pad}{order}.put(i, {self.value}, {values})"
        # values in record order go straight on (the common case: one call less)
        return (f"{pad}if {self.index} == {order}.next and not {order}.waiting: "
                f"{values}({self.value}); {order}.next += 1\n"
                f"{pad}else: {order}.put({self.index}, {self.value}, {values})")


@dataclass(frozen=True)
class Fault:
    """The handler of property ``number``'s exception (``_exc``), at a record or, ``finishing``,
    at the end of the trace (:meth:`rasm.properties.monitor.Monitor._fault`)."""

    number: int
    finishing: bool
    pad: str = ""

    def indented(self, pad: str) -> Fault:
        return replace(self, pad=pad + self.pad)

    def render(self, online: bool) -> str:
        pad, number = self.pad, self.number
        if online:
            if self.finishing:
                return f"{pad}FAULT({number}, None, None, None, _exc, out)"
            return f"{pad}FAULT({number}, i, t, tn, _exc, out)"
        return f"{pad}FAULT_RUN({number}, i, {'None' if self.finishing else 'tn'}, _exc)"


@dataclass(frozen=True)
class Reject:
    """Refuse the record (when ``condition`` holds; None: always): its ``signal``'s value is
    not a ``kind`` (signal None: its time or the record itself is wrong). ``step`` counts the
    rejection and returns no verdicts; ``run`` raises."""

    condition: str | None
    signal: str | None
    kind: str
    pad: str = ""

    def indented(self, pad: str) -> Reject:
        return replace(self, pad=pad + self.pad)

    def render(self, online: bool) -> str:
        test = "" if self.condition is None else f"if {self.condition}: "
        reject = "REJECT_STEP" if online else "REJECT_RUN"
        return f"{self.pad}{test}return {reject}(i + 1, t, rec, {self.signal!r}, {self.kind!r})"


def indent(lines: list[Line], pad: str = "    ") -> list[Line]:
    """``lines``, ``pad`` further in."""
    return [line.indented(pad) for line in lines]


def render(lines: list[Line], online: bool) -> list[str]:
    """The source lines of ``lines`` in ``step`` (``online``) or in ``run``."""
    out: list[str] = []
    for line in lines:
        text = line.render(online)
        if text is not None:
            out += text.split("\n")  # (a verdict given in record order is two lines)
    return out
