"""A faulty planner for the TurtleBot's fallback demonstrator (app.fallback.yaml): the spin
planner crashes during a window of the run, as a planner with a bug on some inputs would."""

from __future__ import annotations

from .components import SpinPlan


class CrashingSpinPlan(SpinPlan):
    """``SpinPlan``, except that it raises from ``CRASH_FROM`` to ``CRASH_UNTIL`` seconds."""

    CRASH_FROM = 14.0
    CRASH_UNTIL = 24.0

    def plan(self, ctx):
        if self.CRASH_FROM <= ctx.time < self.CRASH_UNTIL:
            raise RuntimeError("spin planner bug: no plan for this occlusion")
        return super().plan(ctx)
