"""Hypothesis strategies shared by the comm tests."""

from __future__ import annotations

from hypothesis import strategies as st

from rasm.comm.envelope import RESERVED_KEYS

INT64 = st.integers(min_value=-(2**63), max_value=2**63 - 1)
FINITE = st.floats(allow_nan=False, allow_infinity=False)
SCALARS = st.none() | st.booleans() | INT64 | FINITE | st.text()
JSON_VALUES = st.recursive(
    SCALARS,
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=20,
)
PAYLOADS = st.dictionaries(
    st.text(max_size=10).filter(lambda k: k not in RESERVED_KEYS), JSON_VALUES, max_size=6
)

# Topics and patterns over a tiny alphabet: matches, '$' topics and empty levels are common.
LEVELS = st.sampled_from(["a", "b", "", "$s", "ab"])
TOPICS = st.lists(LEVELS, min_size=1, max_size=4).map("/".join).filter(bool)
PATTERN_LEVELS = st.sampled_from(["a", "b", "", "$s", "+"])


@st.composite
def patterns(draw) -> str:
    """A valid subscription pattern, sometimes ending in '#'."""
    levels = draw(st.lists(PATTERN_LEVELS, min_size=1, max_size=4))
    if draw(st.booleans()):
        levels.append("#")
    return "/".join(levels) or "#"
