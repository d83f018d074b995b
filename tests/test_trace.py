"""rasm.trace: a trace written, read back and held in memory is the same trace."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from rasm.errors import PlatformError, SourceErrors
from rasm.trace import (
    TraceWriter,
    format_line,
    parse_trace,
    read_trace,
    trace_line,
)
from rasm.trace_mcap import open_trace_writer


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
        return None if isinstance(value, float) and math.isnan(value) else value

    line = {"time": round(time, 9), **{k: jsonable(v) for k, v in record.items()}}
    return json.dumps(line, separators=(", ", ": ")) + "\n"


@pytest.mark.slow
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


# ----------------------------------------------------------------------------- in memory


def same(a, b) -> bool:
    """Equal with the same types all the way down, a nan equal to a nan."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return list(a) == list(b) and all(same(a[k], b[k]) for k in a)
    return a == b


RECORD_KEYS = KEYS.filter(lambda key: key != "time")  # the loop's own key: no record sets it


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(st.floats(0, 1e6), st.dictionaries(RECORD_KEYS, VALUES, max_size=5)),
        max_size=5,
    )
)
def test_a_trace_in_memory_is_the_trace_read_back_from_its_file(tmp_path_factory, records):
    path = tmp_path_factory.mktemp("trace") / "trace.jsonl"
    writer = TraceWriter(path)
    in_memory = []
    writer.observers.append(lambda time, record: in_memory.append(trace_line(time, record)))
    for time, record in records:
        writer.emit(time, record)
    writer.close()
    read_back = [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()]
    assert same(in_memory, read_back)
    parsed = read_trace(path)
    assert same([{"time": t, **values} for t, values in parsed], read_back)


def test_a_record_in_memory_shares_no_container_with_the_record():
    record = {"plan": {"mode": "boost", "steps": [1, 2.5]}, "broken_rules": ("a", "b")}
    line = trace_line(1.0, record)
    assert line == {
        "time": 1.0,
        "plan": {"mode": "boost", "steps": [1, 2.5]},
        "broken_rules": ["a", "b"],
    }
    record["plan"]["steps"].append(3)
    assert line["plan"]["steps"] == [1, 2.5]


def test_a_line_has_time_first_to_the_nanosecond_and_a_top_level_nan_as_null():
    line = format_line(0.30000000000000004, {"t": math.nan, "scan": [math.inf], "ok": True})
    assert line == '{"time": 0.3, "t": null, "scan": [Infinity], "ok": true}'


# ----------------------------------------------------------------------------- reading


def test_a_value_is_read_against_its_signals_type_at_its_line_and_column():
    lines = [
        '{"time": 0, "v": 1}',  # an int for a float is a number
        '{"time": 1, "v": true}',
        "",
        '{"time": 2, "n": 1.5, "v": NaN}',  # a trace may hold NaN
        '{"time": -0.5, "v": 2.0}',  # refused records do not count: back from 0
    ]
    with pytest.raises(SourceErrors) as caught:
        parse_trace(lines, {"v": "float", "n": "int"}, source="t.jsonl")
    assert [str(e) for e in caught.value.errors] == [
        "t.jsonl:2:13: 'v' must be a number, not true",
        "t.jsonl:4:13: 'n' must be an integer, not 1.5",
        "t.jsonl:5:2: time -0.5 goes back in time (the previous record has 0)",
    ]


def test_a_huge_int_for_a_float_signal_is_kept_exact():
    [(time, values)] = parse_trace([f'{{"time": 0, "v": {10**400}}}'], {"v": "float"})
    assert values == {"v": 10**400} and time == 0


def test_a_run_in_memory_is_its_trace_file(tmp_path):
    from rasm.testing import run_app

    hotbox = Path(__file__).resolve().parents[1] / "examples" / "hotbox"
    trace = run_app(hotbox, seed=1, duration=30, trace=tmp_path / "run.jsonl")
    read_back = [json.loads(line) for line in (tmp_path / "run.jsonl").read_text().splitlines()]
    assert len(trace) > 100 and same(list(trace), read_back)
    assert trace.lines() == (tmp_path / "run.jsonl").read_text().splitlines()


def test_a_run_trace_is_mcap_by_its_suffix_and_only_jsonl_rotates(tmp_path):
    mcap = open_trace_writer(tmp_path / "run.mcap")
    mcap.emit(0.5, {"speed": 1.0})
    mcap.close()
    assert (tmp_path / "run.mcap").read_bytes().startswith(b"\x89MCAP")
    jsonl = open_trace_writer(tmp_path / "run.jsonl", max_bytes=10_000)
    jsonl.emit(0.5, {"speed": 1.0})
    jsonl.close()
    assert read_trace(tmp_path / "run.jsonl") == [(0.5, {"speed": 1.0})]
    with pytest.raises(PlatformError, match="an MCAP trace is not rotated: write JSONL"):
        open_trace_writer(tmp_path / "big.mcap", max_bytes=10_000)


def test_an_mcap_trace_reads_back_in_the_mcap_library_and_in_rasm(tmp_path):
    import struct
    import zlib

    make_reader = pytest.importorskip("mcap.reader").make_reader
    from rasm.trace import format_line
    from rasm.trace_mcap import McapTrace

    path = tmp_path / "run.mcap"
    writer = open_trace_writer(path)
    records = [(k / 10, {"speed": k * 0.1, "mode": "go"}) for k in range(500)]
    for time, record in records:
        writer.emit(time, record)
    writer.close()
    lines = [format_line(time, record) for time, record in records]
    with path.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary.statistics.message_count == 500
        assert [c.topic for c in summary.channels.values()] == ["/rasm/trace"]
        # each record is a std_msgs/msg/String: the CDR header, the length, the JSON, a NUL
        read = [(m.log_time, m.data[8:-1].decode()) for _, _, m in reader.iter_messages()]
        assert all(m.data[:4] == b"\x00\x01\x00\x00" for _, _, m in reader.iter_messages())
    assert read == [(round(time * 1e9), line) for (time, _), line in zip(records, lines,
                                                                          strict=True)]
    # the summary's CRC covers the summary, its offsets and the footer up to the CRC itself
    data = path.read_bytes()
    summary_start, _, crc = struct.unpack_from("<QQI", data, len(data) - 37 + 9)
    assert crc == zlib.crc32(data[summary_start:len(data) - 12])
    trace = McapTrace(path)
    assert list(trace) == lines and trace.damage == []


def test_a_time_going_back_is_named_to_the_nanosecond():
    # the float nearest 1700000000.123456789 would print 1700000000.1234567: the text is kept
    lines = ['{"time": 1700000000.123456789}', '{"time": 1700000000.123456788}']
    with pytest.raises(SourceErrors) as caught:
        parse_trace(lines, {}, source="t.jsonl")
    assert [str(e) for e in caught.value.errors] == [
        "t.jsonl:2:2: time 1700000000.123456788 goes back in time (the previous record has "
        "1700000000.123456789)",
    ]


# Lines for the fast reader: records, and lines that only decode as records when read together
# with their neighbours (one cut short, one of two values, the reader's own separator).
READER_LINES = st.sampled_from([
    '{"time": 0.5, "a": true}\n', '{"time": 1, "b": [1, 2]}\n', '{"time": 2.25}', '\n', '  \n',
    '{"time": 1, "a": [1\n', '2]}\n', '{"time": 1, "a": {"x": 1\n', '"y": 2}}\n',
    '{"time": 2}, {"time": 3}\n', '{"time": 2}, "\\u0000", {"time": 3}\n', '"\\u0000"\n',
    '{"time": 3, "s": "\\u0000"}\n', '{"time": NaN}\n', '{"time": 1700000000.123456789}\n',
    '{"time": null}\n', '{"a": 1}\n', '[{"time": 1}]\n', '{"time": "1"}\n', '{"time": 1}]\n',
    '{"time": true}\n', '{"time": 5e6}\n', '{"time": 4, "time": 5}\n', '{"time": 1} x\n',
])


@settings(max_examples=300, deadline=None)
@given(st.lists(READER_LINES, max_size=12), st.integers(1, 5))
# a line cut short takes the separator after it into its value, the last line gives the values
# missing: as many values as lines, or a separator at every other place
@example(['{"time": 1, "a": [1\n', '2]}\n', '{"time": 2}, "\\u0000", {"time": 3}\n'], 3)
@example(['{"time": 1, "a": [1\n', '2]}\n', '{"time": 2}, {"time": 3}, {"time": 4}\n'], 3)
def test_the_fast_reader_reads_blocks_as_it_reads_lines(lines, block):
    from rasm import trace

    def read(scan):
        try:
            return [json.dumps([t, r]) for t, r in scan()], None
        except trace.MalformedTrace as exc:
            return None, str(exc)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(trace, "SCANNED", block)
        by_blocks = read(lambda: trace.scan_records(lines, source="t"))
    by_lines = read(lambda: trace._scan_lines(lines, {}, "t", 0))
    assert by_blocks == by_lines
