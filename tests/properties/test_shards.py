"""A trace checked in parts (:mod:`rasm.properties.shards`): for random properties, traces and
cuts, the verdicts, counts, violations, vacuity and explanations of one pass."""

from __future__ import annotations

import json
import os
import tempfile
from unittest import mock

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm.properties.check import check_records, format_json, format_text
from rasm.properties.loader import load_specification
from rasm.properties.shards import (
    ListPart,
    check_part,
    explain_part,
    merge_parts,
    splittable,
    subspec,
    wanted_explanations,
)

from .strategies import HEADER, UNITS, decimal_traces, formulas, traces

SETTINGS = settings(max_examples=300, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def spec_of(texts: list[str]):
    text = HEADER + "".join(f"property p{k}: {f}\n" for k, f in enumerate(texts))
    return load_specification(text, source="props.rv")


def in_parts(spec, records, cuts: list[int], *, named: bool = False):
    """The report of ``records`` checked in the parts ``cuts`` make, explained as a text report
    explains it."""
    bounds = [0, *sorted(set(cuts)), len(records)]
    parts = [ListPart(records, a, b) for a, b in zip(bounds, bounds[1:], strict=False) if a < b]
    results = [check_part(spec, part, named=named) for part in parts]
    report = merge_parts(spec, results, trace="<trace>", named=named)
    wanted = wanted_explanations(report)
    offset, found = 0, {}
    for part, result in zip(parts, results, strict=True):
        mine = {name: [i for i in indices if offset <= i < offset + result.records]
                for name, indices in wanted.items()}
        if any(mine.values()):
            found.update(explain_part(spec, part, mine, offset))
        offset += result.records
    for prop in report.properties:
        prop.explanations = [found[(prop.name, i)] for i in wanted.get(prop.name, [])]
    return report


def bounded(texts: list[str]) -> bool:
    return all(splittable(p.formula) for p in spec_of(texts).properties)


@SETTINGS
@given(st.lists(formulas(), min_size=1, max_size=3), traces(40), st.data())
def test_random_properties_traces_and_cuts_give_the_verdicts_of_one_pass(texts, records, data):
    spec = spec_of(texts)
    spec = subspec(spec, [p.name for p in spec.properties if splittable(p.formula)])
    cuts = data.draw(st.lists(st.integers(0, len(records)), max_size=4))
    one = check_records(spec, records)
    parts = in_parts(spec, records, cuts)
    assert format_json(parts) == format_json(one)
    assert format_text(parts) == format_text(one)


# --------------------------------------------------------------------------- JSONL by bytes


def _line(t, record, escaped: bool) -> str:
    line = json.dumps({"time": t, **record})
    if escaped and '"x"' in line:  # the same key, written with an escape
        line = line.replace('"x"', '"\\u0078"')
    return line


@st.composite
def jsonl_texts(draw, records):
    """The trace's lines, with blank lines, CRLF and lone CR line breaks, and escaped keys."""
    out = []
    for t, record in records:
        if draw(st.integers(0, 9)) == 0:
            out.append(draw(st.sampled_from(["\n", "  \n", "\r\n"])))
        out.append(_line(t, record, draw(st.integers(0, 5)) == 0))
        out.append(draw(st.sampled_from(["\n", "\n", "\n", "\r\n", "\r"])))
    return "".join(out)


def parts_of_file(spec, path: str, cuts: list[int]):
    from rasm.properties.codegen import checked_signals
    from rasm.trace_parts import JsonlPart

    checked = set(checked_signals(spec))
    unchecked = {n: k for n, k in spec.signals.items() if n not in checked}
    bounds = sorted({0, *cuts, os.path.getsize(path)})
    return [JsonlPart(path, a, b, unchecked=unchecked) for a, b in zip(bounds, bounds[1:],
                                                                          strict=False)]


@SETTINGS
@given(st.lists(formulas(), min_size=1, max_size=3), traces(40), st.data())
def test_a_jsonl_file_cut_anywhere_gives_the_verdicts_of_one_pass(texts, records, data):
    import rasm.trace_parts
    from rasm.properties.check import check_file
    from rasm.trace_parts import cut_points

    spec = spec_of(texts)
    spec = subspec(spec, [p.name for p in spec.properties if splittable(p.formula)])
    text = data.draw(jsonl_texts(records))
    # small blocks: the search for held values reads the raw bytes, not the decoded lines
    block = data.draw(st.sampled_from([4, 32, 1 << 16]))
    with tempfile.TemporaryDirectory() as folder, \
            mock.patch.object(rasm.trace_parts, "BLOCK", block):
        path = os.path.join(folder, "t.jsonl")
        with open(path, "w", encoding="utf-8", newline="") as handle:
            handle.write(text)
        size = os.path.getsize(path)
        n = data.draw(st.integers(1, 6))
        cuts = cut_points(path, n)
        assert cuts[0] == 0 and cuts[-1] == size and cuts == sorted(set(cuts))
        one = check_file(spec, path)
        parts = parts_of_file(spec, path, cuts)
        results = [check_part(spec, part) for part in parts]
        merged = merge_parts(spec, results, trace=path)
        wanted = wanted_explanations(merged)
        offset, found = 0, {}
        for part, result in zip(parts, results, strict=True):
            mine = {name: [i for i in indices if offset <= i < offset + result.records]
                    for name, indices in wanted.items()}
            if any(mine.values()):
                found.update(explain_part(spec, part, mine, offset))
            offset += result.records
            part.close()
        for prop in merged.properties:
            prop.explanations = [found[(prop.name, i)] for i in wanted.get(prop.name, [])]
        assert format_json(merged) == format_json(one)
        assert format_text(merged) == format_text(one)


# --------------------------------------------------------------------------- how far back


@pytest.mark.parametrize(("formula", "back"), [
    ("p", 0),
    ("prev(p)", 1),
    ("prev(prev(p))", 2),
    ("once[0, 1] p", 10),  # records every 0.1 s: ten before, at 0.1 … 1.0 s
    ("once[0.5, 1] p", 10),
    ("once[0, 1] prev(p)", 11),  # the oldest in the window, and the one before it
    ("prev(once[0, 1] p)", 11),  # the window of the record before
    ("once[0, 1] once[0, 0.5] p", 15),
    ("p since[0, 0.3] q", 3),
    ("count[0, 2](p) > 1", 20),
    ("eventually[0, 5] once[0, 1] p", 10),  # a future window starts at its own record
    ("(once[0, 1] p) and prev(q)", 10),
])
def test_a_part_reads_back_as_far_as_its_properties_reach(formula, back):
    records = [(k / 10, {"p": k % 3 == 0, "q": True}) for k in range(100)]
    result = check_part(spec_of([formula]), ListPart(records, 50, 60))
    assert result.read_from == back


def test_a_signal_set_once_at_the_start_is_carried_into_a_part_far_from_it():
    records = [(0, {"x": 2.0})] + [(k, {"p": True}) for k in range(1, 1000)]
    spec = spec_of(["x > 1"])
    result = check_part(spec, ListPart(records, 900, 1000))
    assert result.read_from == 0 and result.properties[0].outcome.judged == 100
    assert result.properties[0].outcome.violations == 0


@SETTINGS
@given(st.sampled_from(UNITS), st.data())
def test_decimal_times_and_bounds_on_their_grid_give_the_verdicts_of_one_pass(unit, data):
    # records exactly on a window's bound (every 0.1 s trace has them), epoch-like times
    texts = data.draw(st.lists(formulas(unit=unit), min_size=1, max_size=3))
    records = data.draw(decimal_traces(unit, max_size=40))
    spec = spec_of(texts)
    spec = subspec(spec, [p.name for p in spec.properties if splittable(p.formula)])
    cuts = data.draw(st.lists(st.integers(0, len(records)), max_size=4))
    one = check_records(spec, records)
    parts = in_parts(spec, records, cuts)
    assert format_json(parts) == format_json(one)
    assert format_text(parts) == format_text(one)
