"""Vacuity: the antecedents of a file's properties that never held (``vacuous``, SPEC §6).

``always (anomaly -> eventually[0, 5s] executed)`` over a recording without a single anomaly is
satisfied without ever having been put to the test. For every ``->`` of every property its left
side, the antecedent, is watched on the property's judged records: a probe property of its own,
warmed up like its parent (as explanations do), so its values are the ones it had inside the
parent. The antecedents that never held there are the property's *vacuous* ones. A value that
stayed inconclusive or could not be evaluated did not hold.

Once every antecedent of a file has held, nothing more can change: the watch stops stepping.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from rasm.properties.ast import Binary, Expr, Name, Specification, walk
from rasm.properties.ast import Property as PropertyNode
from rasm.properties.loader import signals_of
from rasm.properties.monitor import Monitor
from rasm.properties.outcome import Untested
from rasm.properties.printer import unparse

__all__ = ["Vacuity", "antecedents"]


def antecedents(formula: Expr) -> list[Expr]:
    """The left side of every ``->`` in ``formula``, outermost first, each once."""
    found: list[Expr] = []
    for node in walk(formula):
        if isinstance(node, Binary) and node.op == "->" and node.left not in found:
            found.append(node.left)
    return found


class Vacuity:
    """Which antecedents of ``spec``'s properties have held on a judged record.

    Fed like a :class:`~rasm.properties.monitor.Monitor`: online with :meth:`step` then
    :meth:`finish`, offline with :meth:`feed` then :meth:`settle`. :meth:`vacuous` names, per
    property, the antecedents that have not held (so far).
    """

    def __init__(self, spec: Specification) -> None:
        self.spec = spec
        events = {e.name for e in spec.events}
        lets = {let.expr: let.name for let in spec.lets}
        probes: list[PropertyNode] = []
        reads: list[tuple[str, ...]] = []
        # probe number -> (property, the antecedent in words)
        self._owners: list[tuple[str, Untested]] = []
        self._by_property: dict[str, list[int]] = {p.name: [] for p in spec.properties}
        for prop in spec.properties:
            parent_reads = tuple(signals_of(prop.formula))
            for node in antecedents(prop.formula):
                label = lets.get(node) or unparse(node)
                event = isinstance(node, Name) and node.name in events
                k = len(probes)
                probes.append(PropertyNode(f"#{k}", node))
                reads.append(parent_reads)  # starts where its parent starts
                self._owners.append((prop.name, Untested(label, event)))
                self._by_property[prop.name].append(k)
        self.held = [False] * len(probes)
        # the records whose values count, by index: [first, end) (end None: to the last one);
        # a part of a trace checked in parts counts only the records it answers for
        self.counted: tuple[int, int | None] = (0, None)
        self._left = len(probes)  # antecedents that have not held yet
        self._monitor: Monitor | None = None
        if probes:
            probe_spec = Specification(
                source=spec.source,
                inputs=spec.inputs,
                events=spec.events,
                lets=(),
                properties=tuple(probes),
                signals=spec.signals,
            )
            self._monitor = Monitor(probe_spec, reads=reads)

    @property
    def settled(self) -> bool:
        """Every antecedent has held: nothing is vacuous, whatever comes next."""
        return self._left == 0

    def antecedents(self, name: str) -> list[tuple[Untested, bool]]:
        """Every antecedent of property ``name``, and whether it has held (so far)."""
        return [(self._owners[k][1], self.held[k]) for k in self._by_property.get(name, ())]

    def vacuous(self, name: str) -> tuple[Untested, ...]:
        """The antecedents of property ``name`` that have not held on a judged record."""
        return tuple(self._owners[k][1] for k in self._by_property.get(name, ()) if not
                     self.held[k])

    def _note(self, k: int) -> None:
        if not self.held[k]:
            self.held[k] = True
            self._left -= 1

    # ----------------------------------------------------------------- online
    def step(self, time: float, values: Mapping[str, object]) -> None:
        """One record of a live trace."""
        if self._monitor is None or self.settled:
            return
        for verdict in self._monitor.step(time, values):
            if verdict.value is True and verdict.error is None:
                self._note(int(verdict.property[1:]))

    def finish(self) -> None:
        """The end of a live trace (its antecedents' last verdicts)."""
        if self._monitor is None or self.settled:
            return
        for verdict in self._monitor.finish():
            if verdict.value is True and verdict.error is None:
                self._note(int(verdict.property[1:]))

    # ----------------------------------------------------------------- offline
    def feed(self, records: Iterable[tuple[float, Mapping[str, object]]]) -> None:
        """The next records of a trace checked offline."""
        if self._monitor is None or self.settled:
            return
        self._monitor.feed(records)
        self._take()

    def settle(self) -> None:
        """The end of a trace checked offline."""
        if self._monitor is None or self.settled:
            return
        self._monitor.settle()
        self._take()

    def _take(self) -> None:
        assert self._monitor is not None
        low, high = self.counted
        for k in range(len(self.held)):
            first, values, _ = self._monitor.take(k)
            if low > first or high is not None:
                values = values[max(low - first, 0):None if high is None else max(high - first, 0)]
            if not self.held[k] and True in values:  # (a value in error is False)
                self._note(k)
