"""``rasm check`` streams its trace: the same report as the check of the trace in memory, with
memory bounded by the properties' windows, not by the trace."""

from __future__ import annotations

import gc
import io
import json
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from rasm.errors import SourceErrors
from rasm.properties.check import (
    check_file,
    check_records,
    format_json,
    format_text,
    format_verdicts,
)
from rasm.properties.loader import load_specification
from rasm.properties.monitor import Monitor
from rasm.trace import read_trace

from .strategies import HEADER, formulas, traces

ROOT = Path(__file__).resolve().parents[2]
SETTINGS = settings(max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def spec_of(formulas_: list[str]):
    text = HEADER + "".join(f"property p{k}: {f}\n" for k, f in enumerate(formulas_))
    return load_specification(text, source="props.rv")


def write_trace(folder: Path, records, extra: list[tuple[int, str]] = ()) -> str:
    lines = [json.dumps({"time": t, **rec}) for t, rec in records]
    for position, line in extra:
        lines.insert(min(position, len(lines)), line)
    path = folder / "t.jsonl"
    path.write_text("".join(line + "\n" for line in lines), encoding="utf-8")
    return str(path)


def faulty(spec, faults: set[tuple[str, int]]) -> Monitor:
    def hook(name: str, index: int) -> None:
        if (name, index) in faults:
            raise RuntimeError(f"injected into {name} at {index}")

    return Monitor(spec, fault_hook=hook)


# --------------------------------------------------------------------------- part by part


@SETTINGS
@given(
    st.lists(formulas(), min_size=1, max_size=3),
    traces(),
    st.sets(st.tuples(st.sampled_from(["p0", "p1", "p2"]), st.integers(0, 25)), max_size=3),
    st.integers(1, 7),
)
def test_a_monitor_fed_part_by_part_gives_what_a_whole_run_gives(formulas_, records, faults,
                                                                    part):
    # faults included: a verdict tainted by a reset is known as such when it is taken
    spec = spec_of(formulas_)
    whole = faulty(spec, faults).run(records)
    monitor = faulty(spec, faults)
    taken: list[tuple[list, dict]] = [([], {}) for _ in spec.properties]

    def take() -> None:
        for k in range(len(spec.properties)):
            first, values, errors = monitor.take(k)
            if values:  # each part starts where the one before ended
                assert first == monitor.starts[k] + len(taken[k][0])
            assert all(first <= j < first + len(values) for j in errors)
            taken[k][0].extend(values)
            taken[k][1].update(errors)

    for start in range(0, len(records), part):
        monitor.feed(records[start:start + part])
        take()
    monitor.settle()
    take()
    for k, run in enumerate(whole):
        values, errors = taken[k]
        assert (monitor.starts[k], values, errors) == (run.start, run.values, run.errors)


@pytest.mark.slow
@SETTINGS
@given(st.lists(formulas(), min_size=1, max_size=3), traces(), st.integers(1, 6))
def test_the_streamed_check_of_a_file_reports_what_the_check_in_memory_reports(
    formulas_, records, part
):
    spec = spec_of(formulas_)
    with tempfile.TemporaryDirectory() as tmp:
        path = write_trace(Path(tmp), records)
        in_memory = check_records(spec, read_trace(path, spec.signals), trace=path)
        text = check_file(spec, path, named=True, chunk=part)
        assert format_text(text) == format_text(in_memory)
        full = check_file(spec, path, explain_violations=False, chunk=part)
        assert format_json(full) == format_json(in_memory)
        out = io.StringIO()
        check_file(spec, path, explain_violations=False, named=True, verdicts=out, chunk=part)
        assert out.getvalue() == format_verdicts(in_memory)


BAD_LINES = [
    "{oops",
    "[1, 2]",
    '{"p": true}',  # no time
    '{"time": "soon"}',
    '{"time": NaN}',
    '{"time": -5}',  # back in time
    '{"time": 1e9, "x": "fast"}',  # a float signal a property may read
    '{"time": 1e9, "y": 1.5}',  # an int
    '{"time": 1e9, "p": 1}',  # an event
    '{"time": 1e9, "r": null}',
]


@SETTINGS
@given(
    st.lists(formulas(), min_size=1, max_size=2),
    traces(),
    # after the first record: a line going back in time is malformed only after another one
    st.lists(st.tuples(st.integers(1, 25), st.sampled_from(BAD_LINES)), min_size=1, max_size=3),
)
def test_a_malformed_trace_is_reported_as_the_full_reader_reports_it(formulas_, records, bad):
    # the fast reader leaves most checks to the monitor: whichever finds a bad record, every
    # malformed line is named, as reading the whole trace names them
    assume(records)
    spec = spec_of(formulas_)
    with tempfile.TemporaryDirectory() as tmp:
        path = write_trace(Path(tmp), records, bad)
        with pytest.raises(SourceErrors) as expected:
            read_trace(path, spec.signals)
        with pytest.raises(SourceErrors) as streamed:
            check_file(spec, path, chunk=4)
        assert [str(e) for e in streamed.value.errors] == [
            str(e) for e in expected.value.errors
        ]


def test_a_signal_declared_but_never_read_is_still_checked(tmp_path):
    spec = load_specification("input x: float\ninput unused: int\nproperty p: x < 1\n")
    path = write_trace(tmp_path, [(0, {"x": 0.5}), (1, {"x": 0.5, "unused": "many"})])
    with pytest.raises(SourceErrors, match=r"t.jsonl:2:\d+: 'unused' must be an integer"):
        check_file(spec, path)


# --------------------------------------------------------------------------- memory


PEAK = textwrap.dedent(
    """
    import resource, sys
    from rasm.cli import main
    code = main(["check", sys.argv[1], sys.argv[2]])
    print(code, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024)
    """
)


def peak_megabytes(props: Path, trace: Path) -> int:
    out = subprocess.run(
        [sys.executable, "-c", PEAK, str(props), str(trace)],
        capture_output=True, text=True, check=True, cwd=ROOT,
    ).stdout.split()
    assert out[-2] == "1"  # the violation below is found and explained
    return int(out[-1])


@pytest.mark.slow
@pytest.mark.parametrize(
    ("where", "formula"),
    [
        ("early", "always (b -> once[0, 1s] a)"),
        # explained from the trace read again up to the end: only the records its windows
        # reach are kept, not the whole prefix
        ("late", "always (b -> once[0, 1s] a)"),
        # an unbounded past window: a bounded number of records is kept all the same
        ("late", "always (b -> historically a)"),
    ],
)
def test_peak_memory_does_not_grow_with_the_trace(tmp_path, where, formula):
    props = tmp_path / "p.rv"
    props.write_text(f"input a: bool\ninput b: bool\nproperty p: {formula}\n")
    peaks = []
    for records in (20_000, 400_000):
        trace = tmp_path / f"t{records}.jsonl"
        bad = range(300, 420) if where == "early" else range(records - 150, records - 30)
        with trace.open("w") as out:
            for k in range(records):
                # violations: a b with no a in the second before it; a b after an a failed
                a = (k % 7 == 0 or "historically" in formula) and k not in bad
                b = k % 11 == 0
                out.write(f'{{"time": {k / 100}, "a": {json.dumps(a)}, "b": {json.dumps(b)}}}\n')
        peaks.append(peak_megabytes(props, trace))
    # twenty times the records (about 15 MB more of trace): the same memory, give or take
    # the allocator; a checker that holds the trace needs some 100 MB more
    assert peaks[1] - peaks[0] < 12, peaks


def test_the_check_leaves_the_garbage_collector_as_it_found_it(tmp_path):
    # the objects from before the check are set aside from the collector's passes only while
    # the records stream, and a caller's own choice stands
    spec = load_specification("input x: float\nproperty p: x < 1\n")
    path = write_trace(tmp_path, [(k, {"x": k / 10}) for k in range(20)])
    assert gc.get_freeze_count() == 0
    assert check_file(spec, path).failed
    assert gc.get_freeze_count() == 0
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        assert check_file(spec, path).failed
        assert gc.get_freeze_count() == frozen
    finally:
        gc.unfreeze()
