"""A property's overall verdict over a run or a trace: the five states every report shows.

* **satisfied** — judged, never false;
* **violated** — false at some judged record;
* **inconclusive** — never false, only a bounded-future tail at the end of a trace undecided;
* **not judged** — it never started: some signal it reads never had a value (named in
  ``missing``);
* **error** — evaluating it raised at some record: the checker could not vouch for it there.

A satisfied property may be satisfied *vacuously*: the left side of one of its ``->`` never held
on a judged record (``vacuous``), so that part was never put to the test. It still passes, and
every report says so: "satisfied (vacuously: anomaly never happened)".

Only satisfied and inconclusive pass: ``rasm run``, ``rasm check``, ``rasm.testing`` and the
report all read the state from :class:`PropertyOutcome`, so they agree.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

__all__ = [
    "ERROR",
    "INCONCLUSIVE",
    "NOT_JUDGED",
    "PASSING",
    "SATISFIED",
    "STATES",
    "VIOLATED",
    "PropertyOutcome",
    "Untested",
]

SATISFIED = "satisfied"
VIOLATED = "violated"
INCONCLUSIVE = "inconclusive"
NOT_JUDGED = "not judged"
ERROR = "error"
STATES = (SATISFIED, VIOLATED, INCONCLUSIVE, NOT_JUDGED, ERROR)
PASSING = frozenset((SATISFIED, INCONCLUSIVE))


class Untested(NamedTuple):
    """The left side of an ``->`` that never held on a judged record: its text (a let's name
    where it is one), and whether it is an event (which *happens* rather than *holds*)."""

    text: str
    event: bool = False

    def phrase(self) -> str:
        """``anomaly never happened``, ``speed > 1 never held``."""
        return f"{self.text} never {'happened' if self.event else 'held'}"


@dataclass
class PropertyOutcome:
    """One property's verdicts so far, counted; :attr:`state` is its overall verdict."""

    name: str
    judged: int = 0
    violations: int = 0
    errors: int = 0
    inconclusive: int = 0
    first_error: str | None = None
    missing: tuple[str, ...] = field(default_factory=tuple)  # never had a value (not judged)
    vacuous: tuple[Untested, ...] = ()  # antecedents that never held on a judged record

    def add(self, value: bool | None, error: str | None = None) -> None:
        """Count one verdict (a :class:`~rasm.properties.monitor.Verdict`'s value and error)."""
        self.judged += 1
        if error is not None:
            self.errors += 1
            if self.first_error is None:
                self.first_error = error
        elif value is False:
            self.violations += 1
        elif value is None:
            self.inconclusive += 1

    @property
    def state(self) -> str:
        # a definite violation is the finding to report first; errors are counted beside it
        if self.violations:
            return VIOLATED
        if self.errors:
            return ERROR
        if not self.judged:
            return NOT_JUDGED
        if self.inconclusive:
            return INCONCLUSIVE
        return SATISFIED

    @property
    def passed(self) -> bool:
        return self.state in PASSING

    @property
    def word(self) -> str:
        """The state, and for a vacuously satisfied property what never happened:
        ``satisfied (vacuously: anomaly never happened)``."""
        state = self.state
        if state == SATISFIED and self.vacuous:
            return f"{state} (vacuously: {', '.join(u.phrase() for u in self.vacuous)})"
        return state

    def describe(self) -> str:
        """The state in words, with what a reader needs next (counts, the first error)."""
        state = self.state
        if state == VIOLATED:
            text = f"violated at {self.violations} of {self.judged} records"
            if self.errors:
                text += f" (and in error at {self.errors})"
            return text
        if state == ERROR:
            return f"error at {self.errors} of {self.judged} records: {self.first_error}"
        if state == NOT_JUDGED:
            if self.missing:
                return "not judged: no value for " + ", ".join(self.missing)
            return "not judged: no record reached it"
        if state == INCONCLUSIVE:
            return f"inconclusive at {self.inconclusive} of {self.judged} records (trace ended)"
        return f"{self.word} at {self.judged} records"
