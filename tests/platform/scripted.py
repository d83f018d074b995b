"""A monitor whose verdicts a test scripts, for the Trustworthiness Checker and Manager tests."""

from __future__ import annotations

from rasm.properties.monitor import Verdict


class Scripted:
    """A monitor of another kind: each step does what the script says next for its one property:
    a verdict value, a list of them (a record deciding several, as a bounded-future property's
    may), ``"nothing"`` or ``"raise"``."""

    properties = ["guard"]

    def __init__(self, script: list) -> None:
        self.script = list(script)
        self.index = 0

    def step(self, time, record):
        what = self.script[self.index]
        self.index += 1
        if what == "raise":
            raise OverflowError("integer division result too large for a float")
        if what == "nothing":  # nothing decided at this record (a bounded-future warm-up)
            return []
        values = what if isinstance(what, list) else [what]
        return [Verdict("guard", self.index - 1, time, value) for value in values]

    def finish(self):
        return []

    def missing(self, name):
        return ()

