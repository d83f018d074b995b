"""Hypothesis strategies for the TurtleBot tests: separated occlusion windows on a ray circle."""

from __future__ import annotations

from hypothesis import strategies as st
from tb4.occlusion import Window


@st.composite
def windows(draw, rays=None, max_windows=4, min_gap=1, min_length=1):
    """``(rays, windows)``: up to ``max_windows`` windows with at least ``min_gap`` clear rays
    between any two (around the circle too), sorted by start."""
    total = draw(st.integers(24, 400)) if rays is None else rays
    count = draw(st.integers(0, max_windows))
    windows, position = [], draw(st.integers(0, total - 1))
    budget = total - min_gap
    for _ in range(count):
        gap = draw(st.integers(min_gap, max(min_gap, total // 8)))
        length = draw(st.integers(min_length, max(min_length, total // 5)))
        if gap + length > budget:
            break
        budget -= gap + length
        position += gap
        windows.append(Window(position % total, length))
        position += length
    return total, sorted(windows, key=lambda w: w.start)
