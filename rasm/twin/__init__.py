"""rasm.twin: digital twins that learn online.

A :class:`DigitalTwin` learns a model of the managed system from the records the probes
deliver (:meth:`~DigitalTwin.observe`), predicts what a plan would do
(:meth:`~DigitalTwin.simulate`, used by the Legitimate stage to check the application's
properties before a plan is accepted) and keeps its learned model as a versioned JSON document
(:meth:`~DigitalTwin.model`, :meth:`~DigitalTwin.load`) that the Storage Manager persists.

The learning pieces: :class:`RecursiveLeastSquares` (with a forgetting factor) estimates the
parameters, :class:`PageHinkley` watches the residuals for drift. See ``docs/twin.md``.
"""

from rasm.twin.base import DigitalTwin, TwinError, TwinUpdate
from rasm.twin.check import PredictionChecker, predicted_violations, worse_than_baseline
from rasm.twin.drift import PageHinkley
from rasm.twin.rls import RecursiveLeastSquares

__all__ = [
    "DigitalTwin",
    "PageHinkley",
    "PredictionChecker",
    "RecursiveLeastSquares",
    "TwinError",
    "TwinUpdate",
    "predicted_violations",
    "worse_than_baseline",
]
