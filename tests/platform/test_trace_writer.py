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


def written_files(path):
    """The rotated files oldest first, then the current one."""
    older = path.parent.glob(f"{path.stem}.*{path.suffix}")
    return [*sorted(older, key=lambda p: -int(p.suffixes[0][1:])), path]


@settings(max_examples=200, deadline=None)
@given(
    records=st.lists(st.dictionaries(st.sampled_from("abc"), st.text(max_size=30)), max_size=40),
    max_bytes=st.integers(1, 300),
    keep=st.integers(0, 4),
)
def test_a_rotated_trace_keeps_the_newest_whole_lines_within_its_cap(
    tmp_path_factory, records, max_bytes, keep
):
    path = tmp_path_factory.mktemp("trace") / "trace.jsonl"
    writer = TraceWriter(path, max_bytes=max_bytes, keep=keep)
    for i, record in enumerate(records):
        writer.emit(float(i), record)
    writer.close()
    expected = [expected_line(float(i), record) for i, record in enumerate(records)]
    files = written_files(path)
    assert len(files) <= keep + 1
    kept = []
    for file in files:
        lines = file.read_text(encoding="utf-8").splitlines(keepends=True)
        # a file passes its cap only by holding one line longer than the cap
        assert len(file.read_bytes()) <= max_bytes or len(lines) == 1
        kept += lines
    # what is kept is the newest records, in order, each line whole: only the oldest are dropped
    assert kept == expected[len(expected) - len(kept) :]
    if keep and expected:  # with older files kept, a full cap's worth of records is never lost
        assert len("".join(kept)) >= min(max_bytes, len("".join(expected)))


def test_a_trace_left_by_an_earlier_run_is_rotated_away_not_overwritten(tmp_path):
    path = tmp_path / "trace.jsonl"
    first = TraceWriter(path, max_bytes=10_000)
    first.emit(1.0, {"run": 1})
    first.close()
    second = TraceWriter(path, max_bytes=10_000)
    second.emit(1.0, {"run": 2})
    second.close()
    assert json.loads(path.read_text())["run"] == 2
    assert json.loads((tmp_path / "trace.1.jsonl").read_text())["run"] == 1


def test_without_a_size_a_trace_file_is_written_afresh(tmp_path):
    path = tmp_path / "trace.jsonl"
    for run in (1, 2):
        writer = TraceWriter(path)
        writer.emit(1.0, {"run": run})
        writer.close()
    assert json.loads(path.read_text())["run"] == 2
    assert not (tmp_path / "trace.1.jsonl").exists()


def test_each_record_reaches_the_file_as_it_is_emitted(tmp_path):
    path = tmp_path / "trace.jsonl"
    writer = TraceWriter(path)
    for i in range(3):
        writer.emit(float(i), {"n": i})
        # read through another file object: what the operating system has, not our buffer
        assert [json.loads(line)["n"] for line in path.read_text().splitlines()] == list(
            range(i + 1)
        )
    writer.close()
