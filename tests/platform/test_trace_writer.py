"""The trace file's lines: what json.dumps made of each record before the line writer got fast."""

from __future__ import annotations

import json
import math

from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.platform.trace import TraceWriter


class Reading(float):
    pass


SCALARS = (
    st.none()
    | st.booleans()
    | st.integers()
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.floats(allow_nan=True, allow_infinity=True).map(Reading)
    | st.text(max_size=4)
    | st.sampled_from([math.nan, math.inf, -math.inf, Reading(math.nan), Reading(-math.inf)])
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=3), inner),
    max_leaves=8,
)
KEYS = st.sampled_from(["time", "stage", "temperature", "plan", "é"]) | st.text(max_size=4)


def expected_line(time, record) -> str:
    def jsonable(value):
        return None if isinstance(value, float) and not math.isfinite(value) else value

    line = {"time": round(time, 9), **{k: jsonable(v) for k, v in record.items()}}
    return json.dumps(line, separators=(", ", ": ")) + "\n"


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(st.floats(0, 1e6), st.dictionaries(KEYS, VALUES, max_size=5)), max_size=5)
)
def test_trace_lines_are_the_records_as_json(tmp_path_factory, records):
    path = tmp_path_factory.mktemp("trace") / "trace.jsonl"
    writer = TraceWriter(path)
    last = -math.inf
    expected = []
    for time, record in records:
        writer.emit(time, record)
        last = max(time, last)
        expected.append(expected_line(last, record))
    writer.close()
    assert path.read_text(encoding="utf-8") == "".join(expected)
