"""Drift detection on a twin's residuals: the Page-Hinkley test.

A twin's prediction errors are noise around a small mean while its model fits the system. When
the system changes (the Hotbox gets a lighter content), the errors grow and stay large while
the system moves. Page-Hinkley (Page 1954; Hinkley 1971) detects such an increase of the mean:

    m_n = sum_{i<=n} (x_i - mean_i - delta)       mean_i: the mean of x_1..x_i
    M_n = min_{i<=n} m_i
    drift at n  <=>  n >= min_samples and m_n - M_n > threshold

``delta`` is the increase of the mean that is tolerated (smaller changes are never flagged);
``threshold`` is the evidence needed, in the signal's unit times samples: a jump of the mean by
``d > delta`` is detected after about ``threshold / (d - delta)`` samples. Without a change
``m_n`` drifts down by ``delta`` per sample, so a false alarm needs a run of large values that
the noise makes ever less likely as ``threshold`` grows.
"""

from __future__ import annotations

from rasm.twin.base import TwinError

__all__ = ["PageHinkley"]


class PageHinkley:
    """One-sided Page-Hinkley test for an increase of the mean of a stream.

    ``update(x)`` returns True on the sample where drift is detected and then starts afresh
    (as :meth:`reset`), so each change is reported once. ``detections`` counts them.
    """

    def __init__(self, *, delta: float, threshold: float, min_samples: int = 30) -> None:
        if delta < 0 or threshold <= 0 or min_samples < 1:
            raise TwinError(
                "Page-Hinkley needs delta >= 0, threshold > 0 and min_samples >= 1, not "
                f"delta={delta!r}, threshold={threshold!r}, min_samples={min_samples!r}"
            )
        self.delta = float(delta)
        self.threshold = float(threshold)
        self.min_samples = int(min_samples)
        self.detections = 0
        self.reset()

    def reset(self) -> None:
        """Forget the stream so far (the mean, the cumulative sum and its minimum)."""
        self.samples = 0
        self.mean = 0.0
        self.cumulative = 0.0
        self.minimum = 0.0

    @property
    def statistic(self) -> float:
        """``m_n - M_n``: the evidence of an increase gathered so far."""
        return self.cumulative - self.minimum

    def update(self, x: float) -> bool:
        """Add one sample; True if it completes the evidence of a drift."""
        self.samples += 1
        self.mean += (x - self.mean) / self.samples
        self.cumulative += x - self.mean - self.delta
        self.minimum = min(self.minimum, self.cumulative)
        if self.samples >= self.min_samples and self.statistic > self.threshold:
            self.detections += 1
            self.reset()
            return True
        return False
